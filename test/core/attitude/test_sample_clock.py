"""The offline estimator integrates on the clock jittered stamps scatter about (issue 38 item 1):
a driver that stamps each message when the host receives it moves the stamps, not the samples.
Oracles: the sample instants, known by construction, and the closed-form attitude of a rate
about a fixed axis (the integral of the rate, whatever the integration algorithm)."""

import math

import numpy as np
import pytest

from gyro_attitude.core.attitude.offline import estimate_offline
from gyro_attitude.core.attitude.sample_clock import run_period, sample_clock
from gyro_attitude.core.attitude.settings import StreamConfig
from gyro_attitude.core.rotation import quat_angle_between, quat_from_rotvec


def stamps(n, period_ns, jitter, drop=0.0, seed=0):
    """(the true sample instants of the samples kept, their stamps jittered by a uniform
    ±``jitter`` of the period), one sample in 1/``drop`` missing."""
    rng = np.random.default_rng(seed)
    true = 5_000_000_000 + np.arange(n, dtype=np.int64) * period_ns
    keep = rng.random(n) >= drop
    keep[0] = keep[-1] = True
    shift = np.round(rng.uniform(-jitter, jitter, n) * period_ns).astype(np.int64)
    return true[keep], (true + shift)[keep]


def rms(x):
    return float(np.sqrt(np.mean(np.square(x, dtype=np.float64))))


def test_even_stamps_are_kept_as_they_are():
    t = 1_000 + np.arange(100_000, dtype=np.int64) * 3_500_000
    assert sample_clock(t, [0]) is t


@pytest.mark.parametrize("period_ns", [25_000_000, 3_500_000, 125_000])
def test_stamps_jittered_by_a_third_of_the_period_are_put_back_on_their_clock(period_ns):
    true, t = stamps(200_000, period_ns, 1 / 3)
    tau = sample_clock(t, [0])
    assert rms(t - true) > 0.18 * period_ns  # the jitter: a third of the period, uniform
    assert rms(tau - true) < 0.02 * period_ns
    assert np.abs(tau - true).max() < 0.1 * period_ns  # the ends of the run as well


def test_missing_samples_are_steps_of_the_clock_not_smoothed_over():
    # a phone-like 100 Hz stream: ±2 ms of jitter, one sample in 20 missing
    true, t = stamps(100_000, 10_000_000, 0.2, drop=0.05, seed=2)
    tau = sample_clock(t, [0])
    assert rms(tau - true) < 0.5 * rms(t - true)
    assert np.abs(tau - true).max() <= np.abs(t - true).max() + 0.1 * 10_000_000


@pytest.mark.parametrize("seed", range(3))
def test_a_missing_sample_in_stamps_jittered_by_a_third_of_the_period_steps_where_it_is(seed):
    # the interval over a hole can read 1.34 periods, one without 1.66: the step is where the
    # residuals change by a whole period, not at the longest interval; the samples between
    # are otherwise put a whole period off their instants (a USB IMU losing 1 sample in 2000)
    true, t = stamps(100_000, 3_500_000, 1 / 3, drop=0.0005, seed=seed)
    assert true.size < 100_000 - 20
    tau = sample_clock(t, [0])
    assert np.abs(tau - true).max() < 0.25 * 3_500_000


def test_the_period_of_a_run_missing_one_sample_in_twenty_is_its_sample_period():
    # the median of every interval reads 1 % long there (the holes' intervals pull it)
    _, t = stamps(100_000, 10_000_000, 0.2, drop=0.05, seed=2)
    assert abs(run_period(t) - 10_000_000) < 0.002 * 10_000_000
    _, t = stamps(100_000, 10_000_000, 0.45, seed=2)  # the cut is symmetric as the jitter is
    assert abs(run_period(t) - 10_000_000) < 0.002 * 10_000_000


def test_no_clock_spans_a_run_start():
    # two runs, the second 7.3 periods late: its clock is its own
    true, t = stamps(20_000, 1_000_000, 1 / 3, seed=3)
    late = np.concatenate([true[:10_000], true[10_000:] + 7_300_000])
    t = np.concatenate([t[:10_000], t[10_000:] + 7_300_000])
    tau = sample_clock(t, [0, 10_000])
    assert np.abs(tau - late).max() < 0.1 * 1_000_000


def end_error_deg(rate_hz, jitter, seed):
    """Gyro-only offline attitude at the end of 60 s of a rate of 3 sin(2π 2t) + 2 sin(2π 0.7t
    + 1) rad/s about a fixed axis (angular accelerations to 50 rad/s², BROAD's fast trials),
    against the closed-form angle."""
    n = int(60 * rate_hz)
    s = np.arange(n) / rate_hz
    axis = np.array([0.3, -0.5, 0.81]) / np.linalg.norm([0.3, -0.5, 0.81])
    rate = 3.0 * np.sin(4 * np.pi * s) + 2.0 * np.sin(1.4 * np.pi * s + 1.0)
    angle = 3.0 / (4 * np.pi) * (1 - np.cos(4 * np.pi * s[-1])) + 2.0 / (1.4 * np.pi) * (
        math.cos(1.0) - np.cos(1.4 * np.pi * s[-1] + 1.0))
    _, t = stamps(n, round(1e9 / rate_hz), jitter, seed=seed)
    res = estimate_offline(t, rate[:, None] * axis, None,
                           config=StreamConfig(aiding="none", gyro_bias="none"))
    q = quat_from_rotvec(angle * axis)
    return math.degrees(float(quat_angle_between(res.q[-1][None], q[None])[0]))


@pytest.mark.parametrize("rate_hz", [100.0, 285.714])
def test_jittered_stamps_cost_the_offline_attitude_little(rate_hz):
    # integrating on the jittered stamps' intervals: 0.2-4.3 degrees at the end (a random walk
    # driven by the angular acceleration); on their clock a tenth of that or less
    errors = [end_error_deg(rate_hz, 1 / 3, seed) for seed in range(3)]
    assert max(errors) < 0.1, errors


def test_a_long_run_taken_a_chunk_at_a_time_has_the_clock_of_the_whole_run():
    # bounded temporaries: chunks with margins give the whole run's clock (to rounding)
    true, t = stamps(300_000, 10_000_000, 0.2, drop=0.05, seed=4)
    whole = sample_clock(t, [0], chunk=1 << 22)
    # (to rounding: the whole run's cumulative sum of residuals passes 2**53 ns)
    assert np.abs(sample_clock(t, [0], chunk=1 << 14) - whole).max() <= 4
    assert rms(whole - true) < 0.5 * rms(t - true)


def _fuzz_stamps(rng, kind):
    """Hostile timing: a wandering sampler (random-walk stamps), a rate change, or jitter up
    to half a period with holes."""
    period = 3_500_000
    n = int(rng.integers(200, 2500))
    if kind == "wandering":
        t = np.cumsum(period * (1 + rng.uniform(-0.5, 0.5, n)))
    else:
        g = np.flatnonzero(rng.random(2 * n) > rng.uniform(0, 0.1))[:n] * float(period)
        t = g + rng.uniform(-0.46, 0.46, g.size) * period
        if kind == "rate change":
            a = int(rng.integers(1, g.size - 1))
            t[a:] = t[a] + (t[a:] - t[a]) * rng.choice([0.5, 0.66, 1.5, 2.0, 3.0])
    return 10**9 + np.round(t).astype(np.int64)


@pytest.mark.parametrize("kind", ["wandering", "rate change", "jitter"])
def test_the_clock_rises_strictly_whatever_the_timing(kind):
    rng = np.random.default_rng(125)
    for _ in range(60):
        t = _fuzz_stamps(rng, kind)
        t = np.unique(t)  # strictly rising stamps: one run
        tau = sample_clock(t, np.array([0]))
        assert (np.diff(tau) > 0).all()


@pytest.mark.parametrize("factor", [1.1, 1.5, 2.0, 3.0])
def test_a_rate_change_keeps_the_stamps_where_no_clock_of_jitter_fits(factor):
    """Clean stamps whose interval changes mid-run are no jitter about one clock: kept (a
    smoothed clock across the change moved them by up to 64 periods)."""
    period = 10_000_000
    dt = np.r_[np.full(1000, period), np.full(1000, int(period * factor))]
    t = 10**9 + np.cumsum(dt).astype(np.int64)
    tau = sample_clock(t, np.array([0]))
    assert np.abs(tau - t).max() <= period // 2
    w = np.zeros((t.size, 3))
    res = estimate_offline(t, w, config=StreamConfig(aiding="none", gyro_bias="none"))
    assert res.q.shape == (t.size, 4) and np.isfinite(res.q).all()
