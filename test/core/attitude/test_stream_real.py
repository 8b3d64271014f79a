"""Real-IMU steps of the attitude stream: run() equals push() in every mode (hostile samples in a
rest included), the bias is removed at rests, level alignment and gyrocompass refusal, the
first-rest correction, and the truth at an Imu stamp (scipy Slerp as the oracle)."""

import math
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp
from sim_static import OMEGA_IE, G, rest_motion_rest, static_imu

from gyro_attitude.core.attitude import NavFrame
from gyro_attitude.core.attitude.stream import (
    ALIGNING,
    INVALID_ACCEL,
    RUNNING,
    AttitudeStream,
    StreamConfig,
)
from gyro_attitude.core.attitude.truth import initial_attitude_from_truth, truth_at_stamps

# the modes and hostile inputs of the golden regression test (one home: test/golden)
sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "golden"))
from golden_cases import MODES, hostile_field, hostile_rest_motion_rest


def push_all(stream, t, g, a, cov, mag=None):
    out = []
    for k in range(t.size):
        _, q = stream.push(int(t[k]), g[k], "imu", cov[k], a[k],
                           None if mag is None else mag[k])
        if q is not None:
            out.append((k, q, stream.variance))
    return out


@pytest.mark.parametrize("mode", sorted(MODES))
def test_run_equals_push_in_every_mode(mode):
    t, g, a, cov = hostile_rest_motion_rest()
    cov = cov.copy()
    cov[450, 4] = -5.0  # an invalid covariance: counted, its first detail the same words
    cfg = MODES[mode]
    mag = hostile_field(t.size) if "magnetometer" in mode else None
    s_push = AttitudeStream("rotvec_cubic", config=cfg)
    pushed = push_all(s_push, t, g, a, cov, mag)
    s = AttitudeStream("rotvec_cubic", config=cfg)
    res = s.run(t, g, "imu", cov, a, mag)
    assert res.counts == s_push.counts
    # the first detail of every count in the same words (one note per rule)
    for key in ("invalid_accel", "invalid_covariance", "non_finite", "implausible_rate"):
        assert res.details.get(key) == s_push.details.get(key), key
    assert res.index.tolist() == [k for k, _, _ in pushed]
    assert np.max(np.abs(res.q - np.array([q for _, q, _ in pushed]))) <= 1e-12
    np.testing.assert_allclose(res.variance, np.array([v for _, _, v in pushed]), rtol=1e-12,
                               atol=0)
    assert np.all(np.isfinite(res.q)) and np.all(np.isfinite(res.variance))
    assert res.counts[INVALID_ACCEL] == 3  # counted on both paths, as push() counts them
    # the input rate and jitter: the same intervals counted, whatever the form
    assert s.intervals.summary() == s_push.intervals.summary()
    assert len(s.intervals) == len(s_push.intervals) > 100
    if cfg.levelling:
        assert res.alignment is not None and res.index[0] > 600  # no attitude while aligning



def test_auto_bias_removed_and_first_rest_applied_back():
    """Closed form: the motion's rate sin(2πs/T)·axis integrates to zero turn, so the truth at
    the end is the start attitude; the residual is the bias-estimate error × time + noise."""
    bias = (0.008, -0.004, 0.01)
    t, g, a, _ = rest_motion_rest(bias=bias, rests=(3.0, 2.0, 3.0))
    cov = np.tile(np.diag([0.002 ** 2] * 3).reshape(9), (t.size, 1))
    s = AttitudeStream("rotvec_cubic", config=StreamConfig())
    res = s.run(t, g, "imu", cov, a)
    err = Rotation.from_quat(res.q[-1]).magnitude()
    raw = AttitudeStream("rotvec_cubic", config=StreamConfig(gyro_bias="none")).run(t, g, "imu")
    raw_err = Rotation.from_quat(raw.q[-1]).magnitude()
    assert raw_err > 0.1  # |bias| · 11.5 s
    # 3σ of the stream's own per-axis variance (≈ 1.5e-4 rad each); measured ≈ 1e-4
    assert err <= 3 * math.sqrt(np.sum(res.variance[-1])), (err, res.variance[-1])
    rep = res.bias
    assert rep.rests_used == 3
    np.testing.assert_allclose(rep.bias, bias, rtol=0, atol=4 * np.max(rep.standard_error))
    assert not rep.earth_rate_removed and "absorbed" in rep.note


def test_first_rest_correction_goes_red_without_it(monkeypatch):
    """At 1.5 s into the initial rest the attitude had integrated the whole bias (0.014 rad/s
    · 1.5 s = 0.02 rad); the correction takes it back so that the rest stays at the start."""
    t, g, a = static_imu(1200, 200.0, (0, 0, 0, 1), 0.0, gyro_bias=(0.008, -0.006, 0.01),
                         gyro_noise=0.001, accel_noise=0.02)
    res = AttitudeStream(config=StreamConfig()).run(t, g, "imu", None, a)
    assert Rotation.from_quat(res.q[-1]).magnitude() < 2e-3


def test_earth_rate_taken_out_in_enu():
    """Static at 50°N in ENU, no bias: the rest average is the Earth rate, which the estimator
    takes out (the bias ≈ 0) and the q_nb stays put."""
    lat = math.radians(50.0)
    q_nb = Rotation.from_euler("z", 20, degrees=True).as_quat()
    t, g, a = static_imu(1000, 100.0, q_nb, lat, gyro_noise=2e-5, accel_noise=0.01, seed=3)
    s = AttitudeStream("rotvec_cubic", q0=q_nb, nav=NavFrame(latitude_rad=lat),
                       config=StreamConfig(aiding="none"))  # the gyro alone: its Earth rate
    res = s.run(t, g, "imu", None, a)
    assert res.bias.earth_rate_removed
    assert np.max(np.abs(res.bias.bias)) < 5 * np.max(res.bias.standard_error) + 1e-7
    assert np.max(np.abs(res.bias.bias)) < 0.05 * OMEGA_IE * 10
    ang = (Rotation.from_quat(res.q[-1]) * Rotation.from_quat(q_nb).inv()).magnitude()
    # noise alone: ≈ 1e-5 rad; the Earth rate absorbed and removed again by the nav frame
    # would turn it by ω_ie · 8.5 s ≈ 6e-4 rad
    assert ang < 1e-4


def test_level_alignment_from_specific_force_and_given_heading():
    q_true = Rotation.from_euler("ZYX", [60.0, 3.0, -4.0], degrees=True)  # yaw 60° from east
    t, g, a = static_imu(400, 100.0, q_true.as_quat(), 0.0, gyro_noise=1e-3,
                         accel_noise=0.02, seed=2)
    # then a rotation about z at 0.5 rad/s for 1 s so that the rest ends
    t2 = t[-1] + np.arange(1, 101) * 10_000_000
    g2 = np.tile([0.0, 0.0, 0.5], (100, 1)) + 1e-3 * np.random.default_rng(5).normal(size=(100, 3))
    a2 = np.tile(a[-1], (100, 1))
    cfg = StreamConfig(initial_attitude_source="level", initial_heading_deg=30.0)  # 90° − 60°
    s = AttitudeStream(config=cfg)
    phases = []
    for k in range(500):
        tk, gk, ak = (t[k], g[k], a[k]) if k < 400 else (t2[k - 400], g2[k - 400], a2[k - 400])
        _, q = s.push(int(tk), gk, "imu", None, ak)
        phases.append((s.phase, q is not None))
    assert all(p == ALIGNING and not got for p, got in phases[:400])
    assert phases[-1] == (RUNNING, True)
    res = s.alignment
    err = (Rotation.from_quat(res.q_nb) * q_true.inv()).magnitude()
    assert err < 3 * res.level_error_expected  # noise only (no accel bias): well below 1σ
    assert math.isclose(math.degrees(res.heading), 30.0, abs_tol=1e-9)


def test_level_on_a_recording_that_never_rests_is_a_clear_error():
    rng = np.random.default_rng(0)
    t = np.arange(2000, dtype=np.int64) * 5_000_000
    g = np.cumsum(rng.normal(scale=0.05, size=(2000, 3)), axis=0)
    a = np.tile([0.0, 0.0, G], (2000, 1)) + rng.normal(scale=1.0, size=(2000, 3))
    with pytest.raises(ValueError, match="cannot align"):
        AttitudeStream(config=StreamConfig(initial_attitude_source="level")).run(t, g, "imu", None, a)
    with pytest.raises(ValueError, match="accelerometer"):
        AttitudeStream(config=StreamConfig(initial_attitude_source="level")).run(t, g, "imu")


def test_gyrocompass_refused_for_a_mems_bias_and_needs_a_stated_bias():
    with pytest.raises(ValueError, match="gyrocompass needs gyro_bias 'parameter'"):
        StreamConfig(initial_attitude_source="level", heading_source="gyrocompass", latitude_rad=0.8)
    mems = dict(initial_attitude_source="level", heading_source="gyrocompass", gyro_bias="parameter",
                gyro_bias_sigma_rad_s=math.radians(0.01))  # 36 °/h
    with pytest.raises(ValueError, match="gyrocompass refused"):
        StreamConfig(latitude_rad=0.8, **mems)
    with pytest.raises(ValueError, match="gyrocompass refused"):
        AttitudeStream(nav=NavFrame(latitude_rad=0.8), config=StreamConfig(**mems))
    # navigation grade (0.01 °/h at 45°: 0.05°) is accepted
    StreamConfig(latitude_rad=0.8, **{**mems, "gyro_bias_sigma_rad_s": math.radians(0.01 / 3600)})


@pytest.mark.parametrize(("bad", "name"), [
    ({"gyro_bias": "automatic"}, "gyro_bias"), ({"gyro_bias_rad_s": (0.0, math.nan, 0.0)},
                                                "gyro_bias_rad_s"),
    ({"gyro_bias_rad_s": "0,0,0"}, "gyro_bias_rad_s"), ({"initial_attitude": "truth"},
                                                         "initial_attitude"),
    ({"aiding": "compass"}, "aiding"), ({"gyro_noise_density": -1.0}, "gyro_noise_density"),
    ({"gyro_noise_density": math.inf}, "gyro_noise_density"), ({"min_rest_s": 0.0}, "min_rest_s"),
    ({"rest_gyro_std_max": math.nan}, "gyro_std_max"), ({"latitude_rad": 2.0}, "latitude_rad"),
    ({"initial_heading_deg": 1e300}, "initial_heading_deg"),
    ({"gyro_bias_sigma_rad_s": True}, "gyro_bias_sigma_rad_s"),
])
def test_bad_settings_name_the_field(bad, name):
    with pytest.raises(ValueError, match=name):
        StreamConfig(**bad)


def test_auto_does_nothing_on_noise_free_data():
    """An ideal gyro in a constant slow turn (0.05 rad/s, below the largest plausible bias) or at
    rest seeing the Earth rate has no bias to find: the default auto mode leaves it alone."""
    n = 3000
    t = (1 + np.arange(n, dtype=np.int64)) * 10_000_000
    g = np.tile([0.0, 0.0, 0.05], (n, 1))
    res = AttitudeStream("rotvec_cubic").run(t, g, "imu")
    assert res.bias.rests_used == 0
    angle = Rotation.from_quat(res.q[-1]).as_rotvec()[2]
    assert math.isclose(angle, 0.05 * (n - 1) * 0.01, rel_tol=1e-12)


# ---------------------------------------------------------------------- truth at an Imu stamp
def truth_series():
    tt = 1_000_000_000 + np.arange(50, dtype=np.int64) * 10_000_000
    q = Rotation.from_rotvec(np.outer(np.linspace(0, 1, 50), [0.3, -0.2, 0.9])
                             + [0.1, 0.0, 0.0]).as_quat()
    return tt, q


def test_truth_at_stamps_matches_scipy_slerp_and_refuses_extrapolation():
    tt, q = truth_series()
    oracle = Slerp(tt * 1e-9, Rotation.from_quat(q))
    stamps = np.array([tt[0], tt[3] + 2_500_000, tt[-2] + 9_999_999, tt[-1]])
    got, covered = truth_at_stamps(tt, q, stamps)
    assert covered.all()
    assert (Rotation.from_quat(got) * oracle(stamps * 1e-9).inv()).magnitude().max() < 1e-9
    assert not truth_at_stamps(tt, q, [tt[-1] + 1, tt[0] - 1])[1].any()  # no extrapolation
    gap = np.delete(np.arange(50), np.arange(10, 20))
    assert not truth_at_stamps(tt[gap], q[gap], [tt[15]])[1].any()  # nothing across a gap


def test_initial_attitude_from_truth_skips_imu_before_the_truth():
    tt, q = truth_series()
    imu = 900_000_000 + np.arange(300, dtype=np.int64) * 3_500_000  # starts 0.1 s earlier
    q0, first, skipped = initial_attitude_from_truth(imu, tt, q)
    assert first == skipped == int(np.argmax(imu >= tt[0]))
    oracle = Slerp(tt * 1e-9, Rotation.from_quat(q))([imu[first] * 1e-9])
    assert (Rotation.from_quat(q0) * oracle.inv()).magnitude()[0] < 1e-9
    q0, first, skipped = initial_attitude_from_truth(tt + 5, tt, q)
    assert (first, skipped) == (0, 0)
    with pytest.raises(ValueError, match="no Imu stamp"):
        initial_attitude_from_truth(imu[:5], tt, q)
    with pytest.raises(ValueError, match="not finite"):
        initial_attitude_from_truth(imu, tt, np.where(np.arange(50)[:, None] == 3, np.nan, q))


def test_run_counts_negative_absurd_values_like_push():
    """Large negative rates and specific forces are as bad as large positive ones (the
    whole-array checks look at both ends)."""
    n = 200
    t = 10**9 + np.arange(n, dtype=np.int64) * 5_000_000
    g = np.tile([0.1, -0.2, 0.3], (n, 1))
    a = np.tile([0.0, 0.0, 9.81], (n, 1))
    g[50] = [0.0, -2e4, 0.0]  # beyond the default max_rate_rad_s = 1e4
    g[60] = [-np.inf, 0.0, 0.0]
    a[70] = [0.0, 0.0, -2e6]  # beyond ACCEL_ABSURD = 1e6
    a[80] = [-np.inf, 0.0, 0.0]
    cfg = MODES["parameter"]
    res = AttitudeStream("rotvec_cubic", config=cfg).run(t, g, "imu", None, a)
    pushed = push_all(AttitudeStream("rotvec_cubic", config=cfg), t, g, a, [None] * n)
    assert res.index.tolist() == [k for k, _, _ in pushed]
    assert 50 not in res.index and 60 not in res.index
    assert res.counts["implausible_rate"] == 1 and res.counts["non_finite"] == 1
    assert res.counts[INVALID_ACCEL] == 2


def test_a_zero_specific_force_through_a_wide_gate_is_no_vertical():
    # ahrs_accel_norm_tol ≥ g lets |f| = 0 through the norm gate: a sample with no direction
    # to align to is skipped by the aiding, not divided by (push and run alike, finite)
    t, g, a, cov = hostile_rest_motion_rest()
    a = a.copy()
    a[1500:1510] = 0.0
    cfg = StreamConfig(aiding="tilt", ahrs_accel_norm_tol=20.0)
    res = AttitudeStream(config=cfg).run(t, g, "imu", cov, a)
    pushed = push_all(AttitudeStream(config=cfg), t, g, a, cov)
    assert np.max(np.abs(res.q - np.array([q for _, q, _ in pushed]))) <= 1e-12
    assert np.all(np.isfinite(res.q))
