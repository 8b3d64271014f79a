"""How late the magnetic field's stamps are against the gyro's (sample_alignment.field_clock_offset):
recovered from the field's turning on a multi-frequency hand-held-like motion for delays given
by construction (the oracle: the shift applied), and no claim where the motion cannot tell
(rest, a steady turn).  The field and rates are built with scipy's Rotation, not the package."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from gyro_attitude.core.attitude.sample_alignment import (
    OFFSET_WARN_S,
    field_clock_offset,
    field_clock_warning,
    latest_at,
)

RATE_HZ = 200.0
FIELD_N = np.array([0.2e-6, 15.7e-6, -40.8e-6])  # Berlin, ENU (tesla)


def _motion(seconds=120.0, steady=None, seed=3):
    n = int(seconds * RATE_HZ) + 1
    t = np.arange(n) / RATE_HZ
    if steady is None:  # rotation vector: a few incommensurate sines per axis (a hand's motion)
        rng = np.random.default_rng(seed)
        f = rng.uniform(0.05, 0.8, (3, 4))
        a = rng.uniform(0.1, 0.6, (3, 4))
        ph = rng.uniform(0, 2 * np.pi, (3, 4))
        r = np.stack([(a[i] * np.sin(2 * np.pi * f[i] * t[:, None] + ph[i])).sum(1)
                      for i in range(3)], axis=1)
    else:
        r = np.outer(t, steady)
    rot = Rotation.from_rotvec(r)
    # body rate over each step (rotation vector of R_k^-1 R_k+1 per step), the last repeated
    w = (rot[:-1].inv() * rot[1:]).as_rotvec() * RATE_HZ
    w = np.vstack((w, w[-1:]))
    rng = np.random.default_rng(seed + 1)
    field = rot.inv().apply(FIELD_N) + rng.normal(scale=0.1e-6, size=(n, 3))
    omega = w + rng.normal(scale=1e-3, size=w.shape)
    t_ns = 1_000_000_000 + np.round(t * 1e9).astype(np.int64)
    return t_ns, omega, field


def _late(t_ns, field, seconds):
    """The field as replay aligns it when its stamps are ``seconds`` late."""
    return latest_at(t_ns, t_ns + int(round(seconds * 1e9)), field, int(0.02e9))


@pytest.mark.parametrize("late", [0.0, 0.2, -0.3, 3.0])
def test_the_delay_of_the_field_is_recovered_from_its_turning(late):
    t, w, m = _motion()
    got = field_clock_offset(t, w, _late(t, m, late))
    assert got == pytest.approx(late, abs=0.015)
    assert (field_clock_warning(got) is None) == (abs(late) < OFFSET_WARN_S)


def test_stamps_the_validator_rejects_do_not_move_or_break_the_estimate():
    # a zero stamp first and one far back in time (replay takes the stamps as recorded)
    t, w, m = _motion()
    rows = _late(t, m, 0.2)
    t = t.copy()
    t[0], t[5000] = 0, t[5000] - 10**12
    assert field_clock_offset(t, w, rows) == pytest.approx(0.2, abs=0.015)


def test_a_disturbed_stretch_does_not_move_the_estimate():
    t, w, m = _motion()
    m = m.copy()
    m[8000:10000] += [25e-6, -15e-6, 10e-6]  # a magnet near for 10 s
    assert field_clock_offset(t, w, _late(t, m, 0.2)) == pytest.approx(0.2, abs=0.015)


@pytest.mark.filterwarnings("error")
@pytest.mark.parametrize("case", ["rest", "steady_turn", "no_field", "too_short", "absurd"])
def test_no_offset_is_claimed_where_the_motion_cannot_tell(case):
    steady = {"rest": [0.0, 0.0, 0.0], "steady_turn": [0.0, 0.0, 0.16]}.get(case)
    t, w, m = _motion(steady=steady)
    if case == "no_field":
        m = np.full_like(m, np.nan)
    if case == "absurd":  # values the filter counts invalid: no figure, no numpy warning
        m = np.full_like(m, 1e300)
    if case == "too_short":
        t, w, m = t[:20], w[:20], m[:20]
    assert field_clock_offset(t, w, _late(t, m, 0.5)) is None
