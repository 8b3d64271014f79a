"""The truth start (initial_attitude_source truth): the attitude starts at the first sample the
estimator accepts, from the truth slerped to that sample's stamp — never at a sample it then
rejects (a zero stamp, a NaN rate), live (TruthStart) and offline (initial_attitude_from_truth)."""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial.transform import Rotation

from gyro_attitude.core.attitude import validation as iv
from gyro_attitude.core.attitude.settings import setting
from gyro_attitude.core.attitude.truth import TruthStart, initial_attitude_from_truth

MS = 1_000_000
RATE = 0.7  # rad/s about z: the truth turns, so a wrong start stamp is a wrong attitude


def truth(n=50, step=10 * MS, t0=0):
    t = t0 + np.arange(n, dtype=np.int64) * step
    q = Rotation.from_rotvec(np.outer(t * 1e-9 * RATE, [0.0, 0.0, 1.0])).as_quat()
    return t, q


def usable(t, w):
    return iv.sample_problem(t, w, setting("max_rate_rad_s").default) is None


def expected_at(t_ns):
    return Rotation.from_rotvec([0.0, 0.0, t_ns * 1e-9 * RATE]).as_quat()


def test_live_start_skips_a_zero_stamp_and_nan_rates_before_taking_the_truth():
    tt, tq = truth()
    ts = TruthStart(usable)
    imu = [(0, [0.0, 0.0, RATE]), (5 * MS, [math.nan, 0.0, 0.0]),
           (15 * MS, [0.0, 0.0, RATE]), (25 * MS, [0.0, 0.0, RATE])]
    for t, w in imu:
        ts.add_sample(t, w, t)
    assert ts.start() is None  # no truth yet
    for t, q in zip(tt, tq, strict=True):
        assert ts.add_truth(int(t), q) is None
    q0, payloads = ts.start()
    assert payloads == [15 * MS, 25 * MS] and ts.skipped == 2
    assert (Rotation.from_quat(q0).inv()
            * Rotation.from_quat(expected_at(15 * MS))).magnitude() < 1e-12


def test_live_start_waits_for_the_truth_around_the_sample_and_refuses_bad_truth():
    tt, tq = truth(t0=20 * MS)
    ts = TruthStart(usable)
    ts.add_sample(10 * MS, [0.0, 0.0, RATE], "before the truth")
    ts.add_sample(25 * MS, [0.0, 0.0, RATE], "covered")
    assert ts.add_truth(int(tt[0]), tq[0]) is None
    assert ts.start() is None  # 25 ms is after the only truth sample: wait
    assert "not after" in ts.add_truth(int(tt[0]), tq[0])
    assert "non-finite or zero" in ts.add_truth(int(tt[1]), [0.0, 0.0, 0.0, 0.0])
    assert "non-finite or zero" in ts.add_truth(int(tt[1]), [math.nan, 0.0, 0.0, 1.0])
    assert ts.add_truth(int(tt[1]), tq[1]) is None
    q0, payloads = ts.start()
    assert payloads == ["covered"] and ts.skipped == 1
    assert (Rotation.from_quat(q0).inv()
            * Rotation.from_quat(expected_at(25 * MS))).magnitude() < 1e-12


def test_offline_start_is_the_first_usable_sample_the_truth_covers():
    tt, tq = truth()
    t = np.arange(0, 300 * MS, 5 * MS, dtype=np.int64)
    w = np.tile([0.0, 0.0, RATE], (t.size, 1))
    w[1:51] = np.nan  # 50 NaN samples after the zero stamp
    q0, first, skipped = initial_attitude_from_truth(
        t, tt, tq, usable=lambda k: usable(t[k], w[k]))
    assert first == skipped == 51
    assert (Rotation.from_quat(q0).inv()
            * Rotation.from_quat(expected_at(int(t[51])))).magnitude() < 1e-12
    # without the rule the zero stamp (rejected by the estimator) would be the start
    assert initial_attitude_from_truth(t, tt, tq)[1] == 0
