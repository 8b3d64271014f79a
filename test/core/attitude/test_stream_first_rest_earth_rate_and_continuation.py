"""Attitude-stream cases, each against a closed form: the first-rest
bias correction (when it applies, its sign on the attitude and the covariance), Earth-rate removal
while estimating the bias, the gyrocompass heading variance after levelling, and the covariance
state run() hands on to a later push()."""

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from stages import bias_rows

from gyro_attitude.core.attitude import NavFrame, chain
from gyro_attitude.core.attitude.gyro_bias import BAD_ATTITUDE, J_HAS_SEG, bias_start, bias_step
from gyro_attitude.core.attitude.stream import RUNNING, AttitudeStream, StreamConfig

MS = 1_000_000
G = 9.80665
OMEGA_IE = 7.292115e-5  # WGS-84 Earth rate, written out (DESIGN.md conventions)
RATE_HZ = 100.0
H = 1.0 / RATE_HZ
W = 50  # samples in the default 0.5 s rest window at 100 Hz (stamps exact multiples of 10 ms)


def angle(a, b):
    return (Rotation.from_quat(a).inv() * Rotation.from_quat(b)).magnitude()


def earth_rate_body(q_nb, lat):
    """C_bn ω_ie^n with ω_ie^n = [0, Ω cos L, Ω sin L] (ENU), scipy as the rotation oracle."""
    return Rotation.from_quat(q_nb).inv().apply([0.0, OMEGA_IE * math.cos(lat),
                                                 OMEGA_IE * math.sin(lat)])


def stamps(n):
    return np.arange(n, dtype=np.int64) * 10 * MS + 10 * MS


# ------------------------------------------------------------------------- 1. first-rest correction
Q0 = Rotation.from_rotvec([0.6, -0.9, 0.5]).as_quat()  # far from identity: body vs nav side
BIAS = np.array([0.008, -0.006, 0.01])  # rad/s, within rest_gyro_mean_max 0.011 on every axis
SIGMA = 1e-6  # rad/s per-sample gyro noise (a real gyro's: the rest detector asks for some)
V0, N_DENS, SIGMA_B0 = 1e-14, 1e-7, 0.05


def still_body(n, shaken=0, seed=11):
    """A body that never turns (at Q0, no Earth rate): gyro = BIAS + white noise; the specific
    force is gravity, with ±3 m/s² of vibration on x over the first ``shaken`` samples (no turn:
    only the accelerometer keeps those samples out of a rest)."""
    rng = np.random.default_rng(seed)
    g = BIAS + SIGMA * rng.standard_normal((n, 3))
    f = np.tile(Rotation.from_quat(Q0).inv().apply([0.0, 0.0, G]), (n, 1))
    f[:shaken, 0] += 3.0 * (-1.0) ** np.arange(shaken)
    return stamps(n), g, f


# The correction is for a given initial attitude only: with initial_attitude "level" the first rest
# is the alignment rest, whose bias updates all come while aligning (zero-rate updates), so that
# condition has no effect a test can see there.


def first_rest_config():
    # auto bias (the default), given attitude; variances chosen so that the bias-estimate term
    # (elapsed² · SE², SE ≈ 1e-7 rad/s) is as large as the others and rtol 1e-9 sees it
    return StreamConfig(aiding="none", initial_attitude_variance=V0, gyro_noise_density=N_DENS,
                        gyro_bias_sigma_rad_s=SIGMA_B0)


def push_all(s, t, g, f):
    qs, var = [], []
    for k in range(t.size):
        _, q = s.push(int(t[k]), g[k], "imu", None, f[k])
        qs.append(q)
        var.append(s.variance)
    return np.array(qs), np.array(var)


def standard_error(g, first, last):
    """Standard error of the mean of rest samples first..last (one rest): s / √n, ddof 1."""
    x = g[first:last + 1]
    return np.std(x, axis=0, ddof=1) / math.sqrt(x.shape[0])


def test_first_rest_takes_the_bias_back_to_the_start_on_attitude_and_covariance():
    # Still from the start: the rest samples are the oldest of each rest window, sample k − W at
    # sample k ≥ W.  The rest qualifies when its samples span min_rest_s = 1 s, i.e. rest sample
    # 100 at sample K = 150; the estimate is then the mean of g[0..100] and the samples up to
    # 149 had been integrated with bias 0 over Δt = t_149 − t_0 = 1.49 s.  The body did not turn,
    # so after the correction the attitude is Q0 up to the estimate error (σ/√101 · 1.5 s ≈ 1.5e-7
    # rad per axis) plus integrated noise (σ·h·√k ≈ 1.7e-7): 2e-6 is > 5σ.  Uncorrected, the
    # error is |b|·1.49 s = 0.08 rad; with the opposite sign 0.16; applied on the nav side
    # (exp(−bΔt) ⊗ q) ≈ 0.1; with Δt one sample off, |b|·h = 5.4e-4.
    n, K = 400, 150
    t, g, f = still_body(n)
    qs, var = push_all(AttitudeStream("exp_map", q0=Q0, config=first_rest_config()), t, g, f)
    # before the rest qualifies: raw integration, q0 ⊗ exp(b t) (exp_map of a constant rate)
    for k in (1, 80, K - 1):
        expected = Rotation.from_quat(Q0) * Rotation.from_rotvec(BIAS * k * H)
        assert angle(qs[k], expected.as_quat()) < 2e-6, k
    err = np.array([angle(qs[k], Q0) for k in range(K, n)])
    assert err.max() < 2e-6, err.max()

    # Covariance, per axis (covariance.py): tt_k = V0 + k q + (k h)² σ_b0² before the rest
    # (q = N² h); at K the first estimate is applied back to the start: tt = V0 + Σq + Δt² SE²,
    # tb = −Δt SE², and the interval ending at K makes it V0 + K q + (K h)² SE_K²; every later
    # sample is a zero-rate update (tb = 0, bb = SE_k²) and adds q + h² SE_k².
    q = N_DENS ** 2 * H
    k = np.arange(K)
    before = V0 + k * q + (k * H) ** 2 * SIGMA_B0 ** 2
    np.testing.assert_allclose(var[:K], np.repeat(before[:, None], 3, axis=1), rtol=1e-9, atol=0)
    se = np.array([standard_error(g, 0, j - W) for j in range(K, n)])
    expected = V0 + np.arange(K, n)[:, None] * q + (K * H) ** 2 * se[0] ** 2
    expected[1:] += np.cumsum(H * H * se[1:] ** 2, axis=0)
    np.testing.assert_allclose(var[K:], expected, rtol=1e-9, atol=0)
    # the estimate error itself stays within its standard error's reach
    assert np.all(np.abs(np.mean(g[:K - W + 1], axis=0) - BIAS) < 5 * se[0])


@pytest.mark.parametrize("shaken, corrected", [(W, True), (W + 1, False)])
def test_first_rest_correction_only_for_a_rest_from_within_one_window_of_the_start(shaken,
                                                                                    corrected):
    # The accelerometer vibrates over the first `shaken` samples (no turn).  The first rest
    # sample is then sample `shaken`: exactly one window (0.5 s) after the start for W, which
    # the policy still calls "rests from its start"; one sample later it is not.  The rest
    # qualifies at sample K = shaken + 150.
    n = 450
    t, g, f = still_body(n, shaken=shaken, seed=12)
    K = shaken + 150
    qs, var = push_all(AttitudeStream("exp_map", q0=Q0, config=first_rest_config()), t, g, f)
    if corrected:
        # body still: back to Q0, to the estimate error (as above, over 2 s: < 2e-6)
        assert angle(qs[-1], Q0) < 2e-6
        # the bias uncertainty before the rest (σ_b0 = 0.05 rad/s over 2 s: 1e-2 rad²) is gone
        assert np.all(var[-1] < 1e-12)
    else:
        # The bias integrated until it is first subtracted: raw rate up to sample K − 1 and,
        # the trapezoid averaging b with b − b̂ ≈ 0, half of the interval ending at K; nothing
        # after (the estimate is good to ~1e-7 rad/s · 2.5 s).
        expected = Rotation.from_quat(Q0) * Rotation.from_rotvec(BIAS * ((K - 1) * H + H / 2))
        assert angle(qs[-1], expected.as_quat()) < 2e-6
        # the attitude error from σ_b0 up to the rest stays: (Δt σ_b0)², Δt = (K − 1) h
        assert np.all(var[-1] >= ((K - 1) * H * SIGMA_B0) ** 2)


# ------------------------------------------------------------------------- 2. Earth rate
LAT = math.radians(50.0)
Q_TRUE = Rotation.from_euler("ZYX", [60.0, 4.0, -2.0], degrees=True)  # heading 30° (ENU yaw 60°)
B_SMALL = np.array([2e-4, -1e-4, 3e-4])  # rad/s
SIGMA_W = 1e-6


def test_bias_stage_takes_the_earth_rate_out_at_the_given_attitude():
    # At rest at Q_TRUE, 50° N: gyro = C_bn ω_ie^n + b + noise.  With q_nb and the latitude the
    # rest average is b (to σ/√n ≈ 7e-8 over 200 rest samples); the Earth rate in the body
    # (≈ 7e-5 rad/s, all three axes non-zero here) must not be absorbed.  A quaternion is a
    # rotation whatever its norm: 3·q gives the same bias.
    n = 350
    rng = np.random.default_rng(21)
    t = stamps(n)
    earth_b = earth_rate_body(Q_TRUE.as_quat(), LAT)
    assert np.all(np.abs(earth_b) > 1e-5)
    g = earth_b + B_SMALL + SIGMA_W * rng.standard_normal((n, 3))
    for scale in (1.0, 3.0):
        _, rep = bias_rows(t, g, None, np.tile(scale * Q_TRUE.as_quat(), (n, 1)),
                           latitude_rad=LAT)
        assert rep.rests_used == 1 and rep.earth_rate_removed
        # estimate = mean of the rest samples 0..n−1−W minus the Earth rate (closed form)
        expected = np.mean(g[:n - W], axis=0) - earth_b
        np.testing.assert_allclose(rep.bias, expected, rtol=0, atol=1e-12)
        assert np.all(np.abs(rep.bias - B_SMALL) < 5 * SIGMA_W / math.sqrt(n - W))
    # a zero quaternion is no attitude: refused, nothing accumulated
    rf, ri, bf, bi = bias_start(StreamConfig())
    ring = np.zeros(64, chain.BIAS_RING_DTYPE).view(np.recarray)
    assert bias_step(bf, bi, 10**9, rf, ri, ring.t, ring.x, ring.c, ring.pv, ring.pe,
                     np.ones(3), int(t[0]), *g[0], False, 0.0, 0.0, 0.0, True, 0.0, 0.0, 0.0,
                     0.0) == BAD_ATTITUDE
    assert not bi[J_HAS_SEG]


@pytest.mark.parametrize("where", ["config", "nav"])
def test_stream_takes_the_earth_rate_out_at_the_current_attitude(where):
    # From Q0 the body turns 90° about its z axis at π/4 rad/s for 2 s, then rests 3 s at
    # q_rest = Q0 ⊗ Rz(90°), at 50° N; the gyro measures C_bn(t) ω_ie^n + ω_nb^b + b + noise.
    # The rest average minus the Earth rate at the CURRENT attitude is b; taking it at the
    # initial attitude instead would leave ≈ √2 Ω cos L ≈ 6.6e-5 rad/s, ignoring it ≈ 7e-5.
    # Error budget: σ/√250 ≈ 6e-8; the attitude error before the bias is known (b·5 s ≈ 2e-3
    # rad, plus the trapezoid's half step at the rate jumps, ≈ 4e-3) tilts the Earth rate by
    # ≈ 7e-5 · 6e-3 = 4e-7: 1e-6.
    n_turn, n_rest = 200, 300
    n = n_turn + n_rest
    r = (math.pi / 2) / (n_turn * H)
    t = stamps(n)
    q0 = Rotation.from_quat(Q0)
    turned = np.minimum(np.arange(n), n_turn) * H * r  # angle about body z at each sample
    q_t = q0 * Rotation.from_rotvec(np.outer(turned, [0.0, 0.0, 1.0]))
    w_n = np.array([0.0, OMEGA_IE * math.cos(LAT), OMEGA_IE * math.sin(LAT)])
    g = q_t.inv().apply(w_n) + B_SMALL + SIGMA_W * np.random.default_rng(22).standard_normal(
        (n, 3))
    g[1:n_turn + 1, 2] += r
    if where == "config":
        s = AttitudeStream("exp_map", q0=Q0, config=StreamConfig(frame="enu", latitude_rad=LAT))
    else:
        s = AttitudeStream("exp_map", q0=Q0, nav=NavFrame(latitude_rad=LAT))
    for k in range(n):
        s.push(int(t[k]), g[k], "imu")
    rep = s.bias_report
    assert rep.rests_used == 1 and rep.earth_rate_removed
    np.testing.assert_allclose(rep.bias, B_SMALL, rtol=0, atol=1e-6)


def test_bias_estimated_while_levelling_has_no_earth_rate():
    # initial_attitude "level", auto bias, latitude known, the given heading right (30°): while
    # aligning, each sample's attitude is levelled from its specific force with that heading, and
    # the Earth rate at it is taken out of the rest average: the bias is b (σ/√250 ≈ 6e-8, the
    # per-sample levelling error 1e-3/g ≈ 1e-4 rad costs 7e-9 of Earth rate), not b + C_bn ω_ie^n
    # (≈ 7e-5); the heading in radians (30 rad is another heading) and with its sign (−30°:
    # ≈ 5e-5 off) matters.  The rest ends with a turn about z at sample 300.
    n, m = 400, 300
    rng = np.random.default_rng(23)
    t = stamps(n)
    g = earth_rate_body(Q_TRUE.as_quat(), LAT) + B_SMALL + SIGMA_W * rng.standard_normal((n, 3))
    g[m:, 2] += 0.5
    f = Q_TRUE.inv().apply([0.0, 0.0, G]) + 1e-3 * rng.standard_normal((n, 3))
    s = AttitudeStream("exp_map", config=StreamConfig(initial_attitude_source="level",
                                                      initial_heading_deg=30.0, frame="enu",
                                                      latitude_rad=LAT))
    for k in range(n):
        s.push(int(t[k]), g[k], "imu", None, f[k])
    assert s.phase == RUNNING
    rep = s.bias_report
    assert rep.rests_used == 1 and rep.earth_rate_removed
    np.testing.assert_allclose(rep.bias, B_SMALL, rtol=0, atol=3e-7)


# ------------------------------------------------------------------------- 3. heading variance
@pytest.mark.parametrize("source", ["gyrocompass", "parameter"])
def test_heading_variance_after_levelling_from_the_documented_expressions(source):
    # Static at 45° N at heading 30°, pitch 10°, roll −3°, with per-axis different gyro and
    # accelerometer noise, then a turn about z from sample m.  The rest samples are 0..m−1−W.
    # alignment.py documents, with n rest samples, f̄ their mean specific force, var_* their
    # per-axis sample variances (ddof 1), g = |f̄|:
    #   level variance  lv = (σ_ba² + mean(var_f[x, y]) / n) / g²
    #   gyrocompass     σ_h² = (σ_b² + mean(var_ω[x, y]) / n) / (Ω cos L)² + lv tan² L
    # and stream.py: the heading axis also takes the roll error through the pitch,
    # sin²θ · lv (sin θ = −f̄_x / g).  A given heading has the initial_variance instead.
    # Then the 50 intervals from the last rest sample to m add (50 h)² σ_b² (bias uncertainty,
    # no noise density given).
    lat = math.radians(45.0)
    q_true = Rotation.from_euler("ZYX", [60.0, 10.0, -3.0], degrees=True)
    n, m = 400, 300
    rng = np.random.default_rng(31)
    t = stamps(n)
    b = np.array([2e-5, -1e-5, 3e-5])
    g = (earth_rate_body(q_true.as_quat(), lat) + b
         + np.array([1e-7, 2e-7, 3e-7]) * rng.standard_normal((n, 3)))
    g[m:, 2] += 0.5
    f = q_true.inv().apply([0.0, 0.0, G]) + np.array([2e-3, 4e-3, 6e-3]) * rng.standard_normal(
        (n, 3))
    sigma_b, sigma_ba, v_given = 2e-7, 0.05, 1e-2
    cfg = StreamConfig(initial_attitude_source="level", heading_source=source, gyro_bias="parameter",
                       gyro_bias_rad_s=tuple(b), gyro_bias_sigma_rad_s=sigma_b,
                       accel_bias_sigma=sigma_ba, latitude_rad=lat, initial_heading_deg=30.0,
                       initial_attitude_variance=v_given)
    s = AttitudeStream("exp_map", config=cfg)
    first = None
    for k in range(n):
        _, q = s.push(int(t[k]), g[k], "imu", None, f[k])
        if q is not None and first is None:
            first, var = k, s.variance
    assert first == m
    last_rest = m - 1 - W
    assert s.alignment.rest_end_ns == t[last_rest] and s.alignment.heading_source == (
        "gyrocompass" if source == "gyrocompass" else "given")
    rest = slice(0, last_rest + 1)
    nr = last_rest + 1
    f_mean = np.mean(f[rest], axis=0)
    g_norm = np.linalg.norm(f_mean)
    var_f = np.var(f[rest], axis=0, ddof=1)
    var_w = np.var(g[rest], axis=0, ddof=1)
    lv = (sigma_ba ** 2 + np.mean(var_f[:2]) / nr) / g_norm ** 2
    if source == "gyrocompass":
        heading_var = ((sigma_b ** 2 + np.mean(var_w[:2]) / nr) / (OMEGA_IE * math.cos(lat)) ** 2
                       + lv * math.tan(lat) ** 2)
    else:
        heading_var = v_given
    sin_pitch = -f_mean[0] / g_norm
    expected = np.array([lv, lv, heading_var + sin_pitch ** 2 * lv]) + (W * H * sigma_b) ** 2
    np.testing.assert_allclose(var, expected, rtol=1e-9, atol=0)
    if source == "gyrocompass":
        # the figure is that of the heading found: within 3σ of the truth (30°)
        assert abs(s.alignment.heading - math.radians(30.0)) < 3 * math.sqrt(heading_var)


# ------------------------------------------------------------------------- 4. run() then push()
def moving_recording(n, seed):
    rng = np.random.default_rng(seed)
    t = stamps(n) + 10_000 * MS  # room for a backward jump
    w = np.column_stack([0.3 * np.sin(np.arange(n) * 0.05), 0.2 * np.cos(np.arange(n) * 0.03),
                         0.5 + 0.01 * rng.standard_normal(n)])
    return t, w


RUN_PUSH_CONFIGS = {
    "parameter": StreamConfig(gyro_bias="parameter", gyro_bias_rad_s=(0.01, -0.02, 0.005),
                              gyro_bias_sigma_rad_s=1e-3, gyro_bias_rw=1e-3,
                              gyro_noise_density=1e-4, initial_attitude_variance=1e-6),
    "none": StreamConfig(gyro_bias="none", gyro_bias_sigma_rad_s=2e-3, gyro_bias_rw=5e-4,
                         initial_attitude_variance=3e-6),
}


@pytest.mark.parametrize("name", sorted(RUN_PUSH_CONFIGS))
def test_push_after_run_continues_the_covariance_recurrence(name):
    # Sequential reference: push() over the whole recording.  run() over the first part (batch
    # path: a time-jump reset and a gap inside, a gyro covariance on part of the rows) and push()
    # over the rest must give the same attitudes and variances: the recurrence tt, tb, bb
    # (tb ≠ 0 and bb grown by the bias walk) continues where run() left it.
    cfg = RUN_PUSH_CONFIGS[name]
    n, split = 400, 250
    t, w = moving_recording(n, seed=41)
    t[120:] += 300 * MS  # a gap
    t[180:] -= 2_500 * MS  # a backward time jump: the attitude and tt reset, bb kept
    cov = np.zeros((n, 9))
    cov[60:200] = np.diag([1e-6, 2e-6, 3e-6]).reshape(9)
    ref = AttitudeStream("exp_map", config=cfg)
    q_ref, v_ref = [], []
    for k in range(n):
        _, q = ref.push(int(t[k]), w[k], "imu", cov[k])
        q_ref.append(q)
        v_ref.append(ref.variance)
    s = AttitudeStream("exp_map", config=cfg)
    res = s.run(t[:split], w[:split], "imu", cov[:split])
    assert res.time_jump_resets == 1 and res.index.size == split
    np.testing.assert_allclose(res.variance, np.array(v_ref[:split]), rtol=1e-12, atol=0)
    assert np.all(s.state.cov[0][3:6] != 0)  # the state carried on (tb) is not a fresh one
    for k in range(split, n):
        _, q = s.push(int(t[k]), w[k], "imu", cov[k])
        np.testing.assert_allclose(s.variance, v_ref[k], rtol=1e-12, atol=0)


def test_push_after_run_with_auto_bias_continues_as_push():
    # auto bias on a recording that never rests takes run()'s batch path; the stream then goes
    # on with push() into a rest.  push() from the start sees a rest that begins 4 s after the
    # start: no first-rest correction (a zero-rate update).  After run() the stream must be
    # where push() would have left it, so the continuation must be the same.
    n1, n2 = 400, 300
    t, w = moving_recording(n1 + n2, seed=42)
    rng = np.random.default_rng(43)
    w[n1:] = np.array([0.008, -0.006, 0.01]) + 1e-6 * rng.standard_normal((n2, 3))
    cfg = StreamConfig(gyro_noise_density=1e-5, gyro_bias_sigma_rad_s=0.05)
    ref = AttitudeStream("exp_map", config=cfg)
    for k in range(n1 + n2):
        _, q_ref = ref.push(int(t[k]), w[k], "imu")
    s = AttitudeStream("exp_map", config=cfg)
    s.run(t[:n1], w[:n1], "imu")
    for k in range(n1, n1 + n2):
        _, q = s.push(int(t[k]), w[k], "imu")
    assert ref.bias_report.rests_used == s.bias_report.rests_used == 1
    np.testing.assert_allclose(s.variance, ref.variance, rtol=1e-12, atol=0)
    assert angle(q, q_ref) < 1e-12


def test_first_push_after_run_takes_the_trapezoid_with_the_last_run_sample():
    # exp_map integrates each interval with exp(½(ω_{k−1} + ω_k) h) (algorithm.py): after run()
    # over samples 0..k−1, the push of sample k must give q_{k−1} ⊗ exp(½(ω_{k−1} + ω_k) h),
    # as push() from the start does.
    cfg = StreamConfig(gyro_bias="none")
    t, w = moving_recording(300, seed=44)
    s = AttitudeStream("exp_map", config=cfg)
    res = s.run(t[:200], w[:200], "imu")
    _, q = s.push(int(t[200]), w[200], "imu")
    expected = Rotation.from_quat(res.q[-1]) * Rotation.from_rotvec(0.5 * (w[199] + w[200]) * H)
    # rounding of one product; holding ω_200 alone costs ½|ω_200 − ω_199| h ≈ 1e-4 rad here
    assert angle(q, expected.as_quat()) < 1e-14
