"""Rotation algebra against closed forms and scipy (``Rotation`` is the independent oracle:
``from_quat`` is scalar-last and ``as_matrix()`` is the active matrix, our ``C_nb``)."""



import numpy as np
import pytest
from rotation_oracle import DEG, random_quats, scipy_angle
from scipy.spatial.transform import Rotation

from gyro_attitude.core import rotation as rot


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


def test_canonical_sign():
    q = np.array([[0.1, 0.2, 0.3, -0.9], [0.0, -1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]])
    c = rot.quat_canonical(q)
    np.testing.assert_array_equal(c, [[-0.1, -0.2, -0.3, 0.9], [0.0, 1.0, 0.0, 0.0], q[2]])


@pytest.mark.parametrize(
    ("fn", "arg", "match"),
    [
        (rot.quat_from_rotvec, [1.0, np.nan, 0.0], "non-finite"),
        (rot.quat_from_matrix, np.ones((3, 3)), "not orthogonal"),
        (rot.quat_normalize, [[1.0, 0, 0, 0], [0, 0, 0, 0]], "zero norm"),
        (rot.quat_inverse, [0.0, 0.0, 0.0, 0.0], "zero norm"),
        (rot.quat_as_matrix, [0.0, 0.0, 1.0], r"shape \(\.\.\., 4\)"),
    ],
)
def test_bad_input_raises_value_error_naming_the_problem(fn, arg, match):
    with pytest.raises(ValueError, match=match):
        fn(arg)
