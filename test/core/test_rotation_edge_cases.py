"""Rotation edge cases: inverse of a non-unit quaternion,
reflections and the default orthogonality tolerance, batched attitude-error angles."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from gyro_attitude.core.rotation import (
    check_rotation_matrix,
    quat_angle_between,
    quat_from_matrix,
    quat_inverse,
)


def test_inverse_of_a_non_unit_quaternion():
    # q⁻¹ = q*/|q|²: for q = (1, 2, 3, 4) (|q|² = 30) written out.
    q = np.array([1.0, 2.0, 3.0, 4.0])
    np.testing.assert_allclose(quat_inverse(q), np.array([-1.0, -2.0, -3.0, 4.0]) / 30.0,
                               rtol=1e-15, atol=0)


def test_reflections_are_refused():
    # det = −1 but CᵀC = I: random rotations times a mirror (scipy as the source).
    r = Rotation.random(50, random_state=3).as_matrix()
    mirrors = r @ np.diag([1.0, 1.0, -1.0])
    for m in mirrors:
        with pytest.raises(ValueError):
            check_rotation_matrix(m)
    assert check_rotation_matrix(r).shape == (50, 3, 3)


def test_default_orthogonality_tolerance_is_tight():
    # 1e-3 off orthogonal is far outside the documented 1e-6 default, 1e-7 is inside.
    c = Rotation.from_rotvec([0.3, -0.2, 0.1]).as_matrix()
    with pytest.raises(ValueError):
        check_rotation_matrix(c * (1 + 1e-3))
    with pytest.raises(ValueError):
        quat_from_matrix(c * (1 + 1e-3))
    check_rotation_matrix(c * (1 + 1e-8))


def test_angle_between_is_per_element_in_a_batch():
    q1 = Rotation.random(6, random_state=4)
    angles = np.array([0.0, 1e-9, 0.3, 1.0, 2.5, np.pi - 1e-6])
    axes = Rotation.random(6, random_state=5).apply([1.0, 0.0, 0.0])
    q2 = q1 * Rotation.from_rotvec(axes * angles[:, None])
    got = quat_angle_between(q1.as_quat(), q2.as_quat())
    assert got.shape == (6,)
    np.testing.assert_allclose(got, angles, rtol=1e-9, atol=1e-15)
