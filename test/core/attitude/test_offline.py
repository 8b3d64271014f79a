"""The offline whole-recording estimator (core/attitude/offline.py) against closed forms and
simulated MEMS recordings whose truth is known exactly (rotation about a fixed axis: the
attitude is the exponential of the integrated rate)."""

import numpy as np
import pytest

from gyro_attitude.core.attitude import offline
from gyro_attitude.core.attitude import validation as v
from gyro_attitude.core.attitude.offline import estimate_offline
from gyro_attitude.core.attitude.settings import StreamConfig
from gyro_attitude.core.attitude.stream import AttitudeStream
from gyro_attitude.core.rotation import (
    quat_as_rotvec,
    quat_conjugate,
    quat_from_rotvec,
    quat_multiply,
    quat_rotate,
)

G = 9.80665
RATE_HZ = 200.0


GYRO_ONLY = StreamConfig(aiding="none")  # the default aids the tilt with the accelerometer

def rest_motion_rest(seed, rest_s=8.0, motion_s=20.0, noise_density=1.5e-4, bias_sigma=0.003,
                     accel_noise=0.02, accel_bias=0.0, tilt0_deg=5.0, amp_range=(0.8, 1.5),
                     shake=0.0, scale_sigma=0.0, axis=None, gain=None):
    """A MEMS IMU resting, turning about a random fixed axis (rate up to ``amp_range`` rad/s;
    ``shake`` m/s² of hand-like accelerometer noise while moving; a gain-and-axes error matrix
    (scale factors and misalignments) drawn with ``scale_sigma`` per element), resting again.  Returns
    t_ns, gyro, accel, true q_nb (N, 4), the stated per-sample gyro variance, the index of the
    end of the motion."""
    rng = np.random.default_rng(seed)
    n_rest, n_move = int(rest_s * RATE_HZ), int(motion_s * RATE_HZ)
    n = 2 * n_rest + n_move
    dt = 1.0 / RATE_HZ
    t_ns = (1_000_000_000 + np.arange(n) * int(round(dt * 1e9))).astype(np.int64)
    axis = rng.normal(size=3) if axis is None else np.asarray(axis, dtype=np.float64)
    axis /= np.linalg.norm(axis)
    # rate: a 0.25 s sin² ramp up, A, a cos² ramp down (a clear start and stop: no slow turn
    # the rest test could take for a rest); θ(s) = ∫ rate in closed form, piece by piece
    amp = rng.uniform(*amp_range)
    ramp = 0.25
    s = np.clip((np.arange(n) - n_rest) * dt, 0.0, motion_s)
    u = np.clip(s - (motion_s - ramp), 0.0, ramp)
    up = s <= ramp
    down = s >= motion_s - ramp
    rate = amp * np.where(up, np.sin(np.pi * s / (2 * ramp)) ** 2,
                          np.where(down, np.cos(np.pi * u / (2 * ramp)) ** 2, 1.0))
    theta_mid = amp * (ramp / 2 + (np.minimum(s, motion_s - ramp) - ramp))
    theta = np.where(up, amp * (s / 2 - ramp * np.sin(np.pi * s / ramp) / (2 * np.pi)),
                     theta_mid + amp * (u / 2 + ramp * np.sin(np.pi * u / ramp) / (2 * np.pi)))
    moving = (s > 0) & (s < motion_s)
    rate = np.where(moving, rate, 0.0)
    q_start = quat_from_rotvec(np.radians(tilt0_deg) * np.array([0.6, 0.8, 0.0])
                               + np.array([0.0, 0.0, rng.uniform(-3, 3)]))
    # body-frame rotation about a body-fixed axis: q(t) = q_start ⊗ exp(θ(t) axis)
    q_true = quat_multiply(q_start, quat_from_rotvec(theta[:, None] * axis))
    sigma = noise_density * np.sqrt(RATE_HZ)  # per-sample white noise
    bias = rng.normal(scale=bias_sigma, size=3)
    # gain and axes error: every element of the 3×3 error matrix drawn with scale_sigma
    if gain is None:
        gain = np.eye(3) + rng.normal(scale=scale_sigma, size=(3, 3)) if scale_sigma else np.eye(3)
    gyro = (rate[:, None] * axis) @ gain.T + bias + rng.normal(scale=sigma, size=(n, 3))
    f_b = quat_rotate(quat_conjugate(q_true), np.array([0.0, 0.0, G]))
    accel = f_b + accel_bias * rng.normal(size=3) + rng.normal(scale=accel_noise, size=(n, 3))
    accel[moving] += rng.normal(scale=shake, size=(int(moving.sum()), 3))
    return t_ns, gyro, accel, q_true, sigma ** 2, n_rest + n_move - 1


def nav_error(q_true, q_est):
    """Error rotation vector in the output frame: q_true = exp(e) ⊗ q_est."""
    return quat_as_rotvec(quat_multiply(q_true, quat_conjugate(q_est)))


def test_gyro_only_recovers_the_bias_and_the_closed_form_attitude():
    t, w, a, q_true, var, k_end = rest_motion_rest(1, noise_density=2e-4)
    res = estimate_offline(t, w, a, q0=q_true[0])
    e = np.degrees(np.linalg.norm(nav_error(q_true[k_end], res.q[k_end])))
    # a bias of ~0.003 rad/s uncorrected would turn ~0.06 rad (3.4°) over the motion;
    # estimated at both rests (SE ~5e-5 rad/s) the error is noise-sized (ARW, bias SE: ~0.1°)
    assert e < 0.3
    assert res.bias.rests_used == 2


def test_verdicts_are_those_of_the_causal_path_and_bad_samples_are_counted():
    t, w, a, q_true, var, k_end = rest_motion_rest(2)
    w = w.copy()
    t = t.copy()
    w[500] = np.nan
    w[900] = (np.inf, 0, 0)
    w[1200] = (1e300, 0, 0)
    w[2500:2540, 0] = 4.3  # a clipped gyro: pinned at its largest value (motion phase)
    t[1500] = t[1499]  # duplicate stamp
    t[3000:] += 300_000_000  # a 0.3 s gap
    cfg = StreamConfig(aiding="none")  # gyro-only: the attitude is held across the gap
    res = estimate_offline(t, w, a, q0=q_true[0], config=cfg)
    causal = AttitudeStream(config=cfg, q0=q_true[0]).run(t, w, "", None, a)
    np.testing.assert_array_equal(res.action, causal.action)
    for key in (*v.REJECT_REASONS, v.MISSING_SAMPLES, "saturated"):
        assert res.counts[key] == causal.counts[key], key
    assert res.counts[v.NON_FINITE] == 2 and res.counts[v.IMPLAUSIBLE_RATE] == 1
    assert res.counts[v.DUPLICATE_STAMP] == 1 and res.counts[v.GAP] == 1
    assert res.counts["saturated"] == causal.counts["saturated"] >= 3
    assert np.isfinite(res.q).all() and np.isfinite(res.variance).all()
    # across the gap the attitude is held: the restart row starts where the row before ended
    k = int(np.flatnonzero(res.action == v.ACTION_CODES[v.RESTART_AFTER_GAP])[0])
    j = int(np.searchsorted(res.index, k))
    np.testing.assert_allclose(res.q[j], res.q[j - 1], atol=1e-15)


def test_a_backward_time_jump_resets_to_the_initial_attitude():
    t, w, a, q_true, var, k_end = rest_motion_rest(3)
    t = np.concatenate([t, t[-1000:] - 5_000_000_000])  # replayed again, 5 s earlier
    w = np.concatenate([w, w[-1000:]])
    a = np.concatenate([a, a[-1000:]])
    q0 = q_true[0]
    res = estimate_offline(t, w, a, q0=q0, config=GYRO_ONLY)
    assert res.time_jump_resets == 1
    j = int(np.flatnonzero(res.action[res.index] == v.ACTION_CODES[v.RESET_TIME_JUMP])[0])
    np.testing.assert_allclose(res.q[j], q0 / np.linalg.norm(q0), atol=1e-15)


def test_tilt_from_gravity_beats_the_gyro_alone_under_a_bias_the_rests_cannot_see():
    # one long motion between two short rests and a bias that changes within the motion: the
    # gyro-only tilt drifts, gravity holds it
    t, w, a, q_true, var, k_end = rest_motion_rest(4, motion_s=60.0, noise_density=1e-3,
                                                   amp_range=(0.1, 0.2), shake=0.5)
    w = w.copy()
    n = t.size
    w[n // 3:2 * n // 3] += (0.008, -0.006, 0.0)  # a bias step inside the motion
    gyro_only = estimate_offline(t, w, a, q0=q_true[0], config=GYRO_ONLY)
    aided = estimate_offline(t, w, a, q0=q_true[0])  # aiding auto: tilt from gravity
    tilt = lambda q: np.degrees(np.linalg.norm(nav_error(q_true, q)[:, :2], axis=1))  # noqa: E731
    rms_gyro = np.sqrt(np.mean(tilt(gyro_only.q) ** 2))
    rms_aided = np.sqrt(np.mean(tilt(aided.q) ** 2))
    print(f"\nRMS tilt gyro only {rms_gyro:.3f}°, with gravity {rms_aided:.3f}°")
    assert rms_gyro > 0.5
    # (a zero-phase low-pass cannot follow the part of the drift that turns with the body)
    assert rms_aided < 0.2 * rms_gyro and rms_aided < 0.6


def test_levelling_at_every_rest_starts_level_and_corrects_the_tilt_at_rests():
    t, w, a, q_true, var, k_end = rest_motion_rest(5, tilt0_deg=20.0)
    cfg = StreamConfig(initial_attitude_source="level", initial_heading_deg=0.0)
    res = estimate_offline(t, w, a, config=cfg)
    e = nav_error(q_true, res.q)
    tilt = np.degrees(np.linalg.norm(e[:, :2], axis=1))
    # at both rests the tilt is the accelerometer's (noise 0.02 m/s² over ~1000 samples)
    assert tilt[100] < 0.02 and tilt[-100] < 0.02
    assert res.alignment is not None and abs(np.degrees(res.alignment.roll)) > 5


def test_without_accelerometer_it_runs_gyro_only_and_says_so():
    t, w, a, q_true, var, k_end = rest_motion_rest(6)
    res = estimate_offline(t, w, None, q0=q_true[0], config=StreamConfig(aiding="tilt"))
    assert any("no accelerometer" in n for n in res.notes)
    assert res.bias.rests_used == 2  # rests from the gyro alone
    with pytest.raises(ValueError, match="cannot align"):
        estimate_offline(t, w, None, config=StreamConfig(initial_attitude_source="level"))


def test_unusable_accelerometer_samples_are_counted_and_not_used():
    t, w, a, q_true, var, k_end = rest_motion_rest(7)
    a = a.copy()
    a[2000] = np.nan
    a[2100] = (1e9, 0, 0)
    res = estimate_offline(t, w, a, q0=q_true[0], config=StreamConfig(aiding="tilt"))
    assert res.counts["invalid_accel"] == 2
    assert np.isfinite(res.q).all()


@pytest.mark.parametrize("keep_forward", [True, False])
@pytest.mark.parametrize("aiding", ["none", "tilt"])
def test_chunked_passes_give_the_whole_recording_result(aiding, keep_forward, monkeypatch):
    t, w, a, q_true, var, k_end = rest_motion_rest(8)
    cfg = StreamConfig(aiding=aiding)
    whole = estimate_offline(t, w, a, q0=q_true[0], config=cfg)
    if not keep_forward:  # long blocks: the forward low-pass is recomputed chunk by chunk
        monkeypatch.setattr(offline, "_KEEP_FORWARD", 0)
    chunked = estimate_offline(t, w, a, q0=q_true[0], config=cfg, chunk_samples=257)
    np.testing.assert_array_equal(whole.index, chunked.index)
    assert np.max(np.abs(nav_error(whole.q, chunked.q))) < 1e-9
    np.testing.assert_allclose(chunked.variance, whole.variance, rtol=1e-6, atol=1e-15)


@pytest.mark.parametrize("bias_rw", [0.0, 1e-4])
def test_heading_variance_grows_in_motion_and_is_held_at_rests(bias_rw):
    t, w, a, q_true, var, k_end = rest_motion_rest(9)
    # (no scale-factor error stated: its projected variance may also fall as the body turns;
    # the bias random walk acts only while the attitude is integrated)
    cfg = StreamConfig(gyro_scale_factor_sigma=0.0, gyro_bias_rw=bias_rw)
    res = estimate_offline(t, w, a, q0=q_true[0], config=cfg,
                           angular_velocity_covariance=np.tile([var, 0, 0, 0, var, 0, 0, 0, var],
                                                               (t.size, 1)))
    h = res.variance[:, 2]
    assert h[k_end] > 10 * h[1000]
    assert np.all(np.diff(h) >= -1e-18)  # never shrinks without an observation of heading
    # held over the final rest (its last window is not known to be followed by rest)
    np.testing.assert_allclose(h[-150], h[-1000], rtol=1e-9)


def test_covariance_is_honest_over_100_simulated_mems_recordings():
    """Gyro-only offline estimate: per output axis, the true error lies within 1σ for 60–75 %
    and within 3σ for ≥ 99 % of the draws (100 seeds × 3 axes × 2 instants).  Half the seeds
    turn fast (the body-frame bias error averages out over the turns: the angle random walk
    dominates), half turn slowly while shaken (the rests' bias errors dominate); every gyro
    has a gain-and-axes error matrix of 1σ = 1e-4 per element, as stated to the estimator."""
    z = []
    cfg = StreamConfig(gyro_scale_factor_sigma=1e-4, aiding="none")
    for seed in range(100):
        slow = seed % 2 == 1
        t, w, a, q_true, var, k_end = rest_motion_rest(
            100 + seed, amp_range=(0.05, 0.2) if slow else (0.8, 1.5), shake=1.0 if slow else 0.0,
            scale_sigma=1e-4)
        cov = np.broadcast_to(np.array([var, 0, 0, 0, var, 0, 0, 0, var]), (t.size, 9))
        res = estimate_offline(t, w, a, q0=q_true[0], angular_velocity_covariance=cov, config=cfg)
        for k in ((k_end + int(8 * RATE_HZ)) // 2 + int(4 * RATE_HZ), k_end):
            e = nav_error(q_true[k], res.q[k])
            z.extend(np.abs(e) / np.sqrt(res.variance[k]))
    z = np.array(z)
    within1, within3 = np.mean(z <= 1.0), np.mean(z <= 3.0)
    print(f"\nwithin 1σ {within1:.3f}, within 3σ {within3:.3f} of {z.size} axis draws")
    assert 0.60 <= within1 <= 0.75
    assert within3 >= 0.99


def test_an_axis_misalignment_is_in_the_covariance_of_the_other_axes():
    # a turn of ~1.6 rad about body z; the x gyro sees 1 % of the z rate (misaligned axis): the
    # error about the horizontal axes is ε·|(sin θ, 1 − cos θ)|·(gain), which the per-element
    # gain-and-axes term must cover (a scale-factor-only model predicts ~0 there)
    gain = np.eye(3)
    gain[0, 2] = 0.01
    t, w, a, q_true, var, k_end = rest_motion_rest(21, motion_s=2.0, amp_range=(0.8, 0.8),
                                                   axis=(0.0, 0.0, 1.0), tilt0_deg=0.0,
                                                   gain=gain)
    cov = np.broadcast_to(np.array([var, 0, 0, 0, var, 0, 0, 0, var]), (t.size, 9))
    res = estimate_offline(t, w, a, q0=q_true[0], angular_velocity_covariance=cov,
                           config=StreamConfig(gyro_scale_factor_sigma=0.01, aiding="none"))
    e = nav_error(q_true[k_end], res.q[k_end])
    sd = np.sqrt(res.variance[k_end])
    assert np.linalg.norm(e[:2]) > 0.01  # the leak is there (~0.02 rad)
    assert np.all(np.abs(e[:2]) <= 3 * sd[:2])


def test_bad_arguments_are_refused_in_words():
    t, w, a, q_true, var, k_end = rest_motion_rest(10)
    with pytest.raises(ValueError, match="accel must have shape"):
        estimate_offline(t, w, a[:-1])
    with pytest.raises(ValueError, match="chunk_samples"):
        estimate_offline(t, w, a, chunk_samples=3)
    with pytest.raises(ValueError, match="initial_attitude"):
        estimate_offline(t, w, a, q0=(0, 0, 0, 0))
    empty = estimate_offline(t[:0], w[:0], a[:0])
    assert empty.q.shape == (0, 4)


def test_hostile_samples_never_give_a_non_finite_or_non_unit_attitude():
    rng = np.random.default_rng(5)
    for trial in range(12):
        t, w, a, q_true, var, k_end = rest_motion_rest(trial % 3)
        t, w, a = t.copy(), w.copy(), a.copy()
        for _ in range(int(rng.integers(1, 30))):
            k = int(rng.integers(0, t.size))
            kind = int(rng.integers(0, 8))
            if kind == 0:
                w[k] = np.nan
            elif kind == 1:
                w[k] = (1e300, 0, 0)
            elif kind == 2:
                a[k] = np.inf
            elif kind == 3:
                t[k] = t[max(k - 1, 0)]
            elif kind == 4:
                t[k:] -= int(rng.integers(1, 5)) * 10**9  # backward jump
            elif kind == 5:
                t[k:] += int(rng.integers(1, 5)) * 10**8  # gap
            elif kind == 6:
                t[k] = 0
            else:
                w[k] = (9999.0, -9999.0, 9999.0)
        for cfg in (GYRO_ONLY, StreamConfig(aiding="tilt")):
            r = estimate_offline(t, w, a, config=cfg, chunk_samples=int(rng.integers(64, 3000)))
            assert np.isfinite(r.q).all(), trial
            np.testing.assert_allclose(np.linalg.norm(r.q, axis=1), 1.0, atol=1e-12)
            assert r.variance is None or np.isfinite(r.variance).all(), trial
            assert r.index.size + sum(r.counts[k] for k in v.REJECT_REASONS if k != v.GAP) \
                == t.size


@pytest.mark.parametrize("rate", [0.02, 0.05])
def test_a_slow_steady_turn_is_never_a_rest_and_leaves_the_bias_alone(rate):
    # a turntable: still, a steady turn about a tilted axis for 20 s, still; MEMS noise
    rng = np.random.default_rng(int(rate * 1000))
    n = int(36 * RATE_HZ)
    t = (10**9 + np.arange(n) * 5_000_000).astype(np.int64)
    s = (t - t[0]) * 1e-9
    axis = np.array([0.3, -0.4, 0.866])
    axis /= np.linalg.norm(axis)
    turning = (s >= 8) & (s < 28)
    bias = np.array([0.003, -0.002, 0.004])
    w = np.where(turning[:, None], rate * axis, 0.0) + bias + rng.normal(scale=2e-3, size=(n, 3))
    a = np.array([0.0, 0.0, G]) + rng.normal(scale=0.02, size=(n, 3))  # small tilt: ignored
    res = estimate_offline(t, w, a, config=GYRO_ONLY)
    assert res.bias.rests_used == 2  # the two still stretches, not the turn
    np.testing.assert_allclose(res.bias.bias, bias, atol=2e-4)
    turned = 2 * np.arctan2(np.linalg.norm(res.q[-1, :3]), res.q[-1, 3])
    assert abs(turned - rate * 20.0) < 0.01  # the whole turn is integrated, none held


def test_gyro_only_variance_after_one_rest_is_the_closed_form():
    # one rest, then 20 s of shaking without turning (the accelerometer rules out a rest):
    # body and output axes coincide, so per axis var(t) = SE² t² + σ² dt t with SE² = σ²/n
    rng = np.random.default_rng(3)
    n = int(28 * RATE_HZ)
    dt = 1.0 / RATE_HZ
    t = (10**9 + np.arange(n) * 5_000_000).astype(np.int64)
    sigma = 2e-3
    w = np.array([0.002, -0.001, 0.003]) + rng.normal(scale=sigma, size=(n, 3))
    a = np.array([0.0, 0.0, G]) + rng.normal(scale=0.02, size=(n, 3))
    a[int(8 * RATE_HZ):] += rng.normal(scale=1.0, size=(n - int(8 * RATE_HZ), 3))
    cov = np.broadcast_to(np.diag([sigma ** 2] * 3).reshape(9), (n, 9))
    cfg = StreamConfig(gyro_scale_factor_sigma=0.0, aiding="none")
    res = estimate_offline(t, w, a, config=cfg, angular_velocity_covariance=cov)
    assert res.bias.rests_used == 1
    se2 = sigma ** 2 / res.bias.rest_samples
    # integrated everywhere but at the rest's samples (its first and last window are not known
    # to be at rest from both sides: integrated too, with the same bias)
    t_motion = (n - res.bias.rest_samples) * dt
    expected = se2 * t_motion ** 2 + sigma ** 2 * dt * t_motion
    np.testing.assert_allclose(res.variance[-1], expected, rtol=0.03)


def test_the_tail_of_a_turn_is_integrated_not_held():
    # a turn that ends in 0.4 s at 0.008 rad/s (below every rest bound) before the rest: the
    # window starting in that tail passes the rest test; holding the attitude over it would
    # lose 3.2e-3 rad of the turn
    n = int(26 * RATE_HZ)
    dt = 1.0 / RATE_HZ
    t = (10**9 + np.arange(n) * 5_000_000).astype(np.int64)
    s = np.arange(n) * dt
    rate = np.where((s >= 8) & (s < 15), 0.5, 0.0) + np.where((s >= 15) & (s < 15.4), 0.008, 0.0)
    rng = np.random.default_rng(4)
    w = np.zeros((n, 3))
    w[:, 2] = rate
    w += rng.normal(scale=1e-4, size=(n, 3))
    a = np.array([0.0, 0.0, G]) + rng.normal(scale=0.01, size=(n, 3))
    a[(s >= 8) & (s < 15)] += rng.normal(scale=1.0, size=(int(7 * RATE_HZ), 3))
    res = estimate_offline(t, w, a, config=StreamConfig(gyro_bias="none"))
    res_auto = estimate_offline(t, w, a)
    turn = 0.5 * 7.0 + 0.008 * 0.4
    for r in (res, res_auto):
        yaw = 2 * np.arctan2(r.q[-1, 2], r.q[-1, 3])
        assert abs(yaw - turn) < 5e-4, (yaw, turn)


def _brute_smoother(t_ns, act, still, x, tau):
    """The tilt smoother by its definition, O(n²): kernel e^(−|s_k − s_j|/τ) on the clock that
    advances by the stamp step at accepted rows and not at still ones; n_eff = (Σkw)²/Σk²w²."""
    ds = np.diff(t_ns, prepend=t_ns[0]) * 1e-9
    ds[(act != v.ACTION_CODES[v.ACCEPT]) | still] = 0.0
    s = np.cumsum(ds)
    k = np.exp(-np.abs(s[:, None] - s[None, :]) / tau)
    w = x[:, -1]
    sw = k @ w
    return k @ x, sw * sw / ((k * k) @ (w * w))


@pytest.mark.parametrize("chunk", [64, 10_000])
def test_the_smoother_clock_stops_where_the_attitude_is_held(chunk):
    # the one zero-phase smoother against its definition: jittered stamps, a gap restart,
    # two still stretches (a rest's rows share the instant of the motion's end next to it),
    # weights 0 and 1, chunk boundaries, and stretches far beyond _SPAN time constants
    rng = np.random.default_rng(3)
    n = 700
    t = np.cumsum(rng.uniform(3e6, 7e6, n)).astype(np.int64)
    t[400:] += 2 * 10**9  # a gap: held across
    act = np.full(n, v.ACTION_CODES[v.ACCEPT])
    act[0] = act[400] = v.ACTION_CODES[v.START]
    still = np.zeros(n, bool)
    still[100:250] = True
    still[500:520] = True
    x = rng.normal(size=(n, 4))
    x[:, 3] = rng.uniform(size=n) > 0.2
    x[:, :3] *= x[:, 3:]
    for tau in (0.05, 1e-4):  # 1e-4 s: the clock spans thousands of τ (pieces, underflow)
        est = type("Stub", (), {})()
        est.t, est.act, est.size = t, act, chunk
        est._clock_steps = lambda b0, c0, c1, st, e=est: offline._Estimator._clock_steps(
            e, b0, c0, c1, st)
        got_sm = np.empty((n, 4))
        got_n = np.empty(n)

        def apply(c0, c1, sm, n_eff, extra, got_sm=got_sm, got_n=got_n):
            assert extra == (c0, c1)  # the columns' extra, of the same chunk
            got_sm[c0:c1] = sm
            got_n[c0:c1] = n_eff

        offline._Estimator._zero_phase(est, 0, n, tau, lambda c0, c1: (x[c0:c1].copy(), (c0, c1)),
                                       apply, still=still)
        want_sm, want_n = _brute_smoother(t, act, still, x, tau)
        dt = np.median(np.diff(t)) * 1e-9
        alpha = np.exp(-dt / tau)
        np.testing.assert_allclose(got_sm, want_sm * (1 - alpha) / (1 + alpha), rtol=1e-9,
                                   atol=1e-12)
        np.testing.assert_allclose(got_n, want_n, rtol=1e-9)
    # at a still stretch every row counts whole: n_eff at least its weighted rows
    assert got_n[150] >= x[100:250, 3].sum() - 1e-9
