"""Truth at many stamps: scipy's Slerp as the oracle, coverage (span, gaps, exact hits)."""

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from gyro_attitude.core.attitude.truth import truth_at_stamps


def test_truth_at_stamps_equals_scipy_slerp_and_refuses_what_it_does_not_cover():
    rng = np.random.default_rng(3)
    t = 10**9 + np.cumsum(rng.integers(8_000_000, 9_000_000, 40)).astype(np.int64)
    t[25:] += 10**8  # a tracking gap between samples 24 and 25
    q = Rotation.from_rotvec(np.cumsum(0.05 * rng.normal(size=(40, 3)), axis=0)).as_quat()
    s = np.sort(np.r_[rng.integers(t[0] - 10**7, t[-1] + 10**7, 500), t[:5], t[0], t[-1]])
    got, covered = truth_at_stamps(t, q, s)
    gap = (s > t[24]) & (s < t[25])
    np.testing.assert_array_equal(covered, (s >= t[0]) & (s <= t[-1]) & ~gap)
    ref = Slerp(t.astype(float), Rotation.from_quat(q))(s[covered].astype(float))
    d = (ref.inv() * Rotation.from_quat(got)).magnitude()
    assert d.max() < 1e-9
    for k in np.flatnonzero(covered)[::37]:  # one stamp at a time (the node) agrees bit for bit
        np.testing.assert_array_equal(truth_at_stamps(t, q, [s[k]])[0][0],
                                      got[np.flatnonzero(covered).tolist().index(k)])


def test_the_interval_limit_of_a_long_truth_comes_from_a_strided_sample_of_its_intervals(
        monkeypatch):
    """Past MEDIAN_INTERVALS intervals the median is taken over an evenly strided sample (no
    temporary of the recording's length): on a jittered 100 Hz truth with tracking gaps it
    stays 1.5 x a nominal interval, as the whole-array median does, and the gaps stay out."""
    import gyro_attitude.core.attitude.truth as tr

    rng = np.random.default_rng(4)
    t = np.cumsum(10_000_000 + rng.integers(-1_000_000, 1_000_001, 20_000)).astype(np.int64)
    t[5000:] += 2_000_000_000  # three tracking gaps of 2 s
    t[9000:] += 2_000_000_000
    t[15000:] += 2_000_000_000
    whole = int(1.5 * float(np.median(np.diff(t))))
    monkeypatch.setattr(tr, "MEDIAN_INTERVALS", 64)
    strided = tr.default_max_interval_ns(t)
    assert 1.5 * 9_000_000 <= strided <= 1.5 * 11_000_000
    assert abs(strided - whole) <= 1.5 * 1_000_000
    assert strided < 2_000_000_000


def test_one_truth_sample_covers_its_own_stamp_only():
    """(The node's truth start asks the truth at the first Imu stamp as soon as one truth
    sample has come: an IndexError stopped the node.)"""

    q = np.array([[0.0, 0.0, np.sin(0.2), np.cos(0.2)]])
    got, covered = truth_at_stamps([100], q, [50, 100, 150])
    assert covered.tolist() == [False, True, False]
    np.testing.assert_array_equal(got, q)
