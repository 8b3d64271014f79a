"""Rests found wherever the sensor rests (issue 40 item 3): the causal bias stage and the offline
estimator agree on which samples rest, at 40 Hz to 8 kHz, with an accelerometer whose scale is a
few percent off and whose axes are offset; every rest long enough for the bias stage is found,
and no rest is reported in motion, on a steady turn or on a moving carrier.

The IMU data are closed forms (not the package's simulator): rests, and moves about a fixed body
axis with a sin² rate profile (angle ``p T (s/2 − sin 2πs / 4π)``) plus a translation; the
attitude from scipy, the specific force ``C_bn (a + g up)``, the accelerometer ``scale · f +
offset + noise``, the gyro ``ω + bias + noise`` (MEMS figures: BROAD's 0.1 °/s and 0.05 m/s² per
axis, a bias up to 0.46 °/s per axis, offsets up to 0.15 m/s²).

Which samples rest, by definition of each estimator (rest.py, gyro_bias.py, offline.py): the
causal stage takes the oldest sample of every rest window, and counts a run of them once it
spans ``min_rest_s``, so a physical rest counts when it lasts ``min_rest_s + rest_window_s``;
the offline estimator keeps of the same runs the samples also preceded by a full window of
rest.  *Agree* here: the same rests, in the same order, each offline rest inside its causal
one, starting at most one window (and a sample) later and ending at most a sample apart.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from gyro_attitude.core.attitude import offline
from gyro_attitude.core.attitude.gyro_bias import J_LAST_ACC
from gyro_attitude.core.attitude.offline import estimate_offline
from gyro_attitude.core.attitude.rest import R_AT_REST
from gyro_attitude.core.attitude.settings import StreamConfig
from gyro_attitude.core.attitude.stream import AttitudeStream

G = 9.80665
GYRO_NOISE = 0.0017  # rad/s per axis and sample (BROAD: 0.08-0.10 °/s at 286 Hz)
ACCEL_NOISE = 0.05  # m/s² per axis
MOVING_RATE = 0.005  # rad/s: a true rate above this (3x under the gyro noise) is motion
MOVING_ACCEL = 0.05  # m/s²: and so is a translation's acceleration above this


def arm(rate_hz, rests_s, moves_s, *, accel_scale=1.0, seed=0, t0_ns=3_000_000_000,
        offsets=True):
    """A robot arm: ``rests_s[0]``, ``moves_s[0]``, ``rests_s[1]``, ... (one rest more than
    moves).  Returns t_ns, gyro, accel, the true bias, the true rest intervals (s from t0,
    [start, stop)) and the motion mask (true |ω| or |a| above the thresholds)."""
    assert len(rests_s) == len(moves_s) + 1
    rng = np.random.default_rng(seed)
    dt = 1.0 / rate_hz
    kinds, lengths = [], []
    for k, r in enumerate(rests_s):
        kinds.append(None)
        lengths.append(int(round(r * rate_hz)))
        if k < len(moves_s):
            axis = rng.normal(size=3)
            push = rng.normal(size=3)
            kinds.append((axis / np.linalg.norm(axis), rng.uniform(0.6, 1.2),
                          push / np.linalg.norm(push) * rng.uniform(0.5, 2.0)))
            lengths.append(int(round(moves_s[k] * rate_hz)))
    n = sum(lengths)
    omega = np.zeros((n, 3))
    a_nav = np.zeros((n, 3))
    q = Rotation.from_rotvec([0.05, -0.03, 0.4])
    rests, k0, quats = [], 0, np.empty((n, 4))
    for kind, m in zip(kinds, lengths, strict=True):
        if kind is None:
            rests.append((k0 * dt, (k0 + m) * dt))
            quats[k0:k0 + m] = q.as_quat()
        else:
            u, peak, push = kind
            big_t = m * dt
            s = np.arange(m) * dt / big_t
            omega[k0:k0 + m] = peak * np.sin(np.pi * s)[:, None] ** 2 * u
            angle = peak * big_t * (s / 2 - np.sin(2 * np.pi * s) / (4 * np.pi))
            quats[k0:k0 + m] = (q * Rotation.from_rotvec(angle[:, None] * u)).as_quat()
            q = q * Rotation.from_rotvec(peak * big_t / 2 * u)
            a_nav[k0:k0 + m] = np.sin(2 * np.pi * s)[:, None] * push
        k0 += m
    r_nb = Rotation.from_quat(quats)
    f_body = r_nb.inv().apply(a_nav + np.array([0.0, 0.0, G]))
    offset = rng.uniform(-0.15, 0.15, 3) * offsets
    accel = accel_scale * f_body + offset + rng.normal(scale=ACCEL_NOISE, size=(n, 3))
    bias = rng.uniform(-0.008, 0.008, 3)
    gyro = omega + bias + rng.normal(scale=GYRO_NOISE, size=(n, 3))
    t_ns = t0_ns + np.round(np.arange(n) * dt * 1e9).astype(np.int64)
    moving = (np.linalg.norm(omega, axis=1) > MOVING_RATE) | (
        np.linalg.norm(a_nav, axis=1) > MOVING_ACCEL)
    return t_ns, gyro, accel, bias, rests, moving


def causal_rests(t, w, a, cfg):
    """The causal bias stage's rest samples, run by run: (first, last) sample indices of each
    run of consecutive accumulated samples, and whether it counted (spans ``min_rest_s``).
    The stage itself, in the stream's state, read after every sample pushed: the index of the
    sample it last accumulated."""
    st = AttitudeStream("rotvec_cubic", config=cfg)
    taken = np.zeros(t.size, bool)
    rest_i, bias_i = st.state.rest_i[0], st.state.bias_i[0]
    for k in range(t.size):
        st.push(int(t[k]), w[k], "imu", None, a[k])
        if rest_i[R_AT_REST]:
            taken[int(bias_i[J_LAST_ACC])] = True
    edges = np.diff(np.concatenate(([0], taken.view(np.int8), [0])))
    runs = list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1, strict=True))
    min_ns = int(round(cfg.min_rest_s * 1e9))
    return [(int(s), int(e), bool(t[e] - t[s] >= min_ns)) for s, e in runs], st.bias_report


def offline_rests(t, w, a, cfg, monkeypatch):
    """The offline estimator's rests as (first, last) sample indices, and its result."""
    seen = []
    run = offline._Estimator.run

    def spy(self):
        seen.append(self)
        return run(self)

    monkeypatch.setattr(offline._Estimator, "run", spy)
    res = estimate_offline(t, w, a, config=cfg)
    idx = res.index
    return [(int(idx[r.start]), int(idx[r.stop - 1])) for r in seen[0].rests], res


def check_rests(t, w, a, bias, rests, moving, monkeypatch, cfg=None, all_found=True):
    """Every true rest long enough found by both (``all_found``), none in motion, and the two
    agree."""
    cfg = cfg or StreamConfig()
    runs, causal_report = causal_rests(t, w, a, cfg)
    counted = [(s, e) for s, e, ok in runs if ok]
    off, res = offline_rests(t, w, a, cfg, monkeypatch)
    stream = AttitudeStream(config=cfg).run(t, w, "imu", None, a).bias
    period = (t[-1] - t[0]) / (t.size - 1)
    window = int(round(cfg.rest_window_s * 1e9 / period))
    t_s = (t - t[0]) * 1e-9
    long_enough = [(r0, r1) for r0, r1 in rests
                   if r1 - r0 >= cfg.min_rest_s + cfg.rest_window_s + 1e-9]
    figures = (f"true rests {[(round(r0, 2), round(r1, 2)) for r0, r1 in rests]}; causal "
               f"{[(round(t_s[s], 2), round(t_s[e], 2)) for s, e in counted]}; offline "
               f"{[(round(t_s[s], 2), round(t_s[e], 2)) for s, e in off]}")
    # no rest sample in motion (either estimator, counted or not), but the causal stage's
    # first window of a rest: a sample counts there once a full window of rest FOLLOWS it, so
    # the tail of a motion that slows below the detector's bounds (the last ~0.15 s of these
    # moves, 0.05 rad/s and 0.5 m/s² and falling) enters; the start of the next motion never
    for s, e, _ in runs:
        late = s + np.flatnonzero(moving[s:e + 1])
        assert (late < s + window).all() and not moving[s + window:e + 1].any(), \
            f"causal rest sample in motion: {figures}"
    for s, e in off:
        assert not moving[s:e + 1].any(), f"offline rest sample in motion: {figures}"
    # every true rest long enough: one causal and one offline rest inside it
    for r0, r1 in long_enough if all_found else []:
        inside_c = [(s, e) for s, e in counted
                    if r0 - cfg.rest_window_s - 1e-9 <= t_s[s] and t_s[e] < r1]
        inside_o = [(s, e) for s, e in off if r0 - 1e-9 <= t_s[s] and t_s[e] < r1]
        assert len(inside_c) == 1 and len(inside_o) == 1, f"rest {r0:.2f}-{r1:.2f}: {figures}"
    # the stream's chain counts what its bias stage counts; the offline report what it found
    assert stream.rests_used == causal_report.rests_used == len(counted), figures
    assert res.bias.rests_used == len(off), figures
    # agree: the same rests in order, offline inside causal, one window apart at most
    assert len(off) == len(counted), figures
    for (cs, ce), (os_, oe) in zip(counted, off, strict=True):
        assert cs <= os_ <= cs + window + 1 and abs(oe - ce) <= 1, figures
    # and the bias from them: offline the white noise over the rest samples (4 sigma), causal
    # that and the motion tails (measured up to 0.53 mrad/s ≈ 0.03 °/s)
    if long_enough and all_found:
        white = 4 * GYRO_NOISE / np.sqrt(res.bias.rest_samples)
        np.testing.assert_allclose(res.bias.bias, bias, atol=white + 5e-5)
        np.testing.assert_allclose(stream.bias, bias, atol=1e-3)
    return counted, off


ARM_RESTS = [2.0, 1.6, 2.6, 1.8, 2.2, 1.7, 2.4, 2.0]
ARM_MOVES = [2.0, 3.5, 2.5, 4.0, 3.0, 2.2, 3.0]


def test_short_rests_between_robot_arm_moves_at_125_hz_are_all_found_by_both(monkeypatch):
    t, w, a, bias, rests, moving = arm(125.0, ARM_RESTS, ARM_MOVES, seed=11)
    counted, off = check_rests(t, w, a, bias, rests, moving, monkeypatch)
    assert len(counted) == len(off) == len(ARM_RESTS)


@pytest.mark.parametrize("scale", [0.96, 1.04, 0.95, 1.05])
def test_an_accelerometer_a_few_percent_off_g_finds_the_same_rests(scale, monkeypatch):
    # |f| 4-5 % below or above g (0.39-0.49 m/s²) plus offsets of up to 0.15 m/s² per axis:
    # the old norm tolerance (0.5 m/s²) lost or split these rests (at 5 %: no rest at all,
    # "bias 0", or 9 offline rests against 7 causal ones)
    t, w, a, bias, rests, moving = arm(125.0, ARM_RESTS, ARM_MOVES, accel_scale=scale, seed=12)
    counted, off = check_rests(t, w, a, bias, rests, moving, monkeypatch)
    assert len(counted) == len(off) == len(ARM_RESTS)


@pytest.mark.parametrize(("scale", "seed"), [(1.05, 23), (0.95, 23), (0.95, 27)])
def test_rests_flickering_at_the_norm_tolerance_are_the_same_rests_offline_and_causal(
        scale, seed, monkeypatch):
    # an accelerometer 5 % off against a 0.5 m/s² tolerance: |f| sits on the edge and rest
    # windows come and go within a rest; whatever passes, both count the same rests (the
    # offline search made extra ones of the pieces the causal stage did not count: 10
    # against 7, 13 against 7, 12 against 8 on these three)
    t, w, a, bias, rests, moving = arm(125.0, ARM_RESTS, ARM_MOVES, accel_scale=scale,
                                       seed=seed, offsets=False)
    cfg = StreamConfig(rest_accel_norm_tol=0.5)
    counted, _ = check_rests(t, w, a, bias, rests, moving, monkeypatch, cfg, all_found=False)
    assert len(counted) > 0


@pytest.mark.parametrize("rate_hz", [40.0, 125.0, 1000.0, 8000.0])
def test_rests_just_long_enough_are_found_at_every_rate(rate_hz, monkeypatch):
    # rests of min_rest_s + the window + 0.1 s (1.6 s: what the bias stage needs), and two of
    # 1.0 s that neither counts (their rest-window starts span 0.5 s and the moves' slow ends,
    # under min_rest_s)
    cfg = StreamConfig()
    just = cfg.min_rest_s + cfg.rest_window_s + 0.1
    rests_s = [just, just, 1.0, just, 1.0, just]
    t, w, a, bias, rests, moving = arm(rate_hz, rests_s, [2.0, 2.5, 2.0, 3.0, 2.0],
                                       accel_scale=0.96, seed=13)
    counted, off = check_rests(t, w, a, bias, rests, moving, monkeypatch, cfg)
    assert len(counted) == len(off) == 4


def still_rate_accel(n, rate_hz, seed, omega_fn=None, accel_fn=None):
    """Gyro and accelerometer of a body at a constant level attitude, plus ``omega_fn(t)``
    (rad/s, body) and ``accel_fn(t)`` (m/s², body, on top of gravity), MEMS noise and bias."""
    rng = np.random.default_rng(seed)
    tt = np.arange(n) / rate_hz
    w = rng.uniform(-0.008, 0.008, 3) + rng.normal(scale=GYRO_NOISE, size=(n, 3))
    f = np.tile([0.0, 0.0, G], (n, 1)) + rng.normal(scale=ACCEL_NOISE, size=(n, 3))
    if omega_fn is not None:
        w += omega_fn(tt)
    if accel_fn is not None:
        f += accel_fn(tt)
    return (10**9 + np.round(tt * 1e9)).astype(np.int64), w, f


def no_rest_anywhere(t, w, a, monkeypatch):
    cfg = StreamConfig()
    runs, report = causal_rests(t, w, a, cfg)
    off, res = offline_rests(t, w, a, cfg, monkeypatch)
    assert runs == [] and off == [] and report.rests_used == 0 and res.bias.rests_used == 0


def test_a_steady_turn_is_no_rest(monkeypatch):
    # a turntable at 0.03 rad/s (1.7 °/s) about the vertical for 8 s: no gyro spread, the
    # accelerometer unchanged; only the mean-rate bound tells it from a bias
    t, w, a = still_rate_accel(1000, 125.0, 21, omega_fn=lambda tt: np.outer(
        np.full(tt.size, 0.03), [0.0, 0.0, 1.0]))
    no_rest_anywhere(t, w, a, monkeypatch)


def test_a_vibrating_carrier_is_no_rest(monkeypatch):
    # an engine at standstill: 0.4 m/s² at 23 Hz on the accelerometer, 0.01 rad/s of 17 Hz
    # shake on the gyro
    t, w, a = still_rate_accel(
        1600, 200.0, 22,
        omega_fn=lambda tt: 0.01 * np.sin(2 * np.pi * 17 * tt)[:, None] * [1.0, 0.5, 0.2],
        accel_fn=lambda tt: 0.4 * np.sin(2 * np.pi * 23 * tt)[:, None] * [0.3, 0.3, 1.0])
    no_rest_anywhere(t, w, a, monkeypatch)


def test_a_carrier_accelerating_upward_beyond_the_norm_tolerance_is_no_rest(monkeypatch):
    # a lift pulling 1.5 m/s² upward, steadily, without rotation: |f| 1.5 m/s² above g
    t, w, a = still_rate_accel(1000, 125.0, 23,
                               accel_fn=lambda tt: np.outer(np.full(tt.size, 1.5), [0, 0, 1]))
    no_rest_anywhere(t, w, a, monkeypatch)
