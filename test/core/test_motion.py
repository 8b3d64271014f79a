"""Carrier motions against closed forms, scipy Rotation and finite differences."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from gyro_attitude.core import motion as mo


def _fd_body_rate(m: mo.Motion, t: np.ndarray, h: float = 1e-5) -> np.ndarray:
    """Independent body rate: central difference of the attitude with scipy,
    ω_b(t) ≈ log(R(t−h)⁻¹ R(t+h)) / 2h (error O(h²))."""
    r_minus = Rotation.from_quat(m.evaluate(t - h).q_nb)
    r_plus = Rotation.from_quat(m.evaluate(t + h).q_nb)
    return (r_minus.inv() * r_plus).as_rotvec() / (2 * h)


def _fd_accel(m: mo.Motion, t: np.ndarray, h: float = 1e-4) -> np.ndarray:
    return (m.velocity(t + h) - m.velocity(t - h)) / (2 * h)


T = np.linspace(0.3, 25.0, 41)

MOTIONS = {
    "stationary": mo.Stationary((0.1, -0.2, 1.0)),
    "constant_velocity": mo.ConstantVelocity(50.0, (0.05, -0.1, 0.7)),
    "coordinated_turn": mo.CoordinatedTurn(120.0, np.radians(3.0), yaw0=0.4),
    "ship": mo.ShipMotion(
        10.0, 0.8,
        {"roll": (0.14, 9.0, 0.0), "pitch": (0.05, 6.5, 0.7), "yaw": (0.03, 14.0, 1.5),
         "heave": (1.0, 8.0, 0.2)},
    ),
    "coning": mo.ClassicalConing(np.radians(5.0), 2 * np.pi * 0.7, (0.0, 0.3, 0.2)),
    "spinning_projectile": mo.SpinningProjectile(2 * np.pi * 3.0, np.radians(4.0),
                                                 2 * np.pi * 0.5, 300.0, (0.0, -0.5, 0.0)),
    "profile": mo.SegmentProfile(
        [mo.ProfileSegment(2.0, (0.1, -0.2, 0.3), (1.0, 0.0, 0.5)),
         mo.ProfileSegment(5.0, (0.0, 0.0, -0.05), (0.0, -2.0, 0.0)),
         mo.ProfileSegment(30.0, (0.01, 0.02, 0.0), (0.0, 0.0, 0.0))],
        (0.1, 0.0, -1.0), (5.0, 1.0, 0.0)),
}


@pytest.mark.parametrize("name", sorted(MOTIONS))
def test_body_rate_is_the_derivative_of_the_attitude(name):
    m = MOTIONS[name]
    s = m.evaluate(T, need_accel=True)
    assert s.q_nb.shape == (T.size, 4)
    assert np.allclose(np.linalg.norm(s.q_nb, axis=1), 1.0, atol=1e-14)
    # Away from the profile's segment switches (the rate jumps there).
    ok = np.ones(T.size, bool)
    if name == "profile":
        ok = np.all(np.abs(T[:, None] - np.array([2.0, 7.0, 37.0])) > 1e-3, axis=1)
    scale = max(1.0, np.abs(s.omega_nb_b).max())
    assert np.abs(_fd_body_rate(m, T)[ok] - s.omega_nb_b[ok]).max() < 1e-6 * scale


@pytest.mark.parametrize("name", sorted(MOTIONS))
def test_acceleration_is_the_derivative_of_the_velocity(name):
    m = MOTIONS[name]
    s = m.evaluate(T, need_accel=True)
    assert np.array_equal(s.velocity_enu, m.velocity(T))
    ok = np.ones(T.size, bool)
    if name == "profile":
        ok = np.all(np.abs(T[:, None] - np.array([2.0, 7.0, 37.0])) > 1e-3, axis=1)
    assert np.abs(_fd_accel(m, T)[ok] - s.accel_enu[ok]).max() < 1e-6
    assert m.evaluate(T).accel_enu is None  # only computed on request


def test_ypr_matches_scipy_intrinsic_zyx():
    rng = np.random.default_rng(0)
    yaw, pitch, roll = rng.uniform(-3, 3, 50), rng.uniform(-1.5, 1.5, 50), rng.uniform(-3, 3, 50)
    q = mo.quat_from_ypr(yaw, pitch, roll)
    ref = Rotation.from_euler("ZYX", np.stack((yaw, pitch, roll), axis=1)).as_quat()
    assert np.allclose(q * np.sign(q[:, 3:]), ref * np.sign(ref[:, 3:]), atol=1e-15)


def test_ros_attitude_convention_yaw_north_pitch_down_roll_left_up():
    # yaw 90°: the nose (body x) points North; pitch +: nose down; roll +: left (y) side up.
    ex, ey = np.array([1.0, 0, 0]), np.array([0, 1.0, 0])
    assert np.allclose(Rotation.from_quat(mo.quat_from_ypr(np.pi / 2, 0, 0)).apply(ex),
                       [0, 1, 0], atol=1e-15)
    assert Rotation.from_quat(mo.quat_from_ypr(0, 0.3, 0)).apply(ex)[2] < 0
    assert Rotation.from_quat(mo.quat_from_ypr(0, 0, 0.3)).apply(ey)[2] > 0


def test_classical_coning_closed_form_of_design():
    alpha, om = np.radians(3.0), 2 * np.pi * 4.0
    m = mo.ClassicalConing(alpha, om)
    t = np.linspace(0, 1, 101)
    s = m.evaluate(t)
    # docs/equations.md, scalar-first [cos(α/2), 0, sin(α/2) cos Ωt, sin(α/2) sin Ωt]
    lam = np.stack((np.full_like(t, np.cos(alpha / 2)), 0 * t, np.sin(alpha / 2) * np.cos(om * t),
                    np.sin(alpha / 2) * np.sin(om * t)), axis=1)
    assert np.abs(s.q_nb - lam[:, [1, 2, 3, 0]]).max() < 1e-15
    w = np.stack((np.full_like(t, -2 * om * np.sin(alpha / 2) ** 2),
                  -om * np.sin(alpha) * np.sin(om * t), om * np.sin(alpha) * np.cos(om * t)), axis=1)
    assert np.abs(s.omega_nb_b - w).max() < 1e-13
    # The body x axis stays at α from the reference x axis (it sweeps the cone).
    x_n = Rotation.from_quat(s.q_nb).apply([1.0, 0, 0])
    assert np.allclose(np.arccos(np.clip(x_n[:, 0], -1, 1)), alpha, atol=1e-7)


def test_spinning_projectile_is_coning_followed_by_spin():
    alpha, om, p = np.radians(2.0), 2 * np.pi * 5.0, 2 * np.pi * 50.0
    base = (0.0, -0.4, 0.3)
    m = mo.SpinningProjectile(p, alpha, om, 100.0, base)
    t = np.linspace(0, 0.3, 301)
    s = m.evaluate(t)
    r_base = Rotation.from_euler("ZYX", [base[2], base[1], base[0]])
    r_cone = Rotation.from_rotvec(alpha * np.stack((0 * t, np.cos(om * t), np.sin(om * t)), 1))
    r_spin = Rotation.from_rotvec(np.outer(p * t, [1.0, 0, 0]))
    ref = (r_base * r_cone * r_spin).as_quat()
    err = (Rotation.from_quat(s.q_nb).inv() * Rotation.from_quat(ref)).magnitude()
    assert err.max() < 1e-12
    # Flies along the cone axis at the given speed.
    assert np.allclose(s.velocity_enu, r_base.apply([100.0, 0, 0]), atol=1e-12)
    # Spin-axis rate is p − 2Ω sin²(α/2); the transverse rate has magnitude Ω sin α.
    assert np.allclose(s.omega_nb_b[:, 0], p - 2 * om * np.sin(alpha / 2) ** 2, rtol=1e-14)
    assert np.allclose(np.hypot(s.omega_nb_b[:, 1], s.omega_nb_b[:, 2]), om * np.sin(alpha),
                       rtol=1e-13)


def test_coordinated_turn_bank_balances_flat_earth_specific_force():
    g = mo.STANDARD_GRAVITY
    for rate in (np.radians(3.0), -np.radians(5.0)):
        m = mo.CoordinatedTurn(150.0, rate, yaw0=1.0)
        t = np.linspace(0, 60, 31)
        s = m.evaluate(t, need_accel=True)
        f_b = Rotation.from_quat(s.q_nb).inv().apply(s.accel_enu + [0, 0, g])
        assert np.abs(f_b[:, 1]).max() < 1e-12  # no side force: the turn is coordinated
        assert np.allclose(np.linalg.norm(s.accel_enu, axis=1), 150.0 * abs(rate), rtol=1e-14)
        # Heading follows the turn rate; the body x axis is along the velocity.
        x_n = Rotation.from_quat(s.q_nb).apply([1.0, 0, 0])
        assert np.allclose(x_n * 150.0, s.velocity_enu, atol=1e-10)


def test_profile_segments_chain_exactly():
    w1, w2 = np.array([0.2, -0.1, 0.4]), np.array([0.0, 0.3, 0.0])
    a1 = np.array([1.0, 2.0, -0.5])
    m = mo.SegmentProfile([mo.ProfileSegment(2.0, tuple(w1), tuple(a1)),
                           mo.ProfileSegment(3.0, tuple(w2))], (0, 0, 0.5), (1.0, 0, 0))
    q0 = Rotation.from_euler("ZYX", [0.5, 0, 0])
    t = np.array([-1.0, 0.0, 1.0, 2.0, 3.5, 5.0, 9.0])
    s = m.evaluate(t, need_accel=True)
    r1 = q0 * Rotation.from_rotvec(w1 * 2.0)
    r2 = r1 * Rotation.from_rotvec(w2 * 3.0)
    ref = [q0, q0, q0 * Rotation.from_rotvec(w1), r1, r1 * Rotation.from_rotvec(w2 * 1.5), r2, r2]
    for k, r in enumerate(ref):
        assert (Rotation.from_quat(s.q_nb[k]).inv() * r).magnitude() < 1e-14
    assert np.allclose(s.velocity_enu[[0, 1, 2, 3, 6]],
                       [[1, 0, 0], [1, 0, 0], [2, 2, -0.5], [3, 4, -1], [3, 4, -1]], atol=1e-14)
    assert np.array_equal(s.omega_nb_b[[0, 6]], np.zeros((2, 3)))
    assert np.array_equal(s.omega_nb_b[4], w2)


def test_stationary_flags_and_bad_times():
    assert not mo.Stationary().moves and not mo.ClassicalConing(0.1, 1.0).moves
    assert mo.ConstantVelocity(1.0).moves and not mo.ConstantVelocity(0.0).moves
    with pytest.raises(ValueError, match="1-D"):
        mo.Stationary().evaluate(np.zeros((2, 2)))
    with pytest.raises(ValueError, match="non-finite"):
        mo.Stationary().evaluate([0.0, np.nan])
    with pytest.raises(ValueError, match="duration"):
        mo.SegmentProfile([mo.ProfileSegment(0.0)])
