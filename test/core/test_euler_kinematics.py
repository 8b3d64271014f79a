"""Chapter 1 of the textbook (rigid body about a fixed point) against its own equations.

Truth here is the textbook, not the code: the passive elementary rotations are written
out below from docs/equations.md, the textbook's geometric definitions of the angles (node line,
measuring axes) are rebuilt with plain vector algebra, and angular velocities are taken
from finite differences of the matrix A(t) along smooth angle trajectories.

Angular velocity from Ȧ (derivation used by the kinematics tests): A = C_bn maps fixed
coordinates ξ into body coordinates x = A ξ.  A vector fixed in the fixed frame seen from
the body rotating at ω moves as ẋ = −ω_b × x, and ẋ = Ȧ ξ = Ȧ Aᵀ x, so

    [ω_b×] = −Ȧ Aᵀ   (body axes, p q r of 1-10 / 1-15),
    [ω_n×] = −Aᵀ Ȧ   (fixed axes, p0 q0 r0 of 1-11), since ω_n = Aᵀ ω_b.
"""

import numpy as np
import pytest

from gyro_attitude.core import euler_kinematics as ek
from gyro_attitude.core import rotation as rot


# --------------------------------------------------------------------------- independent truth
def r1(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, s], [0.0, -s, c]])


def r2(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, -s], [0.0, 1.0, 0.0], [s, 0.0, c]])


def r3(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])


def a_euler(psi, theta, phi):
    """§1-1: A = R3(φ) R1(θ) R3(ψ)."""
    return r3(phi) @ r1(theta) @ r3(psi)


def a_krylov(delta, gamma, phi):
    """§1-3: A = R3(φ) R2(γ) R1(δ)."""
    return r3(phi) @ r2(gamma) @ r1(delta)


def vee(m):
    """Vector of a (nearly) skew-symmetric matrix, from its antisymmetric part."""
    k = 0.5 * (m - m.T)
    return np.array([k[2, 1], k[0, 2], k[1, 0]])


class SmoothAngles:
    """angles(t) = c0 + c1 sin(Ω t + p) per component, with exact derivatives."""

    def __init__(self, rng, centre, amplitude):
        self.c0 = np.asarray(centre, float)
        self.c1 = np.asarray(amplitude, float) * rng.uniform(0.3, 1.0, 3)
        self.om = rng.uniform(0.5, 3.0, 3)
        self.p = rng.uniform(0.0, 2 * np.pi, 3)

    def __call__(self, t):
        return self.c0 + self.c1 * np.sin(self.om * t + self.p)

    def rate(self, t):
        return self.c1 * self.om * np.cos(self.om * t + self.p)


def a_dot(a_of_t, t, h=1e-3):
    """Five-point central difference of A(t): truncation ~h⁴, rounding ~1e-16/h."""
    return (-a_of_t(t + 2 * h) + 8 * a_of_t(t + h) - 8 * a_of_t(t - h) + a_of_t(t - 2 * h)) / (
        12 * h
    )


def _trajectories(seed, centre, amplitude, n=12):
    rng = np.random.default_rng(seed)
    return [SmoothAngles(rng, centre, amplitude) for _ in range(n)], rng.uniform(0, 5, n)


# --------------------------------------------------------------------------- §1-1 definitions
def test_passive_elementary_rotations_match_the_textbook_formulas():
    a = np.array([-2.0, 0.0, 0.4, 3.0])
    for k, ref in ((1, r1), (2, r2), (3, r3)):
        got = getattr(ek, f"passive_r{k}")(a)
        assert got.shape == (4, 3, 3)
        for i in range(4):
            np.testing.assert_allclose(got[i], ref(a[i]), rtol=0, atol=1e-16)


def test_dcm_a_equals_products_of_passive_rotations():
    rng = np.random.default_rng(1)
    ang = rng.uniform(-np.pi, np.pi, (50, 3))
    e = ek.dcm_a_from_euler_zxz(ang)
    k = ek.dcm_a_from_krylov(ang)
    for i in range(50):
        np.testing.assert_allclose(e[i], a_euler(*ang[i]), atol=4e-16)
        np.testing.assert_allclose(k[i], a_krylov(*ang[i]), atol=4e-16)


def test_euler_angles_follow_the_geometric_definition():
    """§1-1 in words: node line ON = Oxy ∩ Oξη at angle ψ from ξ (ccw about ζ); z is ζ
    turned by θ about ON; x is ON turned by φ about z.  Rows of A are the body axes in
    fixed coordinates (x = A ξ)."""
    rng = np.random.default_rng(2)
    ang = rng.uniform(-np.pi, np.pi, (40, 3))
    ang[:, 1] = rng.uniform(0.05, np.pi - 0.05, 40)
    a = ek.dcm_a_from_euler_zxz(ang)
    zeta = np.array([0.0, 0.0, 1.0])
    for (psi, theta, phi), ai in zip(ang, a, strict=True):
        node = np.array([np.cos(psi), np.sin(psi), 0.0])
        z_axis = np.cos(theta) * zeta + np.sin(theta) * np.cross(node, zeta)
        x_axis = np.cos(phi) * node + np.sin(phi) * np.cross(z_axis, node)
        np.testing.assert_allclose(ai[2], z_axis, atol=1e-15)
        np.testing.assert_allclose(ai[0], x_axis, atol=1e-15)
        # ON really is the intersection line: perpendicular to both ζ and z.
        assert abs(node @ ai[2]) < 1e-15


def test_krylov_angles_follow_the_geometric_definition():
    """§1-3: ON lies in the fixed plane Oηζ at δ from η (about ξ); z is the intermediate
    z' turned by γ about ON; y is ON turned by φ about z."""
    rng = np.random.default_rng(3)
    ang = rng.uniform(-np.pi, np.pi, (40, 3))
    ang[:, 1] = rng.uniform(-1.5, 1.5, 40)
    a = ek.dcm_a_from_krylov(ang)
    for (delta, gamma, phi), ai in zip(ang, a, strict=True):
        node = np.array([0.0, np.cos(delta), np.sin(delta)])
        z_prime = np.array([0.0, -np.sin(delta), np.cos(delta)])
        z_axis = np.cos(gamma) * z_prime + np.sin(gamma) * np.cross(node, z_prime)
        y_axis = np.cos(phi) * node + np.sin(phi) * np.cross(z_axis, node)
        np.testing.assert_allclose(ai[2], z_axis, atol=1e-15)
        np.testing.assert_allclose(ai[1], y_axis, atol=1e-15)


def test_orthogonality_relations_1_6():
    """The six relations (1-6), written out element by element."""
    rng = np.random.default_rng(4)
    ang = rng.uniform(-np.pi, np.pi, (200, 3))
    q = rng.normal(size=(200, 4))
    for a in (
        ek.dcm_a_from_euler_zxz(ang),
        ek.dcm_a_from_krylov(ang),
        ek.dcm_a_from_quat(q),
    ):
        a11, a12, a13 = a[:, 0, 0], a[:, 0, 1], a[:, 0, 2]
        a21, a22, a23 = a[:, 1, 0], a[:, 1, 1], a[:, 1, 2]
        a31, a32, a33 = a[:, 2, 0], a[:, 2, 1], a[:, 2, 2]
        for v in (a11**2 + a12**2 + a13**2, a21**2 + a22**2 + a23**2, a31**2 + a32**2 + a33**2):
            np.testing.assert_allclose(v, 1.0, atol=1e-15)
        for v in (
            a11 * a12 + a21 * a22 + a31 * a32,
            a11 * a13 + a21 * a23 + a31 * a33,
            a12 * a13 + a22 * a23 + a32 * a33,
        ):
            np.testing.assert_allclose(v, 0.0, atol=1e-15)
        np.testing.assert_allclose(np.linalg.det(a), 1.0, atol=1e-14)


# --------------------------------------------------------------------------- §1-2 (1-10) (1-11)
def test_euler_body_rates_1_10_against_finite_differences_of_A():
    trajs, times = _trajectories(10, [0.0, 1.2, 0.0], [3.0, 0.8, 3.0])
    for traj, t in zip(trajs, times, strict=True):
        a_t = a_euler(*traj(t))
        omega_b = vee(-a_dot(lambda s, tr=traj: a_euler(*tr(s)), t) @ a_t.T)
        got = ek.body_rates_from_euler_zxz_rates(traj(t), traj.rate(t))
        np.testing.assert_allclose(got, omega_b, rtol=0, atol=1e-9 * (1 + np.abs(omega_b).max()))
        got_m = ek.euler_zxz_body_rate_matrix(traj(t)) @ traj.rate(t)  # matrix form (1-10)'
        np.testing.assert_allclose(got_m, omega_b, rtol=0, atol=1e-9 * (1 + np.abs(omega_b).max()))
        # The inverse recovers the true angle rates (θ stays in [0.4, 2.0] here).
        back = ek.euler_zxz_rates_from_body_rates(traj(t), omega_b)
        np.testing.assert_allclose(back, traj.rate(t), rtol=0, atol=1e-8)


def test_euler_fixed_rates_1_11_against_finite_differences_of_A():
    trajs, times = _trajectories(11, [0.0, 1.9, 0.0], [3.0, 0.8, 3.0])
    for traj, t in zip(trajs, times, strict=True):
        a_t = a_euler(*traj(t))
        omega_n = vee(-a_t.T @ a_dot(lambda s, tr=traj: a_euler(*tr(s)), t))
        got = ek.fixed_rates_from_euler_zxz_rates(traj(t), traj.rate(t))
        np.testing.assert_allclose(got, omega_n, rtol=0, atol=1e-9 * (1 + np.abs(omega_n).max()))
        got_m = ek.euler_zxz_fixed_rate_matrix(traj(t)) @ traj.rate(t)  # (1-11)'
        np.testing.assert_allclose(got_m, omega_n, rtol=0, atol=1e-9 * (1 + np.abs(omega_n).max()))
        back = ek.euler_zxz_rates_from_fixed_rates(traj(t), omega_n)
        np.testing.assert_allclose(back, traj.rate(t), rtol=0, atol=1e-8)


def test_finite_difference_derivative_is_skew_as_required_by_1_6():
    """Differentiating AAᵀ = I gives ȦAᵀ = −(ȦAᵀ)ᵀ: checks the FD oracle itself."""
    traj = SmoothAngles(np.random.default_rng(12), [0.0, 1.0, 0.0], [2.0, 0.5, 2.0])
    a_t = a_euler(*traj(0.7))
    m = a_dot(lambda s: a_euler(*traj(s)), 0.7) @ a_t.T
    assert np.abs(m + m.T).max() < 1e-10
    assert np.abs(m).max() > 0.1


# --------------------------------------------------------------------------- §1-3 Krylov
def test_krylov_body_rates_1_15_against_finite_differences_of_A():
    trajs, times = _trajectories(20, [0.0, 0.0, 0.0], [3.0, 1.2, 3.0])
    for traj, t in zip(trajs, times, strict=True):
        a_t = a_krylov(*traj(t))
        omega_b = vee(-a_dot(lambda s, tr=traj: a_krylov(*tr(s)), t) @ a_t.T)
        got = ek.body_rates_from_krylov_rates(traj(t), traj.rate(t))
        np.testing.assert_allclose(got, omega_b, rtol=0, atol=1e-9 * (1 + np.abs(omega_b).max()))
        got_m = ek.krylov_body_rate_matrix(traj(t)) @ traj.rate(t)  # (1-15)'
        np.testing.assert_allclose(got_m, omega_b, rtol=0, atol=1e-9 * (1 + np.abs(omega_b).max()))
        back = ek.krylov_rates_from_body_rates(traj(t), omega_b)
        np.testing.assert_allclose(back, traj.rate(t), rtol=0, atol=1e-8)


def test_krylov_fixed_rates_against_finite_differences_of_A():
    trajs, times = _trajectories(21, [0.0, 0.3, 0.0], [3.0, 1.0, 3.0])
    for traj, t in zip(trajs, times, strict=True):
        a_t = a_krylov(*traj(t))
        omega_n = vee(-a_t.T @ a_dot(lambda s, tr=traj: a_krylov(*tr(s)), t))
        got = ek.fixed_rates_from_krylov_rates(traj(t), traj.rate(t))
        np.testing.assert_allclose(got, omega_n, rtol=0, atol=1e-9 * (1 + np.abs(omega_n).max()))
        back = ek.krylov_rates_from_fixed_rates(traj(t), omega_n)
        np.testing.assert_allclose(back, traj.rate(t), rtol=0, atol=1e-8)


def test_small_angle_table_1_13_literally():
    d, g, f = 0.011, -0.023, 0.037
    expected = np.array([[1.0, f, -g], [-f, 1.0, d], [g, -d, 1.0]])
    np.testing.assert_array_equal(ek.dcm_a_from_krylov_small_angle([d, g, f]), expected)


def test_small_angle_matrix_1_13_error_is_second_order():
    """|A_exact − A_(1-13)| / ε² stays constant as ε shrinks: error is O(ε²), not O(ε)."""
    direction = np.array([0.6, -0.8, 0.5])
    ratios = []
    for eps in (1e-2, 1e-3, 1e-4):
        ang = eps * direction
        err = np.abs(a_krylov(*ang) - ek.dcm_a_from_krylov_small_angle(ang)).max()
        ratios.append(err / eps**2)
    assert ratios[0] > 0.1  # a genuine second-order term (products like δγ, ½δ²)
    np.testing.assert_allclose(ratios, ratios[0], rtol=0.02)


def test_small_angle_rates_1_16_error_is_second_order():
    rng = np.random.default_rng(22)
    direction = np.array([0.7, 0.4, -0.9])
    rates = rng.normal(size=3)
    ratios = []
    for eps in (1e-2, 1e-3, 1e-4):
        ang = eps * direction
        # Truth from finite differences of the exact A along angles(t) = ang + t·rates.
        a_t = a_krylov(*ang)
        omega_b = vee(-a_dot(lambda s, a0=ang: a_krylov(*(a0 + s * rates)), 0.0, h=1e-4) @ a_t.T)
        approx = ek.body_rates_from_krylov_rates_small_angle(ang, rates)
        approx_m = ek.krylov_body_rate_matrix_small_angle(ang) @ rates
        np.testing.assert_allclose(approx_m, approx, atol=1e-15)
        ratios.append(np.abs(approx - omega_b).max() / eps**2)
    assert ratios[0] > 0.05
    np.testing.assert_allclose(ratios, ratios[0], rtol=0.05)


def test_infinitesimal_rotations_commute_to_second_order():
    """§1-3: the order of small rotations changes the result only at second order."""
    diffs = []
    for eps in (1e-2, 1e-3):
        b = ek.passive_r1(eps)
        c = ek.passive_r2(0.5 * eps)
        diffs.append(np.abs(ek.compose_dcm_a(c, b) - ek.compose_dcm_a(b, c)).max())
    assert diffs[1] / diffs[0] == pytest.approx(1e-2, rel=1e-3)


# --------------------------------------------------------------------------- §1-4 (1-24)
def test_composition_1_24_order_matters():
    """B = 90° about x, then C = 90° about the (new) body z: A = C B.

    Written out by hand: R1(90°) = [[1,0,0],[0,0,1],[0,−1,0]], R3(90°) = [[0,1,0],
    [−1,0,0],[0,0,1]].  Physically body x first stays on ξ, then turns about the body z
    (now along −η) by 90°, ending on ζ: row 0 of A is (0, 0, 1).
    """
    b = ek.passive_r1(np.pi / 2)
    c = ek.passive_r3(np.pi / 2)
    cb = ek.compose_dcm_a(c, b)
    bc = ek.compose_dcm_a(b, c)
    np.testing.assert_allclose(cb, [[0, 0, 1], [-1, 0, 0], [0, -1, 0]], atol=1e-16)
    np.testing.assert_allclose(bc, [[0, 1, 0], [0, 0, 1], [1, 0, 0]], atol=1e-16)
    # The same with quaternions q_nb: A = C B ⇔ q_A = q_B ⊗ q_C.
    q_b, q_c = ek.quat_from_dcm_a(b), ek.quat_from_dcm_a(c)
    q_cb = rot.quat_multiply(q_b, q_c)
    assert rot.quat_angle_between(q_cb, ek.quat_from_dcm_a(cb)) < 1e-15
    assert rot.quat_angle_between(rot.quat_multiply(q_c, q_b), ek.quat_from_dcm_a(cb)) > 1.0
    # Euler angles are exactly this kind of composition: R3(φ) R1(θ) R3(ψ).
    np.testing.assert_allclose(cb, ek.dcm_a_from_euler_zxz([0.0, np.pi / 2, np.pi / 2]),
                               atol=1e-16)


def test_compose_dcm_a_rejects_non_rotations():
    good = ek.passive_r1(0.3)
    with pytest.raises(ValueError, match="C is not orthogonal"):
        ek.compose_dcm_a(2.0 * good, good)
    with pytest.raises(ValueError, match="B is a reflection"):
        ek.compose_dcm_a(good, np.diag([1.0, 1.0, -1.0]))


# --------------------------------------------------------------------------- §1-5
def test_rodrigues_hamilton_parameters_of_a_rotation():
    """§1-5: λ0 = cos(χ/2), (λ1, λ2, λ3) = e sin(χ/2) for a rotation χ about e.

    A = R3(χ) turns the body by χ about ζ, so e = (0, 0, 1) in q_nb terms.
    """
    chi = 0.8
    lam = ek.quat_as_rodrigues_hamilton(ek.quat_from_dcm_a(r3(chi)))
    np.testing.assert_allclose(lam, [np.cos(chi / 2), 0.0, 0.0, np.sin(chi / 2)], atol=1e-16)


# --------------------------------------------------------------------------- singular points
@pytest.mark.parametrize("theta", [0.0, 1e-12, np.pi, np.pi - 1e-13])
def test_euler_rate_inverse_raises_at_nutation_lock(theta):
    ang = np.array([[0.2, 1.0, 0.3], [0.2, theta, 0.3]])
    for fn in (ek.euler_zxz_rates_from_body_rates, ek.euler_zxz_rates_from_fixed_rates):
        with pytest.raises(ek.GimbalLockError, match=r"sin\(theta\).*tol=1e-09") as info:
            fn(ang, [0.1, 0.2, 0.3])
        assert "1 of 2" in str(info.value)
        assert isinstance(info.value, ValueError)


@pytest.mark.parametrize("gamma", [np.pi / 2, -np.pi / 2, np.pi / 2 - 1e-12])
def test_krylov_rate_inverse_raises_at_gamma_90(gamma):
    for fn in (ek.krylov_rates_from_body_rates, ek.krylov_rates_from_fixed_rates):
        with pytest.raises(ek.GimbalLockError, match=r"cos\(gamma\).*tol="):
            fn([0.1, gamma, 0.2], [0.1, 0.2, 0.3])


def test_rate_matrix_determinants_vanish_exactly_at_the_singularities():
    """det (1-10)' = −sinθ and det (1-15)' = cosγ: the inverse exists exactly where the
    inverse functions accept the input."""
    rng = np.random.default_rng(23)
    ang = rng.uniform(-np.pi, np.pi, (100, 3))
    np.testing.assert_allclose(
        np.linalg.det(ek.euler_zxz_body_rate_matrix(ang)), -np.sin(ang[:, 1]), atol=1e-15
    )
    np.testing.assert_allclose(
        np.linalg.det(ek.krylov_body_rate_matrix(ang)), np.cos(ang[:, 1]), atol=1e-15
    )


def test_rate_inverse_near_but_outside_lock_is_finite_and_exact():
    """Just outside the tolerance the inverse is large but correct: (1-10) maps it back."""
    ang = np.array([0.4, 1e-6, -0.7])
    w = np.array([1e-3, -2e-3, 0.5])
    rates = ek.euler_zxz_rates_from_body_rates(ang, w)
    assert np.all(np.isfinite(rates)) and abs(rates[0]) > 1e2
    np.testing.assert_allclose(ek.body_rates_from_euler_zxz_rates(ang, rates), w, atol=1e-12)
    # A stricter tolerance turns the same call into an error.
    with pytest.raises(ek.GimbalLockError):
        ek.euler_zxz_rates_from_body_rates(ang, w, tol=1e-5)
