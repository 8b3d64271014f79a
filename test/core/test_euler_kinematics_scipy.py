"""Chapter-1 kinematics (matrix A, Euler z-x-z, Krylov x-y-z) against scipy, round trips, gimbal lock.

scipy.spatial.transform.Rotation is the independent oracle.  Mapping (worked out once):

* ``Rotation.from_quat(q)`` uses scalar-last quaternions and ``as_matrix()`` is the ACTIVE
  matrix, i.e. our ``C_nb = quat_as_matrix(q_nb)``; the textbook's A is its transpose.
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
from rotation_oracle import edge_rotvecs, quiet, random_quats, scipy_angle
from scipy.spatial.transform import Rotation

from gyro_attitude.core import euler_kinematics as ek
from gyro_attitude.core import rotation as rot


# --------------------------------------------------------------------------- scipy oracle
def test_passive_rotations_are_transposed_active_scipy_rotations():
    a = np.linspace(-3, 3, 7)
    for k, axis in ((1, "x"), (2, "y"), (3, "z")):
        got = getattr(ek, f"passive_r{k}")(a)
        np.testing.assert_allclose(got, Rotation.from_euler(axis, -a[:, None]).as_matrix(), atol=1e-16)


def test_euler_zxz_against_scipy_intrinsic_and_extrinsic():
    rng = np.random.default_rng(12)
    ang = rng.uniform(-np.pi, np.pi, (1000, 3))
    ang[:, 1] = rng.uniform(0, np.pi, 1000)
    q = ek.quat_from_euler_zxz(ang)
    assert np.all(scipy_angle(q, Rotation.from_euler("ZXZ", ang).as_quat()) < 1e-15)
    assert np.all(scipy_angle(q, Rotation.from_euler("zxz", ang[:, ::-1]).as_quat()) < 1e-15)
    np.testing.assert_allclose(
        ek.dcm_a_from_euler_zxz(ang),
        np.swapaxes(Rotation.from_euler("ZXZ", ang).as_matrix(), -1, -2),
        atol=1e-15,
    )
    # Away from lock scipy's angles are the same member of the family (ψ, φ in (−π, π]).
    ok = (ang[:, 1] > 1e-3) & (ang[:, 1] < np.pi - 1e-3)
    np.testing.assert_allclose(
        ek.quat_as_euler_zxz(q[ok]), Rotation.from_quat(q[ok]).as_euler("ZXZ"), atol=1e-11
    )


def test_krylov_against_scipy_intrinsic_and_extrinsic():
    rng = np.random.default_rng(13)
    ang = rng.uniform(-np.pi, np.pi, (1000, 3))
    ang[:, 1] = rng.uniform(-np.pi / 2, np.pi / 2, 1000)
    q = ek.quat_from_krylov(ang)
    assert np.all(scipy_angle(q, Rotation.from_euler("XYZ", ang).as_quat()) < 1e-15)
    assert np.all(scipy_angle(q, Rotation.from_euler("zyx", ang[:, ::-1]).as_quat()) < 1e-15)
    np.testing.assert_allclose(
        ek.dcm_a_from_krylov(ang),
        np.swapaxes(Rotation.from_euler("XYZ", ang).as_matrix(), -1, -2),
        atol=1e-15,
    )
    ok = np.abs(ang[:, 1]) < np.pi / 2 - 1e-3
    np.testing.assert_allclose(
        ek.quat_as_krylov(q[ok]), Rotation.from_quat(q[ok]).as_euler("XYZ"), atol=1e-11
    )


def test_dcm_a_from_quat_is_transpose_of_scipy_matrix():
    q = random_quats(100, 14)
    np.testing.assert_allclose(
        ek.dcm_a_from_quat(q), np.swapaxes(Rotation.from_quat(q).as_matrix(), -1, -2),
        atol=1e-15,
    )
    assert np.all(scipy_angle(ek.quat_from_dcm_a(ek.dcm_a_from_quat(q)), q) < 1e-15)


# --------------------------------------------------------------------------- round trips
def test_angle_round_trips_on_random_sets():
    rng = np.random.default_rng(15)
    ang = rng.uniform(-np.pi, np.pi, (2000, 3))
    ang[:, 1] = rng.uniform(0.01, np.pi - 0.01, 2000)
    np.testing.assert_allclose(ek.quat_as_euler_zxz(ek.quat_from_euler_zxz(ang)), ang, atol=1e-13)
    np.testing.assert_allclose(
        ek.euler_zxz_from_dcm_a(ek.dcm_a_from_euler_zxz(ang)), ang, atol=1e-13
    )
    ang[:, 1] = rng.uniform(-np.pi / 2 + 0.01, np.pi / 2 - 0.01, 2000)
    np.testing.assert_allclose(ek.quat_as_krylov(ek.quat_from_krylov(ang)), ang, atol=1e-13)
    np.testing.assert_allclose(
        ek.krylov_from_dcm_a(ek.dcm_a_from_krylov(ang)), ang, atol=1e-13
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
            "dcm_a": ek.quat_from_dcm_a(ek.dcm_a_from_quat(qq)),
            "euler": ek.quat_from_euler_zxz(quiet(ek.quat_as_euler_zxz, qq)),
            "euler-A": ek.quat_from_euler_zxz(
                quiet(ek.euler_zxz_from_dcm_a, ek.dcm_a_from_quat(qq))
            ),
            "krylov": ek.quat_from_krylov(quiet(ek.quat_as_krylov, qq)),
            "krylov-A": ek.quat_from_krylov(
                quiet(ek.krylov_from_dcm_a, ek.dcm_a_from_quat(qq))
            ),
        }
        for name, back in checks.items():
            err = scipy_angle(back, q)
            assert np.all(err < 2 * ek.GIMBAL_LOCK_TOL + 1e-15), (name, err.max())
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
    q = ek.quat_from_euler_zxz(ang)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        back = ek.quat_as_euler_zxz(q)
        back_a = ek.euler_zxz_from_dcm_a(ek.dcm_a_from_euler_zxz(ang))
    assert np.all(scipy_angle(ek.quat_from_euler_zxz(back), q) < 1e-15)
    assert np.all(scipy_angle(ek.quat_from_euler_zxz(back_a), q) < 4e-16 * 4)
    # From exact quaternions the split ψ/φ is recovered too (not only the rotation).
    np.testing.assert_allclose(back, ang, atol=1e-9)


@pytest.mark.parametrize("gamma", [np.pi / 2 - 1e-6, -np.pi / 2 + 1e-8, 1e-12, 0.0])
def test_krylov_near_lock_outside_tolerance_is_exact_in_rotation(gamma):
    ang = np.array([[0.7, gamma, -2.1], [-3.0, gamma, 0.4]])
    q = ek.quat_from_krylov(ang)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        back = ek.quat_as_krylov(q)
    assert np.all(scipy_angle(ek.quat_from_krylov(back), q) < 1e-15)
    np.testing.assert_allclose(back, ang, atol=1e-9)


def test_near_lock_only_the_defined_combination_is_well_conditioned():
    """θ = 1e-6: a 1e-13 rad perturbation of the attitude may move ψ and φ each by up to
    ~1e-13/θ, but ψ + φ (the rotation about the nearly common z axis) only by ~1e-13,
    and the returned angles still reproduce the perturbed attitude to rounding."""
    ang = np.array([0.7, 1e-6, -2.1])
    q = ek.quat_from_euler_zxz(ang)
    dq = rot.quat_from_rotvec([1e-13, -2e-13, 0.5e-13])
    qp = rot.quat_multiply(q, dq)
    got = ek.quat_as_euler_zxz(qp)
    assert abs((got[0] + got[2]) - (ang[0] + ang[2])) < 5e-13
    assert 1e-10 < abs(got[0] - ang[0]) < 1e-6  # ψ alone is ill-conditioned, as documented
    assert scipy_angle(ek.quat_from_euler_zxz(got), qp) < 1e-15


def test_small_gamma_keeps_relative_accuracy():
    # sin γ = 2(wy + xz) is read directly, so γ = 1e-12 keeps ~full relative precision.
    back = ek.quat_as_krylov(ek.quat_from_krylov([0.0, 1e-12, 0.0]))
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
    q = ek.quat_from_euler_zxz(angles)
    with pytest.warns(UserWarning, match="Gimbal lock detected in 1 of 1.*psi = 0"):
        got = ek.quat_as_euler_zxz(q)
    np.testing.assert_allclose(got, expected, atol=1e-14)
    # The chosen member is the same attitude (within 2·θ for θ inside the tolerance).
    distance_to_lock = min(angles[1], np.pi - angles[1])
    assert scipy_angle(ek.quat_from_euler_zxz(got), q) < 2 * distance_to_lock + 1e-15
    with pytest.warns(UserWarning, match="Gimbal lock"):
        got_a = ek.euler_zxz_from_dcm_a(ek.dcm_a_from_euler_zxz(angles))
    np.testing.assert_allclose(got_a, expected, atol=1e-14)


@pytest.mark.parametrize(
    ("angles", "expected"),
    [
        ([0.3, np.pi / 2, 0.5], [0.0, np.pi / 2, 0.8]),  # γ = +90°: δ + φ
        ([0.3, -np.pi / 2, 0.5], [0.0, -np.pi / 2, 0.2]),  # γ = −90°: δ − φ = −0.2
    ],
)
def test_krylov_gimbal_lock_member_and_warning(angles, expected):
    q = ek.quat_from_krylov(angles)
    with pytest.warns(UserWarning, match="Gimbal lock detected.*delta = 0"):
        got = ek.quat_as_krylov(q)
    np.testing.assert_allclose(got, expected, atol=1e-14)
    assert scipy_angle(ek.quat_from_krylov(got), q) < 1e-15
    with pytest.warns(UserWarning, match="Gimbal lock"):
        got_a = ek.krylov_from_dcm_a(ek.dcm_a_from_krylov(angles))
    np.testing.assert_allclose(got_a, expected, atol=1e-14)
    np.testing.assert_allclose(ek.dcm_a_from_krylov(got),
                               ek.dcm_a_from_krylov(angles), atol=1e-15)


def test_lock_warning_is_issued_once_per_call_and_counts():
    ang = np.zeros((5, 3))
    ang[:3, 1] = 1.0
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        ek.quat_as_euler_zxz(ek.quat_from_euler_zxz(ang))
    assert len(rec) == 1 and "2 of 5" in str(rec[0].message)
    assert rec[0].filename == __file__  # points at the caller, like scipy


def test_lock_tolerance_is_configurable():
    q = ek.quat_from_euler_zxz([0.3, 1e-6, 0.5])
    with pytest.warns(UserWarning):
        got = ek.quat_as_euler_zxz(q, lock_tol=1e-5)
    assert got[0] == 0.0
    assert scipy_angle(ek.quat_from_euler_zxz(got), q) < 2e-6
    with pytest.raises(ValueError, match="lock_tol"):
        ek.quat_as_euler_zxz(q, lock_tol=-1.0)


# --------------------------------------------------------------------------- bad input
@pytest.mark.parametrize(
    ("fn", "arg", "match"),
    [
        (ek.quat_from_euler_zxz, [0.1, 0.2], r"shape \(\.\.\., 3\)"),
        (ek.quat_from_krylov, [[0.1, np.nan, 0.2]], "non-finite"),
        (ek.dcm_a_from_euler_zxz, [0.1, np.inf, 0.2], "non-finite"),
        (ek.quat_as_euler_zxz, [0.0, 0.0, 0.0, 0.0], "zero norm"),
        (ek.quat_as_krylov, [0.0, 0.0, 1.0], r"shape \(\.\.\., 4\)"),
        (ek.euler_zxz_from_dcm_a, np.eye(3) * 1.01, "not orthogonal"),
        (ek.krylov_from_dcm_a, np.diag([-1.0, 1.0, 1.0]), "reflection"),
        (ek.quat_from_dcm_a, np.eye(2), r"shape \(\.\.\., 3, 3\)"),
        (ek.passive_r1, [0.0, np.nan], "non-finite"),
    ],
)
def test_bad_input_raises_value_error_naming_the_problem(fn, arg, match):
    with pytest.raises(ValueError, match=match):
        fn(arg)


def test_bad_rate_input():
    with pytest.raises(ValueError, match="body rates.*shape"):
        ek.euler_zxz_rates_from_body_rates([0.1, 1.0, 0.2], [1.0, 2.0])
    with pytest.raises(ValueError, match="Krylov angle rates.*non-finite"):
        ek.body_rates_from_krylov_rates([0.1, 1.0, 0.2], [1.0, np.nan, 0.0])
    with pytest.raises(ValueError, match="tol"):
        ek.krylov_rates_from_body_rates([0.1, 1.0, 0.2], [1.0, 2.0, 3.0], tol=np.nan)


def test_batched_shapes_broadcast():
    ang = np.zeros((2, 5, 3))
    assert ek.quat_from_euler_zxz(ang).shape == (2, 5, 4)
    assert ek.dcm_a_from_krylov(ang).shape == (2, 5, 3, 3)
    assert ek.body_rates_from_euler_zxz_rates(ang, [1.0, 2.0, 3.0]).shape == (2, 5, 3)
    assert ek.quat_as_krylov(np.tile([0.0, 0.0, 0.0, 1.0], (4, 1, 1))).shape == (4, 1, 3)
    assert ek.quat_as_euler_zxz(rot.quat_identity((0,))).shape == (0, 3)


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
        (ek.quat_as_euler_zxz, ek.quat_from_euler_zxz),
        (ek.quat_as_krylov, ek.quat_from_krylov),
    ):
        ang = quiet(to_angles, q)
        assert scipy_angle(from_angles(ang), q) < 2 * ek.GIMBAL_LOCK_TOL + 1e-15
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
    w = ek.body_rates_from_euler_zxz_rates(angles, rates)
    np.testing.assert_allclose(ek.euler_zxz_rates_from_body_rates(angles, w), rates, atol=scale)
    w0 = ek.fixed_rates_from_euler_zxz_rates(angles, rates)
    np.testing.assert_allclose(ek.euler_zxz_rates_from_fixed_rates(angles, w0), rates, atol=scale)
    # |ω| is frame independent: body and fixed components describe one vector.
    assert np.linalg.norm(w) == pytest.approx(np.linalg.norm(w0), rel=1e-12, abs=1e-12)
    k = angles - np.array([0.0, np.pi / 2, 0.0])  # γ in (−π/2, π/2) away from ±90°
    scale_k = 1e-12 * (1 + np.abs(rates).max()) / np.cos(k[1])
    wk = ek.body_rates_from_krylov_rates(k, rates)
    np.testing.assert_allclose(ek.krylov_rates_from_body_rates(k, wk), rates, atol=scale_k)


def test_rodrigues_hamilton_parameters_are_scalar_first():
    lam = ek.quat_as_rodrigues_hamilton([1.0, 2.0, 3.0, 4.0])
    np.testing.assert_array_equal(lam, [4.0, 1.0, 2.0, 3.0])
    np.testing.assert_array_equal(ek.quat_from_rodrigues_hamilton(lam), [1.0, 2.0, 3.0, 4.0])
    # §1-5: λ0 = cos(χ/2), (λ1, λ2, λ3) = e sin(χ/2) for a rotation χ about the unit axis e
    e, chi = np.array([2.0, -1.0, 2.0]) / 3.0, 0.7
    q = Rotation.from_rotvec(chi * e).as_quat()
    np.testing.assert_allclose(ek.quat_as_rodrigues_hamilton(q),
                               np.r_[np.cos(chi / 2), e * np.sin(chi / 2)], rtol=0, atol=1e-16)
