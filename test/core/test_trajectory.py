"""Trajectory motion: closed forms from sampled poses, Earth terms exact, built-in motions round-trip."""

import dataclasses
import math

import numpy as np
import pytest
from scipy.interpolate import make_smoothing_spline
from scipy.optimize import brentq
from scipy.spatial.transform import Rotation, RotationSpline

from gyro_attitude.core import earth
from gyro_attitude.core.figure_eight import FigureEight
from gyro_attitude.core.scene import SceneSimulator, SceneSpec
from gyro_attitude.core.trajectory import (
    PoseSeries,
    TrajectoryMotion,
    _increasing_root,
    _Reinsch,
    _StackedReinsch,
    check_poses,
    reinsch_smooth,
    smoothing_spline,
)

ORIGIN = (math.radians(48.1), math.radians(11.6), 520.0)
SPAN = 30.0
F8 = FigureEight()


def poses_of(t_s, p, q, t0_ns=10**9):
    t_ns = t0_ns + np.round(np.asarray(t_s) * 1e9).astype(np.int64)
    return PoseSeries(t_ns, np.asarray(p, float), np.asarray(q, float),
                      tuple(f"line {i + 1}" for i in range(len(t_ns))), "test.tum")


def mocap(noise=False, seed=3, rate=120.0):
    t = np.arange(int(SPAN * rate) + 1) / rate
    p, q = F8.poses(t)
    if noise:  # 1 mm and 0.1° per axis, as a motion-capture system
        rng = np.random.default_rng(seed)
        p = p + 1e-3 * rng.standard_normal(p.shape)
        q = (Rotation.from_quat(q) * Rotation.from_rotvec(
            math.radians(0.1) * rng.standard_normal((t.size, 3)))).as_quat()
    return poses_of(t, p, q)


def middle_rms(motion, err_of):
    t = np.arange(int(SPAN * 400) + 1) / 400.0  # a 400 Hz IMU
    mid = (t > 2.0) & (t < SPAN - 2.0)
    s = motion.imu(t, earth_rotation=False, gravity=False)
    gyro = np.sqrt(np.mean(np.sum((s.omega_ib_b - F8.body_rate(t))[mid] ** 2, axis=1)))
    force = np.sqrt(np.mean(np.sum((s.specific_force_b - F8.kinematic_force(t))[mid] ** 2,
                                   axis=1)))
    return gyro, force


def test_exact_poses_at_120_hz_reproduce_the_closed_form_body_rate_and_force():
    gyro, force = middle_rms(TrajectoryMotion(mocap(), ORIGIN), None)
    assert gyro < 1e-3 and force < 0.02  # the targets (measured: 6e-6, 5e-4)


@pytest.mark.parametrize("seed", [3, 4])
def test_noisy_poses_with_their_sigmas_given_stay_within_the_targets(seed):
    poses = mocap(noise=True, seed=seed)
    gyro, force = middle_rms(TrajectoryMotion(poses, ORIGIN, 1e-3, math.radians(0.1)), None)
    assert gyro < 0.03 and force < 0.3  # measured 0.021 rad/s, 0.15 m/s² (seed 3)
    # the same poses interpolated amplify the noise: the sigmas are what makes it work
    gyro0, force0 = middle_rms(TrajectoryMotion(poses, ORIGIN), None)
    assert gyro0 > 10 * gyro and force0 > 100 * force


def test_reinsch_smoothing_equals_scipy_make_smoothing_spline_at_the_same_lambda():
    rng = np.random.default_rng(0)
    t = np.cumsum(rng.uniform(0.005, 0.012, 400))  # uneven stamps
    y = np.sin(3 * t) + 0.01 * rng.standard_normal(t.size)
    for lam in (1e-9, 1e-6, 1e-3):
        ours = reinsch_smooth(t, y, lam)[:, 0]
        theirs = make_smoothing_spline(t, y, lam=lam)(t)
        assert np.max(np.abs(ours - theirs)) < 1e-9


def test_smoothing_spline_residual_is_the_expected_noise():
    rng = np.random.default_rng(1)
    t = np.arange(2000) / 120.0
    y = np.stack((np.sin(t), np.cos(0.5 * t)), axis=1) + 2e-3 * rng.standard_normal((2000, 2))
    target = 2000 * 2 * (2e-3) ** 2
    fit = smoothing_spline(t, y, target)
    assert np.sum((fit(t) - y) ** 2) == pytest.approx(target, rel=1e-3)


def test_long_series_smoothing_parameter_found_on_windows_keeps_the_residual():
    """Past 8 windows of 1000 poses λ is searched on those windows only; the whole series'
    residual still matches the expected noise (a planted search on one window fails)."""
    rng = np.random.default_rng(2)
    t = np.arange(30_000) / 120.0
    y = np.stack((np.sin(0.7 * t) * (1 + 0.5 * np.sin(0.01 * t)), np.cos(0.3 * t)), axis=1)
    y = y + 1e-3 * rng.standard_normal(y.shape)
    target = 30_000 * 2 * 1e-6
    fit = smoothing_spline(t, y, target)
    assert np.sum((fit(t) - y) ** 2) == pytest.approx(target, rel=0.1)  # measured 1.00-1.06


def test_window_residual_equals_scipy_smoothing_splines_fitted_window_by_window():
    """The stacked windows' residual (one banded solve, strided middles) is the sum over
    the windows of scipy's smoothing spline fitted to each window alone."""
    rng = np.random.default_rng(4)
    t = np.cumsum(rng.uniform(0.006, 0.011, 3000))  # uneven stamps
    y = np.stack((np.sin(3 * t), np.cos(0.5 * t))) + 0.01 * rng.standard_normal((2, t.size))
    starts, size, edge, lam = [0, 700, 1400, 2700], 300, 30, 1e-6
    expected = 0.0
    for a in starts:
        tw = t[a:a + size]
        for row in y[:, a:a + size]:
            r = row - make_smoothing_spline(tw, row, lam=lam)(tw)
            expected += np.sum(r[edge:size - edge] ** 2)
    rss = _StackedReinsch(_Reinsch(t, y), starts, size, edge).rss(lam)
    assert rss == pytest.approx(expected, rel=1e-7)


def _window_log_excess():
    """log(residual / target) of the windows' smoothing problem spline_coefficients solves
    for a long noisy series, and the search range it uses."""
    rng = np.random.default_rng(5)
    t = np.arange(12_000) / 120.0
    y = np.stack((np.sin(0.7 * t), np.cos(0.3 * t), np.sin(2.0 * t)))
    y = y + 1e-3 * rng.standard_normal(y.shape)
    windows = _StackedReinsch(_Reinsch(t, y), np.linspace(0, 11_000, 8).astype(int), 1000, 100)
    target = 8 * 800 * 3 * 1e-6
    log_h3 = 3 * math.log(1 / 120.0)
    return (lambda x: math.log(windows.rss(math.exp(x)) / target),
            log_h3, log_h3 + math.log(1e-8), log_h3 + math.log(1e12))


def test_smoothing_parameter_search_finds_the_root_brentq_finds_in_a_few_solves():
    f, start, lo, hi = _window_log_excess()
    exact = brentq(f, lo, hi, xtol=1e-12)
    calls = []

    def counted(x):
        calls.append(x)
        return f(x)

    root, slope = _increasing_root(counted, start, lo, hi, 1e-4)
    assert abs(root - exact) < 1e-4 and len(calls) <= 12
    calls.clear()  # restarted near the root with the slope, as the long windows' search is
    root, _ = _increasing_root(counted, exact + 0.1, lo, hi, 1e-4, slope=slope)
    assert abs(root - exact) < 1e-4 and len(calls) <= 5


@pytest.mark.parametrize("f, lo, hi", [
    (lambda x: math.expm1(3 * x) - 5.0, -20.0, 20.0),      # flat, then steep
    (lambda x: math.atan(50 * (x - 2.0)), -30.0, 30.0),    # steep, between two plateaus
    (lambda x: x ** 3 + 1e-3 * x - 0.5, -10.0, 10.0),      # an inflection at the root
])
def test_increasing_root_agrees_with_brentq_on_curved_functions(f, lo, hi):
    root, _ = _increasing_root(f, 0.0, lo, hi, 1e-6)
    assert abs(root - brentq(f, lo, hi, xtol=1e-14)) < 1e-6


def test_increasing_root_without_a_sign_change_ends_at_the_nearer_end():
    assert _increasing_root(lambda x: x - 100.0, 0.0, -5.0, 5.0, 1e-4)[0] == 5.0
    assert _increasing_root(lambda x: x + 100.0, 0.0, -5.0, 5.0, 1e-4)[0] == -5.0


def test_interpolated_attitude_rate_agrees_with_scipy_rotation_spline():
    """Uneven stamps, exact poses: the projected quaternion spline and scipy's RotationSpline
    (a different interpolant on SO(3)) agree to their interpolation error."""
    rng = np.random.default_rng(5)
    t = np.concatenate(([0.0], np.cumsum(rng.uniform(0.006, 0.011, 1500))))
    p, q = F8.poses(t)
    motion = TrajectoryMotion(poses_of(t, p, q), ORIGIN)
    ti = np.linspace(2.0, t[-1] - 2.0, 3000)
    ours = motion.tangent(ti).omega_tb_b
    oracle = RotationSpline(t, Rotation.from_quat(q))(ti, 1)
    assert np.max(np.linalg.norm(ours - oracle, axis=1)) < 1e-3
    assert np.max(np.linalg.norm(ours - F8.body_rate(ti), axis=1)) < 1e-3


def test_earth_rotation_adds_exactly_the_earth_rate_and_the_coriolis_term():
    scene = {"description": "walk", "seed": 1, "rate_hz": 400.0,
             "earth": {"latitude_deg": 48.1, "longitude_deg": 11.6, "height_m": 520.0},
             "motion": {"type": "stationary"}, "accelerometer": {}}
    motion = TrajectoryMotion(mocap(), ORIGIN)
    runs = {}
    for rotation in (True, False):
        d = {**scene, "earth": {**scene["earth"], "rotation": rotation}}
        spec = dataclasses.replace(SceneSpec.from_dict(d), motion=motion, motion_type="trajectory")
        runs[rotation] = SceneSimulator(spec, 400.0).next_block(8000)
    on, off = runs[True], runs[False]
    t = (on.t_ns - on.t_ns[0]) / 1e9
    fit = motion.tangent(t)
    lat = ORIGIN[0]
    w_ie = earth.OMEGA_IE * np.array([0.0, math.cos(lat), math.sin(lat)])  # in the tangent frame
    r_bt = Rotation.from_quat(fit.q_tb).inv()
    # to the rounding of the sum (|ω| ≈ 1.6 rad/s: one ulp is 2.2e-16)
    assert np.max(np.abs((on.omega_ib_b - off.omega_ib_b) - r_bt.apply(w_ie))) < 1e-15
    coriolis = r_bt.apply(2.0 * np.cross(w_ie, fit.v))
    assert np.max(np.abs((on.specific_force_b - off.specific_force_b) - coriolis)) < 1e-14
    assert np.max(np.abs(coriolis)) > 1e-4  # the term is there at all (walking speed)


def test_gravity_follows_the_local_vertical_far_from_the_origin():
    """10 km north of the origin the plumb line tilts by 10 km / R ≈ 1.6e-3 rad against the
    tangent frame's up: a level-in-t body at rest there feels gravity tilted by that much."""
    t = np.arange(0, 2.0, 0.01)
    n = t.size
    p = np.tile([0.0, 10_000.0, 0.0], (n, 1))
    q = np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))
    motion = TrajectoryMotion(poses_of(t, p, q), ORIGIN)
    s = motion.imu(t[5:-5], earth_rotation=False)
    f = s.specific_force_b
    tilt = math.atan2(f[0, 1], f[0, 2])  # the local up there leans north of the origin's up
    r_m, _ = earth.radii_of_curvature(ORIGIN[0])
    assert tilt == pytest.approx(10_000.0 / (r_m + ORIGIN[2]), rel=2e-3)
    assert np.linalg.norm(f[0]) == pytest.approx(
        -earth.gravity_enu(s.llh[0, 0], s.llh[0, 2])[2], abs=1e-9)


@pytest.mark.parametrize("motion", [
    {"type": "ship", "roll": {"amplitude_deg": 6.0, "period_s": 8.0},
     "pitch": {"amplitude_deg": 2.0, "period_s": 6.0}, "heave": {"amplitude_m": 1.0, "period_s": 9.0}},
    # 12 km of track in 2 minutes: the local-level frame turns against the tangent frame
    {"type": "coordinated_turn", "speed_mps": 100.0, "turn_rate_deg_s": 3.0},
])
def test_a_built_in_motion_exported_as_poses_reproduces_its_imu(motion):
    d = {"description": "export", "seed": 1, "rate_hz": 400.0,
         "earth": {"latitude_deg": 45.0, "longitude_deg": 7.0, "height_m": 300.0},
         "motion": motion, "accelerometer": {}}
    spec = SceneSpec.from_dict(d)
    built_in = SceneSimulator(spec, 400.0).next_block(400 * 120 + 1)
    # poses at 120 Hz from the built-in truth, into the tangent frame at the start
    sub = SceneSimulator(spec, 120.0).next_block(120 * 120 + 1)
    llh0 = np.array([spec.earth.latitude_rad, spec.earth.longitude_rad, spec.earth.height_m])
    c_et = earth.enu_to_ecef_matrix(llh0[0], llh0[1])
    p_t = (earth.ecef_from_llh(sub.position_llh) - earth.ecef_from_llh(llh0)) @ c_et
    c_tn = c_et.T @ earth.enu_to_ecef_matrix(sub.position_llh[:, 0], sub.position_llh[:, 1])
    q_tb = (Rotation.from_matrix(c_tn) * Rotation.from_quat(sub.truth_q_nb)).as_quat()
    poses = poses_of((sub.t_ns - sub.t_ns[0]) / 1e9, p_t, q_tb)
    traj = dataclasses.replace(spec, motion=TrajectoryMotion(poses, llh0),
                               motion_type="trajectory")
    again = SceneSimulator(traj, 400.0).next_block(400 * 120 + 1)
    mid = slice(400 * 5, 400 * 115)
    gyro = np.sqrt(np.mean(np.sum((again.omega_ib_b - built_in.omega_ib_b)[mid] ** 2, axis=1)))
    force = np.sqrt(np.mean(np.sum((again.specific_force_b - built_in.specific_force_b)[mid] ** 2,
                                   axis=1)))
    assert gyro < 1e-5 and force < 1e-3
    # truth attitude in the local-level frame comes back too
    dq = Rotation.from_quat(again.truth_q_nb[mid]).inv() * Rotation.from_quat(built_in.truth_q_nb[mid])
    assert np.max(dq.magnitude()) < 1e-6


@pytest.mark.parametrize("edit, message", [
    (lambda t, p, q: (t[[0, 2, 1, 3]], p, q), r"line 3: timestamp .* goes back"),
    (lambda t, p, q: (t[[0, 1, 1, 3]], p, q), r"line 3: timestamp .* repeats"),
    (lambda t, p, q: (t, p, q * np.array([[1.0], [1.0], [1.1], [1.0]])), r"line 3: quaternion .* not a unit"),
    (lambda t, p, q: (t, p, np.where(np.arange(4)[:, None] == 1, np.nan, q)), r"line 2: quaternion"),
    (lambda t, p, q: (t, np.where(np.arange(4)[:, None] == 3, np.inf, p), q),
     r"line 4: position is not finite"),
    (lambda t, p, q: (t[:1], p[:1], q[:1]), r"1 pose; a trajectory needs at least 2"),
    (lambda t, p, q: (t + np.array([0, 0, 180, 180]) * 10**9, p, q),
     r"line 3: gap of 180.01 s .* longer than max_gap_s = 1 s"),
])
def test_bad_poses_are_refused_naming_the_line(edit, message):
    t = 10**9 + np.arange(4, dtype=np.int64) * 10**7
    p = np.zeros((4, 3))
    q = np.tile([0.0, 0.0, 0.0, 1.0], (4, 1))
    t2, p2, q2 = edit(t, p, q)
    poses = PoseSeries(t2, p2, q2, tuple(f"line {i + 1}" for i in range(len(t2))), "x.tum")
    with pytest.raises(ValueError, match=message):
        check_poses(poses)


def test_free_gyro_rides_a_trajectory_to_its_last_pose():
    """The full free-gyro model differentiates the base rate around each step: at the last
    sample that reaches past the poses (by 1e-5 s), which must not refuse the run."""
    t = np.arange(121) / 120.0
    p, q = F8.poses(t)
    d = {"description": "free gyro walk", "seed": 1, "rate_hz": 100.0,
         "earth": {"latitude_deg": 45.0}, "motion": {"type": "stationary"},
         "free_gyro": {"spin_inertia": 1e-4, "transverse_inertia": 6e-5, "spin_rate": 500.0,
                       "model": "full", "integrator": "rk4",
                       "inner_gimbal_inertia": [1e-5, 1e-5, 1e-5],
                       "outer_gimbal_inertia": [1e-5, 1e-5, 1e-5]}}
    spec = dataclasses.replace(SceneSpec.from_dict(d), motion=TrajectoryMotion(poses_of(t, p, q), ORIGIN),
                               motion_type="trajectory")
    b = SceneSimulator(spec, 100.0).next_block(101)
    assert b.gimbal is not None and np.all(np.isfinite(b.gimbal.positions))


def test_times_outside_the_poses_are_refused():
    motion = TrajectoryMotion(mocap(), ORIGIN)
    with pytest.raises(ValueError, match="outside the 30 s the poses cover"):
        motion.tangent(np.array([0.0, 30.5]))


def _line_poses(p, origin_rate=100.0):
    p = np.asarray(p, float)
    t = np.arange(p.shape[0]) / origin_rate
    return poses_of(t, p, np.tile([0.0, 0.0, 0.0, 1.0], (p.shape[0], 1)))


@pytest.mark.parametrize("height, message", [
    (2e6, r"line 1: position .* height of 2e\+06 m, outside the scene's -12000 … 1e\+06 m"),
    (-3e4, r"line 1: position .* height of -30000 m, outside"),
    (1e300, r"line 1: position .* height of 1e\+300 m, outside"),  # past squares' range
])
@pytest.mark.filterwarnings("error")  # no overflow warning: one line of error
def test_a_position_outside_the_scene_heights_is_refused_naming_the_line(height, message):
    """2000 km up, the normal-gravity model is far outside what it describes (its free-air
    series gave g ≈ 7e5 m/s² at 1e9 m); 30 km below the origin is under any ground."""
    p = np.zeros((200, 3))
    p[:, 0] = np.arange(200) * 0.01
    p[:, 2] = height
    with pytest.raises(ValueError, match=message):
        TrajectoryMotion(_line_poses(p), (ORIGIN[0], ORIGIN[1], 0.0))


@pytest.mark.parametrize("jump, moved", [(5e4, r"50000"), (1e300, r"1e\+300")])
def test_a_pose_that_jumps_faster_than_any_carrier_is_refused_naming_the_line(jump, moved):
    """A motion-capture glitch (a marker swap: 50 km in one frame) is not a motion; 1e300 m
    once overflowed the fit into NaN specific force."""
    p = np.zeros((200, 3))
    p[150, 1] = jump
    with pytest.raises(ValueError, match=rf"line 151: moved {moved} m in 0\.01 s .* faster "
                                         r"than 12000 m/s"):
        TrajectoryMotion(_line_poses(p), ORIGIN)


def test_a_trajectory_over_a_pole_is_refused_as_the_built_in_motions_are():
    """The local-level ENU frame of the truth has no East or North at a pole."""
    p = np.zeros((300, 3))
    p[:, 1] = np.arange(300) * 10.0  # 1 km/s north from 1.1 km short of the pole
    with pytest.raises(ValueError, match=r"line \d+: .* reaches the North pole"):
        TrajectoryMotion(_line_poses(p), (math.radians(89.99), 0.0, 0.0))


def test_live_poses_that_a_file_would_refuse_are_rejected_one_by_one():
    """gyro_sim's motion_topic: a glitch or an absurd height is counted and skipped, not
    fitted (the refit would otherwise raise inside the node's timer)."""
    from gyro_attitude.core.trajectory import LiveTrajectory

    live = LiveTrajectory(ORIGIN, 10**9)
    q = [0.0, 0.0, 0.0, 1.0]
    for k in range(10):
        assert live.add(10**9 + k * 10**7, [0.01 * k, 0.0, 0.0], q) is None
    assert "faster than 12000 m/s" in live.add(10**9 + 10 * 10**7, [5e4, 0.0, 0.0], q)
    assert "outside the scene's" in LiveTrajectory(ORIGIN, 10**9).add(10**9, [0.0, 0.0, 2e6], q)
    assert live.add(10**9 + 10 * 10**7, [0.1, 0.0, 0.0], q) is None
    s = live.imu(np.linspace(0.0, 0.1, 11))
    assert np.all(np.isfinite(s.specific_force_b))


def _turning_poses(n=120, rate=100.0, flip_every_other=False):
    """A 0.5 rad/s turn about z sampled at ``rate``; with ``flip_every_other`` every second
    quaternion is written as −q (the same rotation)."""
    t = np.arange(n) / rate
    q = np.stack((np.zeros(n), np.zeros(n), np.sin(0.25 * t), np.cos(0.25 * t)), axis=1)
    if flip_every_other:
        q[1::2] *= -1.0
    return t, np.zeros((n, 3)), q


def test_q_and_minus_q_alternating_give_the_rates_of_a_consistent_sign():
    t, p, q = _turning_poses()
    _, _, q_alt = _turning_poses(flip_every_other=True)
    ts = np.linspace(0.05, t[-1] - 0.05, 200)
    w = TrajectoryMotion(poses_of(t, p, q), ORIGIN).tangent(ts).omega_tb_b
    w_alt = TrajectoryMotion(poses_of(t, p, q_alt), ORIGIN).tangent(ts).omega_tb_b
    np.testing.assert_allclose(w, [[0.0, 0.0, 0.5]] * len(ts), atol=1e-6)  # closed form
    np.testing.assert_array_equal(w_alt, w)


def test_a_pose_repeated_a_nanosecond_later_with_another_attitude_is_refused():
    """0.1° in 1 ns would be a 1.7e6 rad/s gyro, beyond any scene's rotation."""
    from gyro_attitude.core.trajectory import LiveTrajectory

    t, p, q = _turning_poses()
    t_ns = 10**9 + np.round(t * 1e9).astype(np.int64)
    k = 60
    d = math.radians(0.1) / 2  # about x, applied on the right
    qk = q[k]
    q_re = [qk[3] * d + qk[0], qk[1] + qk[2] * d, qk[2] - qk[1] * d, qk[3] - qk[0] * d]
    poses = PoseSeries(np.insert(t_ns, k + 1, t_ns[k] + 1), np.insert(p, k + 1, p[k], axis=0),
                       np.insert(q, k + 1, q_re, axis=0),
                       tuple(f"line {i + 1}" for i in range(len(t) + 1)), "test.tum")
    with pytest.raises(ValueError, match=r"line 62: turned 0\.1\d*° in 1e-09 s .* faster than "
                                         r"62831\.9 rad/s"):
        check_poses(poses)
    live = LiveTrajectory(ORIGIN, int(t_ns[0]))
    for j in range(k + 1):
        assert live.add(int(t_ns[j]), p[j], q[j]) is None
    assert "faster than 62831.9 rad/s" in live.add(int(t_ns[k]) + 1, p[k], q_re)
    assert live.add(int(t_ns[k]) + 1, p[k], -q[k]) is None  # −q: the same attitude


def test_a_trajectory_tens_of_km_from_the_origin_keeps_its_acceleration_digits():
    """Splines reproduce constants, so poses shifted by 35 km have the same smoothing fit
    shifted; fitted uncentred, differences of km-sized coordinates lost ~1e-6 m/s²."""
    poses = mocap(noise=True)
    shift = np.array([20e3, -35e3, 800.0])
    far = dataclasses.replace(poses, p=poses.p + shift)
    t = np.linspace(1.0, SPAN - 1.0, 2000)
    near_fit = TrajectoryMotion(poses, ORIGIN, 1e-3, math.radians(0.1)).tangent(t, need_accel=True)
    far_fit = TrajectoryMotion(far, ORIGIN, 1e-3, math.radians(0.1)).tangent(t, need_accel=True)
    assert np.max(np.abs(far_fit.a - near_fit.a)) < 2e-8
    assert np.max(np.abs(far_fit.p - shift - near_fit.p)) < 1e-10
