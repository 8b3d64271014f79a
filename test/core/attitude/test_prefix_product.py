"""The blocked quaternion scan against the left-to-right product written out."""

import numpy as np
import pytest

from gyro_attitude.core.attitude.compose import prefix_product, prefix_product_left
from gyro_attitude.core.rotation import quat_from_rotvec


def _sequential(d: np.ndarray, left: bool = False) -> np.ndarray:
    """P_k = d_0 ⊗ … ⊗ d_k (or d_k ⊗ … ⊗ d_0) one Hamilton product at a time, as 4x4
    matrices (an arithmetic of its own, not the package's)."""
    out = np.empty_like(d)
    acc = np.array([0.0, 0.0, 0.0, 1.0])
    for k, (x, y, z, w) in enumerate(d):
        if left:  # d_k ⊗ acc
            m = np.array([[w, -z, y, x], [z, w, -x, y], [-y, x, w, z], [-x, -y, -z, w]])
        else:  # acc ⊗ d_k
            m = np.array([[w, z, -y, x], [-z, w, x, y], [y, -x, w, z], [-x, -y, -z, w]])
        acc = m @ acc
        out[k] = acc
    return out


@pytest.mark.parametrize("m", [0, 1, 2, 47, 48, 49, 63, 256, 257, 4099, 61440 + 13])
def test_blocked_scan_equals_the_sequential_product(m):
    rng = np.random.default_rng(m)
    # steps of up to ~0.6 rad: the running product turns far from its start (the order of
    # the factors matters at first order)
    d = quat_from_rotvec(rng.normal(scale=0.3, size=(m, 3)))
    got = prefix_product(d)
    want = _sequential(d)
    assert got.shape == (m, 4)
    if m:
        # reassociated rounding: ~1e-16 per factor (random walk) and per level
        assert np.abs(got - want).max() < 1e-12
        np.testing.assert_allclose(np.linalg.norm(got, axis=1), 1.0, atol=1e-12)


def test_left_scan_composes_in_the_other_order():
    rng = np.random.default_rng(5)
    d = quat_from_rotvec(rng.normal(scale=0.3, size=(1000, 3)))
    assert np.abs(prefix_product_left(d) - _sequential(d, left=True)).max() < 1e-12
    assert np.abs(prefix_product(d) - _sequential(d, left=True)).max() > 0.1
