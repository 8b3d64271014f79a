"""The attitude-stream policy: per-sample and whole-recording paths agree, bad samples are skipped
and counted, gaps hold and time jumps reset the attitude (closed form), the variance grows as
written out, and no input ever gives a non-finite attitude."""

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from gyro_attitude.core.attitude import chain
from gyro_attitude.core.attitude import validation as iv
from gyro_attitude.core.attitude.stream import (
    INTEGRATOR_ERROR,
    INVALID_COVARIANCE,
    AttitudeStream,
    StreamConfig,
    _covariance_row,
)
from gyro_attitude.core.jit import compiled


def gyro_variances(cov):
    """(variances or None, invalid) by the step's verdict on one covariance as push() takes
    it (a row that is not 9 numbers becomes NaN: invalid)."""
    code, *d = compiled(chain.covariance_verdict)(_covariance_row(cov))
    return (tuple(d) if code == chain.COV_KNOWN else None), code == chain.COV_INVALID

MS = 1_000_000
CAUSAL = ["rotvec_cubic", "exp_map"]  # the algorithms of the estimator's step


def push_all(stream, t, w, frame="imu", cov=None):
    out = []
    for k in range(len(t)):
        frame_k = frame if isinstance(frame, str) else frame[k]
        _, q = stream.push(int(t[k]), w[k], frame_k, None if cov is None else cov[k])
        if q is not None:
            out.append((k, q, stream.variance))
    return out


def hostile_stream(n=400, seed=0):
    """A 1 kHz stream with NaN, inf, 1e300 and 1e200 rates, zero, duplicate and out-of-order
    stamps, a changed frame, a 5 s gap and a 2.5 s backward jump."""
    rng = np.random.default_rng(seed)
    t = 10_000_000_000 + np.arange(n, dtype=np.int64) * MS
    w = np.cumsum(rng.normal(scale=0.05, size=(n, 3)), axis=0) + [0.3, -0.2, 0.5]
    frames = ["imu"] * n
    w[10] = [np.nan, 0, 0]
    w[11] = [0, np.inf, 0]
    w[12] = [1e300, 0, 0]
    w[13] = [0, 0, -1e200]
    t[20] = 0
    t[30] = t[29]  # duplicate
    t[40] = t[39] - 3 * MS  # out of order (small backward step)
    frames[50] = "other"
    t[100:] += 5_000_000_000  # gap of 5 s
    t[250:] -= 7_500_000_000  # backward jump of ~2.5 s
    cov = np.tile(np.diag([1e-6, 2e-6, 3e-6]).reshape(9), (n, 1))
    cov[60] = np.nan
    cov[61, 4] = -1.0
    return t, w, frames, cov


@pytest.mark.parametrize("algorithm", CAUSAL)
def test_run_equals_push_sample_for_sample(algorithm):
    t, w, frames, cov = hostile_stream()
    cfg = StreamConfig(initial_attitude_variance=1e-4)
    pushed = push_all(AttitudeStream(algorithm, config=cfg), t, w, frames, cov)
    res = AttitudeStream(algorithm, config=cfg).run(t, w, frames, cov)
    assert res.index.tolist() == [k for k, _, _ in pushed]
    q_push = np.array([q for _, q, _ in pushed])
    assert np.max(np.abs(res.q - q_push)) <= 1e-12
    var_push = np.array([var for _, _, var in pushed])
    np.testing.assert_allclose(res.variance, var_push, rtol=1e-12, atol=0)
    assert res.variance_known.all()


def test_counts_by_reason_are_exact():
    t, w, frames, cov = hostile_stream()
    res = AttitudeStream("exp_map").run(t, w, frames, cov)
    c = res.counts
    assert c[iv.NON_FINITE] == 2 and c[iv.IMPLAUSIBLE_RATE] == 2
    assert c[iv.ZERO_STAMP] == 1 and c[iv.DUPLICATE_STAMP] == 1 and c[iv.OUT_OF_ORDER] == 1
    assert c[iv.FRAME_CHANGED] == 1 and c[iv.GAP] == 1
    assert c[INVALID_COVARIANCE] == 2 and c[INTEGRATOR_ERROR] == 0
    assert res.time_jump_resets == 1
    assert res.skipped == 8 and len(res.index) == len(t) - 8
    assert "time_jump" in res.details and iv.GAP in res.details


def test_gap_holds_and_jump_resets_in_closed_form():
    # constant rate about z: the attitude is exp(ω (t - t_start)) from the segment's start q
    wz = 0.7
    t = 10_000_000_000 + np.arange(1, 201, dtype=np.int64) * 10 * MS
    t[100:] += 2_000_000_000  # 2 s gap before sample 100
    t[150:] -= 4_000_000_000  # 2 s backward jump at sample 150 (beyond 1 s)
    w = np.tile([0.0, 0.0, wz], (200, 1))
    q0 = Rotation.from_euler("xyz", [0.3, -0.2, 1.0]).as_quat()
    res = AttitudeStream("exp_map", q0=q0).run(t, w, "imu")
    q = res.q
    t_s = t * 1e-9

    def expect(q_start, t_start, k):
        return (Rotation.from_quat(q_start) * Rotation.from_rotvec([0, 0, wz * (t_s[k] -
                                                                          t_start)])).as_quat()

    angle = lambda a, b: (Rotation.from_quat(a).inv() * Rotation.from_quat(b)).magnitude()  # noqa
    assert angle(q[99], expect(q0, t_s[0], 99)) < 1e-13
    # after the gap: held at q[99], restarted at sample 100 (nothing integrated across 2 s)
    assert angle(q[100], q[99]) < 1e-15
    assert angle(q[149], expect(q[99], t_s[100], 149)) < 1e-13
    # after the jump: back to the initial attitude at sample 150
    assert angle(q[150], q0) < 1e-15
    assert angle(q[199], expect(q0, t_s[150], 199)) < 1e-13


def test_variance_growth_written_out():
    n, dt_ms, sigma2 = 500, 5, 4e-6
    t = np.arange(1, n + 1, dtype=np.int64) * dt_ms * MS
    w = np.zeros((n, 3))
    cov = np.tile(np.diag([sigma2, 2 * sigma2, 3 * sigma2]).reshape(9), (n, 1))
    init = 1e-5
    for path in ("push", "run"):
        s = AttitudeStream("exp_map", config=StreamConfig(initial_attitude_variance=init))
        if path == "push":
            var = np.array([v for _, _, v in push_all(s, t, w, "imu", cov)])
        else:
            var = s.run(t, w, "imu", cov).variance
        k = np.arange(n)[:, None]
        expected = init + np.array([1, 2, 3]) * sigma2 * (dt_ms * 1e-3) ** 2 * k
        # the growth itself is ~1e-10 per sample: compare with atol=0
        np.testing.assert_allclose(var, expected, rtol=1e-12, atol=0)


def test_unknown_covariance_gives_no_variance():
    t = np.arange(1, 11, dtype=np.int64) * MS
    w = np.zeros((10, 3))
    no_estimate = np.zeros((10, 9))
    no_estimate[:, 0] = -1.0
    for cov in (None, np.zeros((10, 9)), no_estimate):
        res = AttitudeStream().run(t, w, "imu", cov)
        assert res.variance is None
        s = AttitudeStream()
        push_all(s, t, w, "imu", cov)
        assert s.variance is None


@pytest.mark.parametrize("cov, expected", [
    ([-1.0] + [0.0] * 8, (None, False)),
    ([0.0] * 9, (None, False)),
    ([math.nan] + [0.0] * 8, (None, True)),
    ([1.0, 0, 0, 0, -1.0, 0, 0, 0, 1.0], (None, True)),
    ([1.0] * 8, (None, True)),
])
def test_gyro_variances_classification(cov, expected):
    var, invalid = gyro_variances(cov)
    assert (var is None, invalid) == (expected[0] is None, expected[1])


@pytest.mark.parametrize("algorithm", CAUSAL)
@pytest.mark.parametrize("huge", [1e200, 1e100, 1.5e4])
def test_implausible_rate_is_skipped_not_propagated(algorithm, huge):
    t = np.arange(1, 101, dtype=np.int64) * MS
    w = np.tile([0.1, 0.0, 0.0], (100, 1))
    w[50] = [huge, 0.0, 0.0]
    s = AttitudeStream(algorithm)
    out = push_all(s, t, w)
    q = np.array([q for _, q, _ in out])
    assert np.isfinite(q).all() and len(out) == 99
    assert s.counts[iv.IMPLAUSIBLE_RATE] == 1
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, rtol=0, atol=1e-15)


def test_max_rate_is_a_setting():
    t = np.arange(1, 11, dtype=np.int64) * MS
    w = np.tile([5.0, 0.0, 0.0], (10, 1))
    res = AttitudeStream(config=StreamConfig(max_rate_rad_s=4.0)).run(t, w, "imu")
    assert res.counts[iv.IMPLAUSIBLE_RATE] == 10 and res.index.size == 0
    with pytest.raises(ValueError, match="max_rate_rad_s"):
        StreamConfig(max_rate_rad_s=math.nan)


def test_non_finite_update_restores_last_good_attitude():
    t = np.arange(1, 21, dtype=np.int64) * MS
    w = np.tile([0.0, 0.0, 1.0], (20, 1))
    s = AttitudeStream("exp_map")
    out = push_all(s, t[:9], w[:9])
    s.state.cubic_f[0][:4] = math.nan  # the integrator's attitude lost before sample 9
    out += [(k + 9, q, v) for k, q, v in push_all(s, t[9:], w[9:])]
    q = np.array([q for _, q, _ in out])
    assert np.isfinite(q).all() and len(out) == 19
    assert s.counts[INTEGRATOR_ERROR] == 1
    # sample 9 (the bad one) is skipped; sample 10 restarts from the attitude at sample 8
    k = [i for i, _, _ in out]
    assert 9 not in k
    np.testing.assert_allclose(q[k.index(10)], q[k.index(8)], rtol=0, atol=0)


def test_algorithms_outside_the_step_are_refused_naming_the_choices():
    for name in ("quat_rk4", "coning2", "euler_zxz_rk4"):
        with pytest.raises(ValueError, match=r"\['exp_map', 'rotvec_cubic'\]"):
            AttitudeStream(name)
    with pytest.raises(ValueError, match="offline algorithm"):
        AttitudeStream("magnus6_quintic")


def test_run_needs_fresh_stream_and_valid_shapes():
    s = AttitudeStream()
    s.push(MS, [0, 0, 0], "imu")
    with pytest.raises(ValueError, match="fresh"):
        s.run(np.array([2 * MS]), np.zeros((1, 3)))
    with pytest.raises(ValueError, match="shape"):
        AttitudeStream().run(np.array([MS, 2 * MS]), np.zeros((3, 3)))
    with pytest.raises(ValueError, match="integer"):
        AttitudeStream().run(np.array([1.0, 2.0]), np.zeros((2, 3)))


finite_or_not = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([1e300, -1e300, 5e-324, 1e4, -1e4, 0.0]),
    st.floats(-20, 20),
)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    steps=st.lists(st.sampled_from([0, 1, 1, 1, 1, -1, -3000, 200, 5000, 10**12]),
                   min_size=1, max_size=60),
    rates=st.lists(st.tuples(finite_or_not, finite_or_not, finite_or_not), min_size=60,
                   max_size=60),
    covs=st.lists(st.sampled_from([None, 1e-6, -1.0, math.nan, math.inf, 0.0]), min_size=60,
                  max_size=60),
    algorithm=st.sampled_from(CAUSAL),
    start=st.sampled_from([0, 1, 10**9]),
)
def test_fuzz_never_non_finite_and_paths_agree(steps, rates, covs, algorithm, start):
    n = len(steps)
    t = start + np.cumsum(np.array(steps, dtype=np.int64) * MS)
    w = np.array(rates[:n], dtype=np.float64)
    cov = np.zeros((n, 9))
    for k, c in enumerate(covs[:n]):
        cov[k] = [c, 0, 0, 0, c, 0, 0, 0, c] if c is not None else [-1.0] + [0.0] * 8
    pushed = push_all(AttitudeStream(algorithm), t, w, "imu", cov)
    res = AttitudeStream(algorithm).run(t, w, "imu", cov)
    assert res.index.tolist() == [k for k, _, _ in pushed]
    if pushed:
        q_push = np.array([q for _, q, _ in pushed])
        assert np.isfinite(res.q).all() and np.isfinite(q_push).all()
        np.testing.assert_allclose(np.linalg.norm(res.q, axis=1), 1.0, rtol=0, atol=1e-12)
        assert np.max(np.abs(res.q - q_push)) <= 1e-12
        if res.variance is not None:
            assert np.isfinite(res.variance).all()


def test_settings_and_inputs_beyond_any_gyro_are_refused_or_unknown():
    """Bounds that keep every update finite: rate limit <= 1e6 rad/s, thresholds <= 1e6 s, a
    carrier's height and speed; an absurd gyro variance (1e308) counts as unknown, and the
    orientation variance stays finite."""
    from gyro_attitude.core.attitude import NavFrame

    for bad in (1e300, 2e6):
        with pytest.raises(ValueError, match="max_rate_rad_s"):
            StreamConfig(max_rate_rad_s=bad)
    with pytest.raises(ValueError, match="max_gap_s"):
        StreamConfig(max_gap_s=1e7)
    for kw, match in (({"velocity_enu": (1e300, 0.0, 0.0)}, "velocity_enu"),
                      ({"height_m": -7e6}, "height_m")):
        with pytest.raises(ValueError, match=match):
            NavFrame(latitude_rad=0.7, **kw).rate_enu()
    n = 1000
    t = np.arange(1, n + 1, dtype=np.int64) * 90 * MS
    cov = np.tile(np.diag([1e308, 1e308, 1e308]).reshape(9), (n, 1))
    cov[:10] = np.diag([1e-6, 1e-6, 1e-6]).reshape(9)
    res = AttitudeStream("exp_map", config=StreamConfig(max_gap_s=1.0)).run(
        t, np.zeros((n, 3)), "imu", cov)
    assert res.counts[INVALID_COVARIANCE] == n - 10
    assert np.isfinite(res.variance).all()
    assert gyro_variances(np.diag([1e308, 1.0, 1.0]).reshape(9)) == (None, True)
