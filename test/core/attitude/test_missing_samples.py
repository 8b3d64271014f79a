"""Missing samples against the stream's own nominal period (issue 22.5): a hole of a few sample
periods is counted and integrated across; a longer one is a gap (not integrated across),
whatever the absolute max_gap_s; both forms of the chain agree."""

from __future__ import annotations

import numpy as np
import pytest

from gyro_attitude.core.attitude import validation as iv
from gyro_attitude.core.attitude.stream import AttitudeStream, StreamConfig

MS = 1_000_000
PERIOD = 5 * MS  # 200 Hz: max_gap_s 0.1 s would let 19 missing samples through


def stream_with_holes(holes):
    """400 samples at 200 Hz with the given (index, samples missing) holes cut out."""
    keep = np.ones(400 + sum(m for _, m in holes), dtype=bool)
    for k, m in holes:
        keep[k:k + m] = False
    t = (1 + np.flatnonzero(keep)).astype(np.int64) * PERIOD
    w = np.tile([0.0, 0.0, 0.5], (t.size, 1))
    return t, w


def test_a_few_missing_samples_are_counted_and_a_long_hole_is_a_gap():
    t, w = stream_with_holes([(100, 2), (200, 10), (300, 4)])
    val = AttitudeStream("rotvec_cubic", config=StreamConfig(gyro_bias="none"))
    verdicts = [val.push(int(x), w[0], "imu")[0] for x in t]
    hole = {int(m) - 1: int(k) + 1 for k, m in
            zip(np.flatnonzero(np.diff(t) > PERIOD), np.diff(t)[np.diff(t) > PERIOD] // PERIOD,
                strict=True)}  # samples missing -> row after the hole
    gaps = [k for k, vd in enumerate(verdicts) if vd.action == iv.RESTART_AFTER_GAP]
    assert gaps == [hole[10]] and "hole of 10 sample(s) (10 missing" in verdicts[hole[10]].detail
    assert val.counts[iv.MISSING_SAMPLES] == 2 + 4 and val.counts[iv.GAP] == 1
    assert verdicts[hole[2]].reason == verdicts[hole[4]].reason == iv.MISSING_SAMPLES
    # the array form gives the same verdicts and counts
    cls = iv.classify(t, w, "imu", StreamConfig())
    codes = [iv.ACTION_CODES[vd.action] for vd in verdicts]
    assert cls.action.tolist() == codes and cls.missing_samples == 6 and cls.counts[iv.GAP] == 1


@pytest.mark.parametrize("limit, gaps", [(0, 3), (4, 1), (10, 0)])
def test_max_missing_samples_sets_which_holes_are_gaps(limit, gaps):
    t, w = stream_with_holes([(100, 2), (200, 10), (300, 4)])
    cfg = StreamConfig(max_missing_samples=limit)
    res = AttitudeStream("rotvec_cubic", config=cfg).run(t, w, "imu")
    assert res.counts[iv.GAP] == gaps
    s = AttitudeStream("rotvec_cubic", config=cfg)
    q = [s.push(int(x), w[k], "imu")[1] for k, x in enumerate(t)]
    assert np.max(np.abs(np.array(q) - res.q)) <= 1e-12
    assert s.counts == res.counts


def test_holes_are_found_only_once_the_period_is_known_and_jitter_is_no_hole():
    rng = np.random.default_rng(3)
    dt = PERIOD + rng.integers(-PERIOD // 4, PERIOD // 4, 500)  # ±25 % jitter
    t = np.cumsum(dt).astype(np.int64)
    w = np.zeros((t.size, 3))
    cls = iv.classify(t, w, "imu", StreamConfig())
    assert cls.missing_samples == 0 and cls.counts[iv.GAP] == 0
    # a hole within the first 16 intervals (while the period is learnt) is not counted
    t2, w2 = stream_with_holes([(5, 3)])
    assert iv.classify(t2, w2, "imu", StreamConfig()).missing_samples == 0


def test_rejected_samples_make_holes_but_are_not_counted_missing():
    t, w = stream_with_holes([])
    w[100] = np.nan  # one rejected: a hole of 1, counted as non-finite, not as missing
    w[200:210] = np.nan  # ten rejected in a row: the integration cannot bridge them: a gap
    cfg = StreamConfig()
    cls = iv.classify(t, w, "imu", cfg)
    val = AttitudeStream("rotvec_cubic", config=StreamConfig(gyro_bias="none"))
    codes = [iv.ACTION_CODES[val.push(int(x), w[k], "imu")[0].action] for k, x in enumerate(t)]
    assert cls.action.tolist() == codes
    assert cls.missing_samples == val.counts[iv.MISSING_SAMPLES] == 0
    assert cls.counts[iv.NON_FINITE] == 11 and cls.counts[iv.GAP] == 1
    assert cls.action[210] == iv.ACTION_CODES[iv.RESTART_AFTER_GAP]


def test_a_gyro_pinned_at_its_range_is_counted_as_saturated():
    # ±2000 °/s (34.9 rad/s) clipped for 0.5 s at 200 Hz: the samples repeat the extreme
    rng = np.random.default_rng(5)
    n = 400
    t = (1 + np.arange(n, dtype=np.int64)) * PERIOD
    w = 0.01 * rng.standard_normal((n, 3))
    clip = np.radians(2000.0)
    w[100:200, 2] = clip  # 100 samples pinned: counted from 20 ms (4 periods) on, 96
    w[300:310, 0] = -clip  # 10 samples: 6
    # a quantized gyro at rest repeats small values: no saturation
    w[200:300] = np.round(w[200:300] / 0.001) * 0.001
    res = AttitudeStream("rotvec_cubic", config=StreamConfig(gyro_bias="none")).run(t, w, "imu")
    assert res.counts["saturated"] == 96 + 6
    assert "pinned at 34.9066 rad/s on axis z" in res.details["saturated"]
    s = AttitudeStream("rotvec_cubic", config=StreamConfig(gyro_bias="none"))
    for k in range(n):
        s.push(int(t[k]), w[k], "imu")
    assert s.counts["saturated"] == 102


def test_classify_finds_a_hole_or_a_step_back_wherever_it_falls():
    """classify's verdicts on a regular stream with one sample removed, one stamp repeated or
    one interval beyond max_gap, at every place: a hole counted exactly from the 17th interval
    on when it spans 1.5 x the first 16's median or more (the rule over all intervals at once:
    the oracle), a duplicate rejected, a gap restarted."""
    from gyro_attitude.core.attitude.validation import NOMINAL_INTERVALS

    def holes_from(dt):  # an interval from the 17th on of 1.5 x the first 16's median or more
        if dt.size <= NOMINAL_INTERVALS:
            return False
        p = int(np.sort(dt[:NOMINAL_INTERVALS])[NOMINAL_INTERVALS // 2])
        return bool(np.any(2 * dt[NOMINAL_INTERVALS:] >= 3 * p))

    t = 10**9 + np.arange(120, dtype=np.int64) * 5_000_000
    cfg = StreamConfig(max_gap_s=0.1)
    codes = iv.ACTION_CODES
    cls = iv.classify(t, np.zeros((120, 3)), "imu", cfg)
    assert cls.action[0] == codes[iv.START] and (cls.action[1:] == codes[iv.ACCEPT]).all()
    assert cls.missing_samples == 0 and not any(cls.counts.values())
    for k in range(1, 119):
        tk = np.delete(t, k)  # interval k-1 doubles: a hole from the 17th interval on
        cls = iv.classify(tk, np.zeros((119, 3)), "imu", cfg)
        assert cls.missing_samples == int(holes_from(np.diff(tk))), k
        assert cls.accepted == 119 and not any(cls.counts.values()), k
        back = t.copy()
        back[k] = back[k - 1]  # a repeated stamp
        cls = iv.classify(back, np.zeros((120, 3)), "imu", cfg)
        assert cls.counts == {**dict.fromkeys(iv.REJECT_REASONS, 0), iv.DUPLICATE_STAMP: 1}, k
        assert cls.action[k] == codes[iv.REJECT], k
        far = t.copy()
        far[k:] += 100_000_000  # an interval beyond max_gap
        cls = iv.classify(far, np.zeros((120, 3)), "imu", cfg)
        assert cls.counts == {**dict.fromkeys(iv.REJECT_REASONS, 0), iv.GAP: 1}, k
        assert cls.action[k] == codes[iv.RESTART_AFTER_GAP], k


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_stamps_jittered_by_a_third_of_the_period_count_their_holes_and_no_jitter(seed):
    """A driver's timing moves each stamp up to a third of a period about the sample clock:
    an interval then reads up to 1.66 periods without a hole (the interval rule counted one
    every few dozen samples, thousands in a recording), and a hole as little as 1.34."""
    rng = np.random.default_rng(seed)
    n, period = 20_000, 3_500_000
    t = 10**9 + np.arange(n, dtype=np.int64) * period
    t += np.round(rng.uniform(-1 / 3, 1 / 3, n) * period).astype(np.int64)
    keep = np.ones(n, bool)
    keep[rng.choice(np.arange(100, n - 100), 40, replace=False)] = False
    t = t[keep]
    w = np.zeros((t.size, 3))
    cfg = StreamConfig(aiding="none", gyro_bias="none")
    cls = iv.classify(t, w, "imu", cfg)
    res = AttitudeStream(config=cfg).run(t, w, "imu")
    # a hole whose interval reads under 1.5 nominal periods (3-4 % at this jitter, the nominal
    # period a few % off from 16 jittered intervals) is not counted
    assert 34 <= cls.missing_samples == res.counts[iv.MISSING_SAMPLES] <= 40
    assert cls.counts[iv.GAP] == res.counts[iv.GAP] == 0


@pytest.mark.parametrize("where", ["start", "after a gap"])
def test_a_burst_while_the_period_is_learnt_counts_no_missing_samples(where):
    """A driver flushing its buffer delivers a few samples microseconds apart as a time base
    starts: the burst is no period of the clock (counted as one, it set the clock 25 % fast
    and jitter then read as hundreds of missing samples)."""
    rng = np.random.default_rng(1)
    n, period = 4000, 3_500_000
    t = 10**9 + np.arange(n, dtype=np.int64) * period
    t += np.round(rng.uniform(-1 / 3, 1 / 3, n) * period).astype(np.int64)
    k0 = 0 if where == "start" else 2000
    if where == "after a gap":
        t[k0:] += 200_000_000
    t[k0:k0 + 4] = t[k0 + 4] - np.arange(4, 0, -1) * 1000
    w = np.zeros((n, 3))
    cfg = StreamConfig(aiding="none", gyro_bias="none")
    res = AttitudeStream(config=cfg).run(t, w, "imu")
    cls = iv.classify(t, w, "imu", cfg)
    assert res.counts[iv.MISSING_SAMPLES] == cls.missing_samples == 0
