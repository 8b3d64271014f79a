"""Rotation primitives and angle conversions against closed forms and scipy.

scipy.spatial.transform.Rotation is the independent oracle.  Mapping (worked out once):

* ``Rotation.from_quat(q)`` uses scalar-last quaternions and ``as_matrix()`` is the ACTIVE
  matrix, i.e. our ``C_nb = quat_as_matrix(q_nb)``; the seed's A is its transpose.
* A passive R_k(a) equals the active rotation by −a about axis k: ``R1(a) =
  Rotation.from_euler("x", -a).as_matrix() = Rotation.from_euler("x", a).as_matrix().T``.
* Classical Euler angles, ``A = R3(φ) R1(θ) R3(ψ)``: transposing gives the active product
  ``C_nb = Rz(ψ) Rx(θ) Rz(φ)``.  scipy's intrinsic upper-case sequence multiplies in the
  written order, ``from_euler("ZXZ", [ψ, θ, φ])``; its extrinsic lower-case one in reverse
  order, ``from_euler("zxz", [φ, θ, ψ])``.
* Krylov angles, ``A = R3(φ) R2(γ) R1(δ)``: ``C_nb = Rx(δ) Ry(γ) Rz(φ)`` =
  ``from_euler("XYZ", [δ, γ, φ])`` = ``from_euler("zyx", [φ, γ, δ])``.
"""

import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from gyro_attitude.core import rotation as rot

DEG = np.pi / 180.0


def scipy_angle(q1, q2):
    """Rotation angle between two attitudes, computed by scipy."""
    return (Rotation.from_quat(q1).inv() * Rotation.from_quat(q2)).magnitude()


def random_quats(n, seed):
    q = np.random.default_rng(seed).normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def edge_rotvecs():
    """Identity, 1e-12 rad, 90°, 180°, 179.999° about coordinate and skew axes."""
    axes = np.array(
        [[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0], [1, -2, 3], [-0.3, 0.1, -0.9]], float
    )
    axes /= np.linalg.norm(axes, axis=-1, keepdims=True)
    angles = np.array([0.0, 1e-12, 1e-8, 90 * DEG, 180 * DEG, 179.999 * DEG, 1e-4, 0.99e-4])
    return (angles[:, None, None] * axes[None, :, :]).reshape(-1, 3)


def quiet(fn, *args, **kw):
    """Call ignoring the gimbal-lock UserWarning (tested separately)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        return fn(*args, **kw)


# --------------------------------------------------------------------------- primitives
def test_rotvec_taylor_branch_keeps_full_relative_accuracy_at_1e_12():
    e = np.array([2.0, -3.0, 6.0]) / 7.0
    theta = 1e-12
    q = rot.quat_from_rotvec(theta * e)
    # sin(θ/2) = θ/2 and cos(θ/2) = 1 to within θ²/24 ≈ 4e-26: exact in double.
    np.testing.assert_allclose(q[:3], 0.5 * theta * e, rtol=1e-15, atol=0)
    assert q[3] == 1.0
    back = rot.quat_as_rotvec(np.concatenate((0.5 * theta * e, [1.0])))
    np.testing.assert_allclose(back, theta * e, rtol=1e-15, atol=0)
    assert rot.quat_as_rotvec([0.0, 0.0, 0.0, 1.0]).tolist() == [0.0, 0.0, 0.0]


@pytest.mark.parametrize("theta", [0.999e-4, 1.001e-4, 1e-6, 0.3, 3.0])
def test_rotvec_both_branches_match_closed_form(theta):
    # Away from θ = 0, sin(θ/2)/θ and θ/sin(θ/2) have no cancellation: the direct
    # quotients are accurate to a few ulp and serve as truth on both sides of the switch.
    e = np.array([0.48, -0.6, 0.64])
    q = rot.quat_from_rotvec(theta * e)
    np.testing.assert_allclose(q, np.r_[np.sin(theta / 2) * e, np.cos(theta / 2)], rtol=4e-16)
    np.testing.assert_allclose(rot.quat_as_rotvec(q), theta * e, rtol=1e-15)


def test_rotvec_against_scipy_random_and_wrapping():
    rng = np.random.default_rng(5)
    v = rng.normal(size=(500, 3)) * rng.uniform(0, 3.1, (500, 1))
    np.testing.assert_allclose(
        rot.quat_canonical(rot.quat_from_rotvec(v)),
        rot.quat_canonical(Rotation.from_rotvec(v).as_quat()),
        atol=2e-16,
    )
    q = random_quats(500, 6)
    np.testing.assert_allclose(rot.quat_as_rotvec(q), Rotation.from_quat(q).as_rotvec(), atol=2e-15)
    # More than π wraps: 3π/2 about z is −π/2 about z.
    np.testing.assert_allclose(rot.quat_as_rotvec(rot.quat_from_rotvec([0, 0, 1.5 * np.pi])),
                               [0, 0, -0.5 * np.pi], atol=1e-15)


def rodrigues_matrix(e, theta):
    """Closed form C = I + sinθ [e×] + (1 − cosθ) [e×]² (active, v_a = C v_b)."""
    k = np.array([[0, -e[2], e[1]], [e[2], 0, -e[0]], [-e[1], e[0], 0]])
    return np.eye(3) + np.sin(theta) * k + (1 - np.cos(theta)) * k @ k


@pytest.mark.parametrize("theta_deg", [180.0, 179.999, 179.0, 90.0, 1e-10])
def test_markley_matrix_to_quaternion_near_180(theta_deg):
    e = np.array([1.0, -2.0, 2.0]) / 3.0
    theta = theta_deg * DEG
    q = rot.quat_from_matrix(rodrigues_matrix(e, theta))
    expected = np.r_[np.sin(theta / 2) * e, np.cos(theta / 2)]
    # q and −q are the same rotation; compare the nearer sign, to ulp level.
    err = min(np.abs(q - expected).max(), np.abs(q + expected).max())
    assert err < 4e-16
    assert q[3] >= 0


def test_trace_only_formula_really_fails_at_179_999_deg():
    """Shows the edge case is a real one: w = √(1+tr)/2 then v = (C32−C23, …)/(4w) loses
    ~8 digits at 179.999°, where Markley's branch keeps ~1e-16 (previous test)."""
    e = np.array([1.0, -2.0, 2.0]) / 3.0
    theta = 179.999 * DEG
    c = rodrigues_matrix(e, theta)
    w = 0.5 * np.sqrt(1 + np.trace(c))
    v = np.array([c[2, 1] - c[1, 2], c[0, 2] - c[2, 0], c[1, 0] - c[0, 1]]) / (4 * w)
    assert np.abs(v - np.sin(theta / 2) * e).max() > 1e-12


def test_matrix_and_quaternion_against_scipy():
    q = random_quats(1000, 7)
    np.testing.assert_allclose(rot.quat_as_matrix(q), Rotation.from_quat(q).as_matrix(), atol=1e-15)
    m = Rotation.from_quat(q).as_matrix()
    assert np.all(scipy_angle(rot.quat_from_matrix(m), q) < 1e-15)
    v = np.random.default_rng(8).normal(size=(1000, 3))
    np.testing.assert_allclose(rot.quat_rotate(q, v), Rotation.from_quat(q).apply(v), atol=1e-14)


def test_slightly_non_orthogonal_matrix_gives_nearest_quaternion_within_atol():
    q = random_quats(50, 16)
    noise = 1e-8 * np.random.default_rng(17).normal(size=(50, 3, 3))
    got = rot.quat_from_matrix(rot.quat_as_matrix(q) + noise)
    assert np.all(np.linalg.norm(got, axis=-1) == pytest.approx(1.0, abs=1e-15))
    assert np.all(scipy_angle(got, q) < 1e-7)
    with pytest.raises(ValueError, match="not orthogonal"):
        rot.quat_from_matrix(rot.quat_as_matrix(q) + noise, atol=1e-10)


def test_batched_validation_flags_one_bad_matrix_in_a_batch():
    m = rot.quat_as_matrix(random_quats(10, 18))
    m[7] = -m[7]  # det −1, still orthogonal
    with pytest.raises(ValueError, match="reflection"):
        rot.quat_from_matrix(m)


def test_quat_multiply_and_rotate_broadcast_over_leading_axes():
    p, q = random_quats(3, 19), random_quats(5, 20)
    pq = rot.quat_multiply(p[:, None, :], q[None, :, :])
    assert pq.shape == (3, 5, 4)
    for i in range(3):
        for j in range(5):
            expected = (Rotation.from_quat(p[i]) * Rotation.from_quat(q[j])).as_quat()
            assert scipy_angle(pq[i, j], expected) < 1e-15
    v = np.random.default_rng(21).normal(size=(4, 1, 3))
    out = rot.quat_rotate(q[None, :, :], v)
    assert out.shape == (4, 5, 3)
    np.testing.assert_allclose(out[2, 3], Rotation.from_quat(q[3]).apply(v[2, 0]), atol=1e-15)


def test_quat_multiply_composition_matches_scipy_and_matrices():
    p, q = random_quats(200, 9), random_quats(200, 10)
    pq = rot.quat_multiply(p, q)
    assert np.all(scipy_angle(pq, (Rotation.from_quat(p) * Rotation.from_quat(q)).as_quat()) < 1e-15)
    np.testing.assert_allclose(
        rot.quat_as_matrix(pq), rot.quat_as_matrix(p) @ rot.quat_as_matrix(q), atol=1e-15
    )
    np.testing.assert_allclose(rot.quat_multiply(q, rot.quat_inverse(q)),
                               rot.quat_identity((200,)), atol=1e-15)


def test_angle_between_is_sign_immune_and_accurate_at_both_ends():
    e = np.array([0.0, 0.6, 0.8])
    base = random_quats(1, 11)[0]
    for theta in (1e-12, 1e-6, 1.0, np.pi - 1e-9, np.pi):
        q2 = rot.quat_multiply(base, rot.quat_from_rotvec(theta * e))
        assert rot.quat_angle_between(base, q2) == pytest.approx(theta, rel=1e-12)
        assert rot.quat_angle_between(base, -q2) == pytest.approx(theta, rel=1e-12)


def test_canonical_sign_and_seed_order():
    q = np.array([[0.1, 0.2, 0.3, -0.9], [0.0, -1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]])
    c = rot.quat_canonical(q)
    np.testing.assert_array_equal(c, [[-0.1, -0.2, -0.3, 0.9], [0.0, 1.0, 0.0, 0.0], q[2]])
    lam = rot.quat_as_seed([1.0, 2.0, 3.0, 4.0])
    np.testing.assert_array_equal(lam, [4.0, 1.0, 2.0, 3.0])
    np.testing.assert_array_equal(rot.quat_from_seed(lam), [1.0, 2.0, 3.0, 4.0])


# --------------------------------------------------------------------------- scipy oracle
def test_passive_rotations_are_transposed_active_scipy_rotations():
    a = np.linspace(-3, 3, 7)
    for k, axis in ((1, "x"), (2, "y"), (3, "z")):
        got = getattr(rot, f"passive_r{k}")(a)
        np.testing.assert_allclose(got, Rotation.from_euler(axis, -a[:, None]).as_matrix(), atol=1e-16)


def test_euler_zxz_against_scipy_intrinsic_and_extrinsic():
    rng = np.random.default_rng(12)
    ang = rng.uniform(-np.pi, np.pi, (1000, 3))
    ang[:, 1] = rng.uniform(0, np.pi, 1000)
    q = rot.quat_from_euler_zxz(ang)
    assert np.all(scipy_angle(q, Rotation.from_euler("ZXZ", ang).as_quat()) < 1e-15)
    assert np.all(scipy_angle(q, Rotation.from_euler("zxz", ang[:, ::-1]).as_quat()) < 1e-15)
    np.testing.assert_allclose(
        rot.seed_matrix_from_euler_zxz(ang),
        np.swapaxes(Rotation.from_euler("ZXZ", ang).as_matrix(), -1, -2),
        atol=1e-15,
    )
    # Away from lock scipy's angles are the same member of the family (ψ, φ in (−π, π]).
    ok = (ang[:, 1] > 1e-3) & (ang[:, 1] < np.pi - 1e-3)
    np.testing.assert_allclose(
        rot.quat_as_euler_zxz(q[ok]), Rotation.from_quat(q[ok]).as_euler("ZXZ"), atol=1e-11
    )


def test_krylov_against_scipy_intrinsic_and_extrinsic():
    rng = np.random.default_rng(13)
    ang = rng.uniform(-np.pi, np.pi, (1000, 3))
    ang[:, 1] = rng.uniform(-np.pi / 2, np.pi / 2, 1000)
    q = rot.quat_from_krylov(ang)
    assert np.all(scipy_angle(q, Rotation.from_euler("XYZ", ang).as_quat()) < 1e-15)
    assert np.all(scipy_angle(q, Rotation.from_euler("zyx", ang[:, ::-1]).as_quat()) < 1e-15)
    np.testing.assert_allclose(
        rot.seed_matrix_from_krylov(ang),
        np.swapaxes(Rotation.from_euler("XYZ", ang).as_matrix(), -1, -2),
        atol=1e-15,
    )
    ok = np.abs(ang[:, 1]) < np.pi / 2 - 1e-3
    np.testing.assert_allclose(
        rot.quat_as_krylov(q[ok]), Rotation.from_quat(q[ok]).as_euler("XYZ"), atol=1e-11
    )


def test_seed_matrix_from_quat_is_transpose_of_scipy_matrix():
    q = random_quats(100, 14)
    np.testing.assert_allclose(
        rot.seed_matrix_from_quat(q), np.swapaxes(Rotation.from_quat(q).as_matrix(), -1, -2),
        atol=1e-15,
    )
    assert np.all(scipy_angle(rot.quat_from_seed_matrix(rot.seed_matrix_from_quat(q)), q) < 1e-15)


# --------------------------------------------------------------------------- round trips
def test_angle_round_trips_on_random_sets():
    rng = np.random.default_rng(15)
    ang = rng.uniform(-np.pi, np.pi, (2000, 3))
    ang[:, 1] = rng.uniform(0.01, np.pi - 0.01, 2000)
    np.testing.assert_allclose(rot.quat_as_euler_zxz(rot.quat_from_euler_zxz(ang)), ang, atol=1e-13)
    np.testing.assert_allclose(
        rot.euler_zxz_from_seed_matrix(rot.seed_matrix_from_euler_zxz(ang)), ang, atol=1e-13
    )
    ang[:, 1] = rng.uniform(-np.pi / 2 + 0.01, np.pi / 2 - 0.01, 2000)
    np.testing.assert_allclose(rot.quat_as_krylov(rot.quat_from_krylov(ang)), ang, atol=1e-13)
    np.testing.assert_allclose(
        rot.krylov_from_seed_matrix(rot.seed_matrix_from_krylov(ang)), ang, atol=1e-13
    )


def test_round_trips_on_edge_sets_and_both_signs():
    """Identity, 1e-12 rad, 90°, 180°, 179.999°, Taylor-switch neighbours; q and −q.

    Every representation must give back the same attitude (scipy measures the angle).
    Gimbal-lock members are allowed their documented 2·lock_tol.
    """
    v = edge_rotvecs()
    q = Rotation.from_rotvec(v).as_quat()
    for qq in (q, -q):
        checks = {
            "rotvec": rot.quat_from_rotvec(rot.quat_as_rotvec(qq)),
            "matrix": rot.quat_from_matrix(rot.quat_as_matrix(qq)),
            "seed": rot.quat_from_seed_matrix(rot.seed_matrix_from_quat(qq)),
            "euler": rot.quat_from_euler_zxz(quiet(rot.quat_as_euler_zxz, qq)),
            "euler-A": rot.quat_from_euler_zxz(
                quiet(rot.euler_zxz_from_seed_matrix, rot.seed_matrix_from_quat(qq))
            ),
            "krylov": rot.quat_from_krylov(quiet(rot.quat_as_krylov, qq)),
            "krylov-A": rot.quat_from_krylov(
                quiet(rot.krylov_from_seed_matrix, rot.seed_matrix_from_quat(qq))
            ),
        }
        for name, back in checks.items():
            err = scipy_angle(back, q)
            assert np.all(err < 2 * rot.GIMBAL_LOCK_TOL + 1e-15), (name, err.max())
    # Rotation vector accuracy is relative, also for the tiniest ones (180° exactly is
    # left out: ±πe are both valid there, and that case was compared as rotations above).
    back = rot.quat_as_rotvec(rot.quat_from_rotvec(v))
    norm = np.linalg.norm(v, axis=-1)
    keep = norm < np.pi - 1e-6
    err = np.linalg.norm(back - v, axis=-1)[keep]
    assert np.all(err <= 1e-15 * norm[keep]), err.max()


@pytest.mark.parametrize("theta", [1e-3, 1e-6, 1e-8, np.pi - 1e-6, np.pi - 1e-8])
def test_euler_near_lock_outside_tolerance_is_exact_in_rotation(theta):
    """θ → 0 and θ → π without reaching the tolerance: no warning, rotation exact."""
    ang = np.array([[0.7, theta, -2.1], [-3.0, theta, 0.4]])
    q = rot.quat_from_euler_zxz(ang)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        back = rot.quat_as_euler_zxz(q)
        back_a = rot.euler_zxz_from_seed_matrix(rot.seed_matrix_from_euler_zxz(ang))
    assert np.all(scipy_angle(rot.quat_from_euler_zxz(back), q) < 1e-15)
    assert np.all(scipy_angle(rot.quat_from_euler_zxz(back_a), q) < 4e-16 * 4)
    # From exact quaternions the split ψ/φ is recovered too (not only the rotation).
    np.testing.assert_allclose(back, ang, atol=1e-9)


@pytest.mark.parametrize("gamma", [np.pi / 2 - 1e-6, -np.pi / 2 + 1e-8, 1e-12, 0.0])
def test_krylov_near_lock_outside_tolerance_is_exact_in_rotation(gamma):
    ang = np.array([[0.7, gamma, -2.1], [-3.0, gamma, 0.4]])
    q = rot.quat_from_krylov(ang)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        back = rot.quat_as_krylov(q)
    assert np.all(scipy_angle(rot.quat_from_krylov(back), q) < 1e-15)
    np.testing.assert_allclose(back, ang, atol=1e-9)


def test_near_lock_only_the_defined_combination_is_well_conditioned():
    """θ = 1e-6: a 1e-13 rad perturbation of the attitude may move ψ and φ each by up to
    ~1e-13/θ, but ψ + φ (the rotation about the nearly common z axis) only by ~1e-13,
    and the returned angles still reproduce the perturbed attitude to rounding."""
    ang = np.array([0.7, 1e-6, -2.1])
    q = rot.quat_from_euler_zxz(ang)
    dq = rot.quat_from_rotvec([1e-13, -2e-13, 0.5e-13])
    qp = rot.quat_multiply(q, dq)
    got = rot.quat_as_euler_zxz(qp)
    assert abs((got[0] + got[2]) - (ang[0] + ang[2])) < 5e-13
    assert 1e-10 < abs(got[0] - ang[0]) < 1e-6  # ψ alone is ill-conditioned, as documented
    assert scipy_angle(rot.quat_from_euler_zxz(got), qp) < 1e-15


def test_small_gamma_keeps_relative_accuracy():
    # sin γ = 2(wy + xz) is read directly, so γ = 1e-12 keeps ~full relative precision.
    back = rot.quat_as_krylov(rot.quat_from_krylov([0.0, 1e-12, 0.0]))
    assert back[1] == pytest.approx(1e-12, rel=1e-14)


# --------------------------------------------------------------------------- gimbal lock
@pytest.mark.parametrize(
    ("angles", "expected"),
    [
        ([0.3, 0.0, 0.5], [0.0, 0.0, 0.8]),  # θ = 0: only ψ + φ is defined
        ([0.3, np.pi, 0.5], [0.0, np.pi, 0.2]),  # θ = π: only ψ − φ = −0.2 is defined
        ([2.0, 1e-12, 2.5], [0.0, 1e-12, 4.5 - 2 * np.pi]),
    ],
)
def test_euler_gimbal_lock_member_and_warning(angles, expected):
    q = rot.quat_from_euler_zxz(angles)
    with pytest.warns(UserWarning, match="Gimbal lock detected in 1 of 1.*psi = 0"):
        got = rot.quat_as_euler_zxz(q)
    np.testing.assert_allclose(got, expected, atol=1e-14)
    # The chosen member is the same attitude (within 2·θ for θ inside the tolerance).
    distance_to_lock = min(angles[1], np.pi - angles[1])
    assert scipy_angle(rot.quat_from_euler_zxz(got), q) < 2 * distance_to_lock + 1e-15
    with pytest.warns(UserWarning, match="Gimbal lock"):
        got_a = rot.euler_zxz_from_seed_matrix(rot.seed_matrix_from_euler_zxz(angles))
    np.testing.assert_allclose(got_a, expected, atol=1e-14)


@pytest.mark.parametrize(
    ("angles", "expected"),
    [
        ([0.3, np.pi / 2, 0.5], [0.0, np.pi / 2, 0.8]),  # γ = +90°: δ + φ
        ([0.3, -np.pi / 2, 0.5], [0.0, -np.pi / 2, 0.2]),  # γ = −90°: δ − φ = −0.2
    ],
)
def test_krylov_gimbal_lock_member_and_warning(angles, expected):
    q = rot.quat_from_krylov(angles)
    with pytest.warns(UserWarning, match="Gimbal lock detected.*delta = 0"):
        got = rot.quat_as_krylov(q)
    np.testing.assert_allclose(got, expected, atol=1e-14)
    assert scipy_angle(rot.quat_from_krylov(got), q) < 1e-15
    with pytest.warns(UserWarning, match="Gimbal lock"):
        got_a = rot.krylov_from_seed_matrix(rot.seed_matrix_from_krylov(angles))
    np.testing.assert_allclose(got_a, expected, atol=1e-14)
    np.testing.assert_allclose(rot.seed_matrix_from_krylov(got),
                               rot.seed_matrix_from_krylov(angles), atol=1e-15)


def test_lock_warning_is_issued_once_per_call_and_counts():
    ang = np.zeros((5, 3))
    ang[:3, 1] = 1.0
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        rot.quat_as_euler_zxz(rot.quat_from_euler_zxz(ang))
    assert len(rec) == 1 and "2 of 5" in str(rec[0].message)
    assert rec[0].filename == __file__  # points at the caller, like scipy


def test_lock_tolerance_is_configurable():
    q = rot.quat_from_euler_zxz([0.3, 1e-6, 0.5])
    with pytest.warns(UserWarning):
        got = rot.quat_as_euler_zxz(q, lock_tol=1e-5)
    assert got[0] == 0.0
    assert scipy_angle(rot.quat_from_euler_zxz(got), q) < 2e-6
    with pytest.raises(ValueError, match="lock_tol"):
        rot.quat_as_euler_zxz(q, lock_tol=-1.0)


# --------------------------------------------------------------------------- bad input
@pytest.mark.parametrize(
    ("fn", "arg", "match"),
    [
        (rot.quat_from_euler_zxz, [0.1, 0.2], r"shape \(\.\.\., 3\)"),
        (rot.quat_from_krylov, [[0.1, np.nan, 0.2]], "non-finite"),
        (rot.seed_matrix_from_euler_zxz, [0.1, np.inf, 0.2], "non-finite"),
        (rot.quat_as_euler_zxz, [0.0, 0.0, 0.0, 0.0], "zero norm"),
        (rot.quat_as_krylov, [0.0, 0.0, 1.0], r"shape \(\.\.\., 4\)"),
        (rot.euler_zxz_from_seed_matrix, np.eye(3) * 1.01, "not orthogonal"),
        (rot.krylov_from_seed_matrix, np.diag([-1.0, 1.0, 1.0]), "reflection"),
        (rot.quat_from_seed_matrix, np.eye(2), r"shape \(\.\.\., 3, 3\)"),
        (rot.quat_from_rotvec, [1.0, np.nan, 0.0], "non-finite"),
        (rot.quat_from_matrix, np.ones((3, 3)), "not orthogonal"),
        (rot.quat_normalize, [[1.0, 0, 0, 0], [0, 0, 0, 0]], "zero norm"),
        (rot.quat_inverse, [0.0, 0.0, 0.0, 0.0], "zero norm"),
        (rot.passive_r1, [0.0, np.nan], "non-finite"),
    ],
)
def test_bad_input_raises_value_error_naming_the_problem(fn, arg, match):
    with pytest.raises(ValueError, match=match):
        fn(arg)


def test_bad_rate_input():
    with pytest.raises(ValueError, match="body rates.*shape"):
        rot.euler_zxz_rates_from_body_rates([0.1, 1.0, 0.2], [1.0, 2.0])
    with pytest.raises(ValueError, match="Krylov angle rates.*non-finite"):
        rot.body_rates_from_krylov_rates([0.1, 1.0, 0.2], [1.0, np.nan, 0.0])
    with pytest.raises(ValueError, match="tol"):
        rot.krylov_rates_from_body_rates([0.1, 1.0, 0.2], [1.0, 2.0, 3.0], tol=np.nan)


def test_batched_shapes_broadcast():
    ang = np.zeros((2, 5, 3))
    assert rot.quat_from_euler_zxz(ang).shape == (2, 5, 4)
    assert rot.seed_matrix_from_krylov(ang).shape == (2, 5, 3, 3)
    assert rot.body_rates_from_euler_zxz_rates(ang, [1.0, 2.0, 3.0]).shape == (2, 5, 3)
    assert rot.quat_as_krylov(np.tile([0.0, 0.0, 0.0, 1.0], (4, 1, 1))).shape == (4, 1, 3)
    assert rot.quat_as_euler_zxz(rot.quat_identity((0,))).shape == (0, 3)


# --------------------------------------------------------------------------- properties
unit_quats = st.lists(
    st.floats(-1.0, 1.0, allow_nan=False, allow_infinity=False), min_size=4, max_size=4
).filter(lambda v: np.linalg.norm(v) > 1e-3)
prop = settings(
    max_examples=60, deadline=None, database=None, suppress_health_check=[HealthCheck.too_slow]
)


@prop
@given(unit_quats)
def test_property_euler_and_krylov_reproduce_any_attitude(q):
    q = np.asarray(q) / np.linalg.norm(q)
    for to_angles, from_angles in (
        (rot.quat_as_euler_zxz, rot.quat_from_euler_zxz),
        (rot.quat_as_krylov, rot.quat_from_krylov),
    ):
        ang = quiet(to_angles, q)
        assert scipy_angle(from_angles(ang), q) < 2 * rot.GIMBAL_LOCK_TOL + 1e-15
        # −q gives the same angles (up to the 2π wrap at ±π).
        d = quiet(to_angles, -q) - ang
        assert np.all(np.abs(np.angle(np.exp(1j * d))) < 1e-12)


@prop
@given(
    st.tuples(st.floats(-3.1, 3.1), st.floats(0.05, 3.09), st.floats(-3.1, 3.1)),
    st.tuples(*[st.floats(-100.0, 100.0)] * 3),
)
def test_property_rate_maps_invert_each_other(angles, rates):
    angles, rates = np.array(angles), np.array(rates)
    scale = 1e-12 * (1 + np.abs(rates).max()) / np.sin(angles[1])
    w = rot.body_rates_from_euler_zxz_rates(angles, rates)
    np.testing.assert_allclose(rot.euler_zxz_rates_from_body_rates(angles, w), rates, atol=scale)
    w0 = rot.fixed_rates_from_euler_zxz_rates(angles, rates)
    np.testing.assert_allclose(rot.euler_zxz_rates_from_fixed_rates(angles, w0), rates, atol=scale)
    # |ω| is frame independent: body and fixed components describe one vector.
    assert np.linalg.norm(w) == pytest.approx(np.linalg.norm(w0), rel=1e-12, abs=1e-12)
    k = angles - np.array([0.0, np.pi / 2, 0.0])  # γ in (−π/2, π/2) away from ±90°
    scale_k = 1e-12 * (1 + np.abs(rates).max()) / np.cos(k[1])
    wk = rot.body_rates_from_krylov_rates(k, rates)
    np.testing.assert_allclose(rot.krylov_rates_from_body_rates(k, wk), rates, atol=scale_k)
