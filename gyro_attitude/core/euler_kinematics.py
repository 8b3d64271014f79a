"""Chapter-1 kinematics of the textbook: direction-cosine matrix A, Euler and Krylov angles, (1-10)…(1-24).

Equation and section numbers are those of chapter 1 of the gyroscope-mechanics textbook;
``docs/equations.md`` maps each to the function here and states the conventions:

* the direction-cosine matrix A of (1-4), ``x = A ξ`` (fixed coordinates to body
  coordinates), built from the passive elementary rotations R1, R2, R3, is ``C_bn``;
  its orthogonality relations are (1-6) and composition (1-24) is ``A = C B``;
* classical Euler angles (ψ precession, θ nutation, φ spin), z-x-z, with the body-rate
  equations (1-10) and fixed-frame rates (1-11);
* Krylov angles (δ, γ, φ), x-y-z, their small-angle matrix (1-13), body rates (1-15)
  and the small-angle form (1-16);
* the Rodrigues–Hamilton parameters of §1-5, (λ0, λ1, λ2, λ3) scalar-first, against the
  package's scalar-last quaternions;
* gimbal lock: the angle conversions return ψ = 0 (δ = 0) with the whole rotation in φ
  and warn; the rate inverses raise :class:`GimbalLockError` (a ``ValueError``).

The quaternion and matrix algebra these build on is in :mod:`gyro_attitude.core.rotation`.
Bad input raises ``ValueError`` naming the problem.
"""

from __future__ import annotations

import numpy as np

from gyro_attitude.core.angles import wrap_pi_closed
from gyro_attitude.core.rotation import (
    as_matrix_array,
    as_quat_array,
    as_vector_array,
    check_rotation_matrix,
    quat_as_matrix,
    quat_from_matrix,
    quat_normalize,
    skew,
)

__all__ = [
    "quat_from_rodrigues_hamilton",
    "quat_as_rodrigues_hamilton",
    "GIMBAL_LOCK_TOL",
    "GimbalLockError",
    "passive_r1",
    "passive_r2",
    "passive_r3",
    "dcm_a_from_quat",
    "quat_from_dcm_a",
    "compose_dcm_a",
    "dcm_a_from_euler_zxz",
    "quat_from_euler_zxz",
    "quat_as_euler_zxz",
    "euler_zxz_from_dcm_a",
    "dcm_a_from_krylov",
    "dcm_a_from_krylov_small_angle",
    "quat_from_krylov",
    "quat_as_krylov",
    "krylov_from_dcm_a",
    "body_rates_from_euler_zxz_rates",
    "euler_zxz_rates_from_body_rates",
    "fixed_rates_from_euler_zxz_rates",
    "euler_zxz_rates_from_fixed_rates",
    "body_rates_from_krylov_rates",
    "body_rates_from_krylov_rates_small_angle",
    "krylov_rates_from_body_rates",
    "fixed_rates_from_krylov_rates",
    "krylov_rates_from_fixed_rates",
    "euler_zxz_body_rate_matrix",
    "euler_zxz_fixed_rate_matrix",
    "krylov_body_rate_matrix",
    "krylov_body_rate_matrix_small_angle",
]


# --------------------------------------------------------------------------- Rodrigues–Hamilton
def quat_from_rodrigues_hamilton(lam) -> np.ndarray:
    """Scalar-last quaternion from the scalar-first (λ0, λ1, λ2, λ3) (§1-5)."""
    lam = as_quat_array(lam, "Rodrigues-Hamilton parameters")
    return np.concatenate((lam[..., 1:], lam[..., :1]), axis=-1)


def quat_as_rodrigues_hamilton(q) -> np.ndarray:
    """The scalar-first Rodrigues-Hamilton parameters (λ0, λ1, λ2, λ3) of ``q``."""
    q = as_quat_array(q)
    return np.concatenate((q[..., 3:], q[..., :3]), axis=-1)



# Euler angles (§1-1), Krylov angles (§1-3), their kinematic equations (§1-2, §1-3),
# the matrix A (§1-1, §1-4) and its composition (1-24).
#
# The text writes attitudes as the matrix A of (1-4), ``x = A ξ``: fixed (ξ, η, ζ)
# coordinates into body (x, y, z) coordinates, built from PASSIVE elementary rotations
#
#     R1(a) = [[1, 0, 0], [0, c, s], [0, −s, c]]      (about x)
#     R2(a) = [[c, 0, −s], [0, 1, 0], [s, 0, c]]      (about y)
#     R3(a) = [[c, s, 0], [−s, c, 0], [0, 0, 1]]      (about z),   c = cos a, s = sin a.
#
# In this package the fixed frame is n and the body frame b, so ``A = C_bn`` and our
# quaternion ``q_nb`` has ``quat_as_matrix(q_nb) = C_nb = Aᵀ``.  A passive R_k(a) is the
# transpose of the active rotation by a about axis k, which gives the scipy equivalents:
#
#   * classical Euler angles (ψ precession, θ nutation, φ spin), ``A = R3(φ) R1(θ) R3(ψ)``:
#     ``C_nb = Rz(ψ) Rx(θ) Rz(φ)`` (active) ``= Rotation.from_euler("ZXZ", [ψ, θ, φ])``
#     (intrinsic) ``= Rotation.from_euler("zxz", [φ, θ, ψ])`` (extrinsic);
#   * Krylov angles (δ, γ, φ), ``A = R3(φ) R2(γ) R1(δ)``:
#     ``C_nb = Rx(δ) Ry(γ) Rz(φ) = Rotation.from_euler("XYZ", [δ, γ, φ])``.
#
# Angle arrays have shape (..., 3) ordered (ψ, θ, φ) and (δ, γ, φ); rates likewise.
# Returned angles: ψ, φ, δ in (−π, π]; θ in [0, π]; γ in [−π/2, π/2].

#: Default tolerance (rad) for gimbal lock: the angle conversions treat θ within this of
#: 0 or π (z-x-z), or γ within this of ±π/2 (Krylov), as locked; the rate inversions
#: raise :class:`GimbalLockError` when |sin θ| (or |cos γ|) is at or below it.
#: Trade-off: a locked result reproduces the attitude only to ~2·tol rad; outside the
#: lock the attitude is reproduced to rounding, but an input error ε (in q or A) can move
#: ψ and φ individually by ~ε/sin θ (by ~ε/cos γ for δ, φ).  1e-9 keeps both small.
GIMBAL_LOCK_TOL = 1e-9

_TWO_PI = 2.0 * np.pi


class GimbalLockError(ValueError):
    """Euler/Krylov angle rates requested at (or too near) a singular attitude.

    The inverse kinematic equations divide by sin θ (z-x-z, θ = 0 or π: the upright
    spinning top) or by cos γ (Krylov, γ = ±90°).  Rather than return inf or NaN, the
    functions raise this ``ValueError`` subclass naming the angle and the tolerance.
    """


def _as_angle_array(a, name: str) -> np.ndarray:
    a = np.asarray(a, dtype=np.float64)
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} contains non-finite values (NaN or inf)")
    return a


_wrap_pi = wrap_pi_closed  # (−π, π]


def _check_lock_tol(lock_tol: float) -> float:
    lock_tol = float(lock_tol)
    if not (0.0 <= lock_tol < 0.5):
        raise ValueError(f"lock_tol must be in [0, 0.5) rad, got {lock_tol!r}")
    return lock_tol


# --------------------------------------------------------------------------- passive R1 R2 R3
def _passive(angle, axis: int) -> np.ndarray:
    a = _as_angle_array(angle, "angle")
    c, s = np.cos(a), np.sin(a)
    m = np.zeros(a.shape + (3, 3))
    i, j = (axis + 1) % 3, (axis + 2) % 3
    m[..., axis, axis] = 1.0
    m[..., i, i] = c
    m[..., j, j] = c
    m[..., i, j] = s
    m[..., j, i] = -s
    return m


def passive_r1(angle) -> np.ndarray:
    """The passive rotation R1(a) about x, shape ``angle.shape + (3, 3)``.

    ``R1(a) = [[1, 0, 0], [0, cos a, sin a], [0, −sin a, cos a]]``: coordinates of a fixed
    vector in axes turned by +a about x.  Equal to the transpose of the active rotation.
    """
    return _passive(angle, 0)


def passive_r2(angle) -> np.ndarray:
    """The passive rotation R2(a) about y: ``[[c, 0, −s], [0, 1, 0], [s, 0, c]]``."""
    return _passive(angle, 1)


def passive_r3(angle) -> np.ndarray:
    """The passive rotation R3(a) about z: ``[[c, s, 0], [−s, c, 0], [0, 0, 1]]``."""
    return _passive(angle, 2)


# ------------------------------------------------------------------------- direction-cosine matrix A
def dcm_a_from_quat(q_nb) -> np.ndarray:
    """The matrix ``A = C_bn = C_nbᵀ`` (fixed → body coordinates, 1-4) of ``q_nb``."""
    return np.swapaxes(quat_as_matrix(q_nb), -1, -2)


def quat_from_dcm_a(a, atol: float = 1e-6) -> np.ndarray:
    """Quaternion ``q_nb`` (``w >= 0``) of the matrix ``A = C_bn``.

    ``A`` must be orthogonal with det +1 (relations 1-6) to within ``atol``.
    """
    a = as_matrix_array(a, "direction-cosine matrix A")
    return quat_from_matrix(np.swapaxes(a, -1, -2), atol=atol)


def compose_dcm_a(c, b, atol: float = 1e-6) -> np.ndarray:
    """(1-24): the rotation B followed by the rotation C is ``A = C B``.

    Both must be rotation matrices to within ``atol``; broadcasts over leading axes.  In
    quaternions the same composition is ``quat_multiply(q_B, q_C)`` for ``q = q_nb`` of
    each (``A = C_bn``, so the order flips with the transpose).
    """
    c = check_rotation_matrix(c, atol=atol, name="C")
    b = check_rotation_matrix(b, atol=atol, name="B")
    return c @ b


# --------------------------------------------------------------------------- Euler z-x-z
def dcm_a_from_euler_zxz(angles) -> np.ndarray:
    """§1-1: ``A = R3(φ) R1(θ) R3(ψ)`` from classical Euler angles (ψ, θ, φ).

    ``angles`` has shape (..., 3) ordered (ψ precession, θ nutation, φ spin) in rad; the
    result (..., 3, 3) maps fixed coordinates into body coordinates (``A = C_bn``).
    """
    a = as_vector_array(angles, "Euler angles (psi, theta, phi)")
    cp, sp = np.cos(a[..., 0]), np.sin(a[..., 0])
    ct, st = np.cos(a[..., 1]), np.sin(a[..., 1])
    cf, sf = np.cos(a[..., 2]), np.sin(a[..., 2])
    return np.stack(
        (
            np.stack((cp * cf - sp * ct * sf, sp * cf + cp * ct * sf, st * sf), axis=-1),
            np.stack((-cp * sf - sp * ct * cf, -sp * sf + cp * ct * cf, st * cf), axis=-1),
            np.stack((sp * st, -cp * st, ct), axis=-1),
        ),
        axis=-2,
    )


def quat_from_euler_zxz(angles) -> np.ndarray:
    """Quaternion ``q_nb`` of classical Euler angles (ψ, θ, φ), shape (..., 4).

    ``q_nb = qz(ψ) ⊗ qx(θ) ⊗ qz(φ)`` (same as ``Rotation.from_euler("ZXZ", ...)``),
    written in closed form::

        x = sin(θ/2) cos((ψ−φ)/2),  y = sin(θ/2) sin((ψ−φ)/2),
        z = cos(θ/2) sin((ψ+φ)/2),  w = cos(θ/2) cos((ψ+φ)/2).

    The sign is not canonicalised (``w`` may be negative); see :func:`quat_canonical`.
    """
    a = as_vector_array(angles, "Euler angles (psi, theta, phi)")
    half_sum = 0.5 * (a[..., 0] + a[..., 2])
    half_diff = 0.5 * (a[..., 0] - a[..., 2])
    ct, st = np.cos(0.5 * a[..., 1]), np.sin(0.5 * a[..., 1])
    return np.stack(
        (st * np.cos(half_diff), st * np.sin(half_diff), ct * np.sin(half_sum),
         ct * np.cos(half_sum)),
        axis=-1,
    )


def _warn_gimbal_lock(locked: np.ndarray, what: str, stacklevel: int) -> None:
    import warnings

    n = int(np.count_nonzero(locked))
    warnings.warn(
        f"Gimbal lock detected in {n} of {locked.size} attitude(s): {what}",
        UserWarning,
        stacklevel=stacklevel + 1,
    )


def _euler_zxz_from_unit_quat(q: np.ndarray, lock_tol: float, stacklevel: int) -> np.ndarray:
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    # Half-angle form (Bernardes & Viollet 2022, also scipy's): θ from two hypot's with
    # atan2 is accurate at both ends; (ψ+φ)/2 and (ψ−φ)/2 come from separate atan2's, so
    # the well-determined combination keeps full accuracy near the lock.  q and −q give
    # half-angles differing by π each, hence the same ψ, φ modulo 2π.
    theta = 2.0 * np.arctan2(np.hypot(x, y), np.hypot(z, w))
    half_sum = np.arctan2(z, w)
    half_diff = np.arctan2(y, x)
    psi = half_sum + half_diff
    phi = half_sum - half_diff
    lock0 = theta <= lock_tol
    lock_pi = theta >= np.pi - lock_tol
    locked = lock0 | lock_pi
    if np.any(locked):
        # Only ψ+φ (θ = 0) or ψ−φ (θ = π) is determined: choose ψ = 0, all into φ.
        psi = np.where(locked, 0.0, psi)
        phi = np.where(lock0, 2.0 * half_sum, np.where(lock_pi, -2.0 * half_diff, phi))
        _warn_gimbal_lock(
            locked,
            f"theta within {lock_tol:g} rad of 0 or pi, so psi and phi are not unique; "
            "set psi = 0 and put the whole rotation about z into phi",
            stacklevel + 1,
        )
    return np.stack((_wrap_pi(psi), theta, _wrap_pi(phi)), axis=-1)


def quat_as_euler_zxz(q, lock_tol: float = GIMBAL_LOCK_TOL) -> np.ndarray:
    """Classical Euler angles (ψ, θ, φ) of ``q_nb``, shape (..., 3).

    Inverse of :func:`quat_from_euler_zxz`: ψ, φ in (−π, π], θ in [0, π]; ``q`` and ``−q``
    give the same angles.  At gimbal lock (θ within ``lock_tol`` of 0 or π) only ψ+φ
    (θ ≈ 0) or ψ−φ (θ ≈ π) is defined: the result is the member with ψ = 0 and the whole
    rotation about z put into φ, and a ``UserWarning`` ("Gimbal lock detected ...") is
    issued once per call.  Such a result reproduces the attitude to within about
    2·``lock_tol`` rad; outside the lock the reconstruction is accurate to rounding
    (near the lock ψ and φ individually are ill-conditioned: an error ε in ``q`` moves
    them by up to ~ε/sin θ, their sum or difference stays accurate).
    """
    return _euler_zxz_from_unit_quat(quat_normalize(q), _check_lock_tol(lock_tol), 2)


def euler_zxz_from_dcm_a(
    a, atol: float = 1e-6, lock_tol: float = GIMBAL_LOCK_TOL
) -> np.ndarray:
    """Classical Euler angles (ψ, θ, φ) of the matrix ``A = R3(φ) R1(θ) R3(ψ)``.

    Goes through the Markley quaternion of ``Aᵀ`` and the half-angle atan2 formulas of
    :func:`quat_as_euler_zxz` (same ranges and gimbal-lock convention).  ``A`` must be a
    rotation to within ``atol``.
    """
    lock_tol = _check_lock_tol(lock_tol)
    return _euler_zxz_from_unit_quat(quat_from_dcm_a(a, atol=atol), lock_tol, 2)


# --------------------------------------------------------------------------- Krylov x-y-z
def dcm_a_from_krylov(angles) -> np.ndarray:
    """§1-3: ``A = R3(φ) R2(γ) R1(δ)`` from Krylov angles (δ, γ, φ), shape (..., 3, 3).

    δ about the fixed ξ axis, γ about the node line ON, φ about the body z axis (rad).
    """
    a = as_vector_array(angles, "Krylov angles (delta, gamma, phi)")
    cd, sd = np.cos(a[..., 0]), np.sin(a[..., 0])
    cg, sg = np.cos(a[..., 1]), np.sin(a[..., 1])
    cf, sf = np.cos(a[..., 2]), np.sin(a[..., 2])
    return np.stack(
        (
            np.stack((cg * cf, cd * sf + sd * sg * cf, sd * sf - cd * sg * cf), axis=-1),
            np.stack((-cg * sf, cd * cf - sd * sg * sf, sd * cf + cd * sg * sf), axis=-1),
            np.stack((sg, -sd * cg, cd * cg), axis=-1),
        ),
        axis=-2,
    )


def dcm_a_from_krylov_small_angle(angles) -> np.ndarray:
    """(1-13): first-order A for small Krylov angles (δ, γ, φ).

    Rows ``x (1, φ, −γ)``, ``y (−φ, 1, δ)``, ``z (γ, −δ, 1)``: ``A ≈ I − [ω×]`` with
    ``ω = (δ, γ, φ)``; it differs from :func:`dcm_a_from_krylov` by second-order
    terms (and is not exactly orthogonal).
    """
    a = as_vector_array(angles, "Krylov angles (delta, gamma, phi)")
    return np.eye(3) - skew(a)


def quat_from_krylov(angles) -> np.ndarray:
    """Quaternion ``q_nb = qx(δ) ⊗ qy(γ) ⊗ qz(φ)`` of Krylov angles (δ, γ, φ), (..., 4).

    Same as ``Rotation.from_euler("XYZ", [δ, γ, φ]).as_quat()`` up to sign; not
    canonicalised.
    """
    a = as_vector_array(angles, "Krylov angles (delta, gamma, phi)")
    cd, sd = np.cos(0.5 * a[..., 0]), np.sin(0.5 * a[..., 0])
    cg, sg = np.cos(0.5 * a[..., 1]), np.sin(0.5 * a[..., 1])
    cf, sf = np.cos(0.5 * a[..., 2]), np.sin(0.5 * a[..., 2])
    return np.stack(
        (
            sd * cg * cf + cd * sg * sf,
            cd * sg * cf - sd * cg * sf,
            cd * cg * sf + sd * sg * cf,
            cd * cg * cf - sd * sg * sf,
        ),
        axis=-1,
    )


def _krylov_from_unit_quat(q: np.ndarray, lock_tol: float, stacklevel: int) -> np.ndarray:
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    # Multiplying out qx(δ) ⊗ qy(γ) ⊗ qz(φ) (g = γ/2):
    #   (w + y, x + z) = (cos g + sin g) (cos((δ+φ)/2), sin((δ+φ)/2)),
    #   (w − y, x − z) = (cos g − sin g) (cos((δ−φ)/2), sin((δ−φ)/2)),
    # and both prefactors are >= 0 for |γ| <= π/2.  Their product is cos γ and
    # 2(wy + xz) = sin γ (= C_nb[0, 2]), so γ = atan2(sin γ, cos γ) keeps full relative
    # accuracy at small γ and absolute accuracy near ±π/2.
    a_plus = np.hypot(w + y, x + z)
    a_minus = np.hypot(w - y, x - z)
    gamma = np.arctan2(2.0 * (w * y + x * z), a_plus * a_minus)
    half_sum = np.arctan2(x + z, w + y)
    half_diff = np.arctan2(x - z, w - y)
    delta = half_sum + half_diff
    phi = half_sum - half_diff
    lock_up = gamma >= 0.5 * np.pi - lock_tol
    lock_down = gamma <= -0.5 * np.pi + lock_tol
    locked = lock_up | lock_down
    if np.any(locked):
        # Only δ+φ (γ = +π/2) or δ−φ (γ = −π/2) is determined: choose δ = 0.
        delta = np.where(locked, 0.0, delta)
        phi = np.where(lock_up, 2.0 * half_sum, np.where(lock_down, -2.0 * half_diff, phi))
        _warn_gimbal_lock(
            locked,
            f"gamma within {lock_tol:g} rad of +-pi/2, so delta and phi are not unique; "
            "set delta = 0 and put the whole rotation about z into phi",
            stacklevel + 1,
        )
    return np.stack((_wrap_pi(delta), gamma, _wrap_pi(phi)), axis=-1)


def quat_as_krylov(q, lock_tol: float = GIMBAL_LOCK_TOL) -> np.ndarray:
    """Krylov angles (δ, γ, φ) of ``q_nb``, shape (..., 3).

    Inverse of :func:`quat_from_krylov`: δ, φ in (−π, π], γ in [−π/2, π/2].  At gimbal
    lock (γ within ``lock_tol`` of ±π/2) the result has δ = 0 with the whole rotation
    about z in φ, and a ``UserWarning`` ("Gimbal lock detected ...") is issued once per
    call; the attitude is then reproduced to within about 2·``lock_tol`` rad.
    """
    return _krylov_from_unit_quat(quat_normalize(q), _check_lock_tol(lock_tol), 2)


def krylov_from_dcm_a(
    a, atol: float = 1e-6, lock_tol: float = GIMBAL_LOCK_TOL
) -> np.ndarray:
    """Krylov angles (δ, γ, φ) of the matrix ``A = R3(φ) R2(γ) R1(δ)``.

    Via the Markley quaternion of ``Aᵀ``; ranges and lock convention as
    :func:`quat_as_krylov`.
    """
    lock_tol = _check_lock_tol(lock_tol)
    return _krylov_from_unit_quat(quat_from_dcm_a(a, atol=atol), lock_tol, 2)


# --------------------------------------------------------------------------- kinematics
def _angles_and_rates(angles, rates, angle_name: str, rate_name: str):
    a = as_vector_array(angles, angle_name)
    r = as_vector_array(rates, rate_name)
    return a, r


def _check_singular(divisor: np.ndarray, tol: float, what: str) -> None:
    tol = float(tol)
    if not tol >= 0.0:
        raise ValueError(f"tol must be >= 0, got {tol!r}")
    bad = np.abs(divisor) <= tol
    if np.any(bad):
        worst = float(np.min(np.abs(divisor)))
        raise GimbalLockError(
            f"{what}: |{what.split(' ')[0]}| = {worst:.3g} <= tol={tol:g} in "
            f"{int(np.count_nonzero(bad))} of {bad.size} sample(s); the angle rates are "
            "undefined at gimbal lock (use quaternions there)"
        )


def body_rates_from_euler_zxz_rates(angles, angle_rates) -> np.ndarray:
    """(1-10): body rates (p, q, r) from Euler angle rates (ψ̇, θ̇, φ̇).

    ``p = ψ̇ sinθ sinφ + θ̇ cosφ``, ``q = ψ̇ sinθ cosφ − θ̇ sinφ``, ``r = ψ̇ cosθ + φ̇``:
    the angular velocity of the body relative to the fixed frame, resolved in body axes
    (``ω_nb^b`` for ``q_nb``).  Shapes (..., 3) broadcast.
    """
    a, d = _angles_and_rates(angles, angle_rates, "Euler angles", "Euler angle rates")
    st, ct = np.sin(a[..., 1]), np.cos(a[..., 1])
    sf, cf = np.sin(a[..., 2]), np.cos(a[..., 2])
    return np.stack(
        (
            d[..., 0] * st * sf + d[..., 1] * cf,
            d[..., 0] * st * cf - d[..., 1] * sf,
            d[..., 0] * ct + d[..., 2],
        ),
        axis=-1,
    )


def euler_zxz_rates_from_body_rates(
    angles, body_rates, tol: float = GIMBAL_LOCK_TOL
) -> np.ndarray:
    """Inverse of (1-10): Euler angle rates (ψ̇, θ̇, φ̇) from body rates (p, q, r).

    ``ψ̇ = (p sinφ + q cosφ)/sinθ``, ``θ̇ = p cosφ − q sinφ``, ``φ̇ = r − ψ̇ cosθ``.
    Raises :class:`GimbalLockError` when ``|sin θ| <= tol`` for any sample (θ = 0 or π:
    the upright top) instead of returning inf/NaN.
    """
    a, w = _angles_and_rates(angles, body_rates, "Euler angles", "body rates")
    st, ct = np.sin(a[..., 1]), np.cos(a[..., 1])
    _check_singular(st, tol, "sin(theta) (Euler nutation angle near 0 or pi)")
    sf, cf = np.sin(a[..., 2]), np.cos(a[..., 2])
    psi_dot = (w[..., 0] * sf + w[..., 1] * cf) / st
    return np.stack(
        (psi_dot, w[..., 0] * cf - w[..., 1] * sf, w[..., 2] - psi_dot * ct), axis=-1
    )


def fixed_rates_from_euler_zxz_rates(angles, angle_rates) -> np.ndarray:
    """(1-11): fixed-frame rates (p0, q0, r0) from Euler angle rates (ψ̇, θ̇, φ̇).

    ``p0 = θ̇ cosψ + φ̇ sinθ sinψ``, ``q0 = θ̇ sinψ − φ̇ sinθ cosψ``, ``r0 = ψ̇ + φ̇ cosθ``:
    the same angular velocity as (1-10), resolved in the fixed axes (``ω_nb^n``).
    """
    a, d = _angles_and_rates(angles, angle_rates, "Euler angles", "Euler angle rates")
    sp, cp = np.sin(a[..., 0]), np.cos(a[..., 0])
    st, ct = np.sin(a[..., 1]), np.cos(a[..., 1])
    return np.stack(
        (
            d[..., 1] * cp + d[..., 2] * st * sp,
            d[..., 1] * sp - d[..., 2] * st * cp,
            d[..., 0] + d[..., 2] * ct,
        ),
        axis=-1,
    )


def euler_zxz_rates_from_fixed_rates(
    angles, fixed_rates, tol: float = GIMBAL_LOCK_TOL
) -> np.ndarray:
    """Inverse of (1-11): ``φ̇ = (p0 sinψ − q0 cosψ)/sinθ``, ``θ̇ = p0 cosψ + q0 sinψ``,
    ``ψ̇ = r0 − φ̇ cosθ``.  Raises :class:`GimbalLockError` when ``|sin θ| <= tol``.
    """
    a, w = _angles_and_rates(angles, fixed_rates, "Euler angles", "fixed-frame rates")
    st, ct = np.sin(a[..., 1]), np.cos(a[..., 1])
    _check_singular(st, tol, "sin(theta) (Euler nutation angle near 0 or pi)")
    sp, cp = np.sin(a[..., 0]), np.cos(a[..., 0])
    phi_dot = (w[..., 0] * sp - w[..., 1] * cp) / st
    return np.stack(
        (w[..., 2] - phi_dot * ct, w[..., 0] * cp + w[..., 1] * sp, phi_dot), axis=-1
    )


def body_rates_from_krylov_rates(angles, angle_rates) -> np.ndarray:
    """(1-15): body rates (p, q, r) from Krylov angle rates (δ̇, γ̇, φ̇).

    ``p = δ̇ cosγ cosφ + γ̇ sinφ``, ``q = −δ̇ cosγ sinφ + γ̇ cosφ``, ``r = δ̇ sinγ + φ̇``.
    """
    a, d = _angles_and_rates(angles, angle_rates, "Krylov angles", "Krylov angle rates")
    sg, cg = np.sin(a[..., 1]), np.cos(a[..., 1])
    sf, cf = np.sin(a[..., 2]), np.cos(a[..., 2])
    return np.stack(
        (
            d[..., 0] * cg * cf + d[..., 1] * sf,
            -d[..., 0] * cg * sf + d[..., 1] * cf,
            d[..., 0] * sg + d[..., 2],
        ),
        axis=-1,
    )


def body_rates_from_krylov_rates_small_angle(angles, angle_rates) -> np.ndarray:
    """(1-16): small-angle form of (1-15), ``[[1, φ, 0], [−φ, 1, 0], [γ, 0, 1]]``
    times (δ̇, γ̇, φ̇); differs from (1-15) by terms of second order in the angles.
    """
    a, d = _angles_and_rates(angles, angle_rates, "Krylov angles", "Krylov angle rates")
    g, f = a[..., 1], a[..., 2]
    return np.stack(
        (d[..., 0] + f * d[..., 1], -f * d[..., 0] + d[..., 1], g * d[..., 0] + d[..., 2]),
        axis=-1,
    )


def krylov_rates_from_body_rates(
    angles, body_rates, tol: float = GIMBAL_LOCK_TOL
) -> np.ndarray:
    """Inverse of (1-15): ``δ̇ = (p cosφ − q sinφ)/cosγ``, ``γ̇ = p sinφ + q cosφ``,
    ``φ̇ = r − δ̇ sinγ``.  Raises :class:`GimbalLockError` when ``|cos γ| <= tol``
    (γ = ±90°).
    """
    a, w = _angles_and_rates(angles, body_rates, "Krylov angles", "body rates")
    sg, cg = np.sin(a[..., 1]), np.cos(a[..., 1])
    _check_singular(cg, tol, "cos(gamma) (Krylov angle gamma near +-90 deg)")
    sf, cf = np.sin(a[..., 2]), np.cos(a[..., 2])
    delta_dot = (w[..., 0] * cf - w[..., 1] * sf) / cg
    return np.stack(
        (delta_dot, w[..., 0] * sf + w[..., 1] * cf, w[..., 2] - delta_dot * sg), axis=-1
    )


def fixed_rates_from_krylov_rates(angles, angle_rates) -> np.ndarray:
    """Fixed-frame rates (p0, q0, r0) from Krylov angle rates (not printed in the text).

    From (1-14) ``ω = δ̇ i0 + γ̇ n + φ̇ k`` with ``n = (0, cosδ, sinδ)`` and
    ``k = (sinγ, −sinδ cosγ, cosδ cosγ)`` in fixed axes:
    ``p0 = δ̇ + φ̇ sinγ``, ``q0 = γ̇ cosδ − φ̇ sinδ cosγ``, ``r0 = γ̇ sinδ + φ̇ cosδ cosγ``.
    """
    a, d = _angles_and_rates(angles, angle_rates, "Krylov angles", "Krylov angle rates")
    sd, cd = np.sin(a[..., 0]), np.cos(a[..., 0])
    sg, cg = np.sin(a[..., 1]), np.cos(a[..., 1])
    return np.stack(
        (
            d[..., 0] + d[..., 2] * sg,
            d[..., 1] * cd - d[..., 2] * sd * cg,
            d[..., 1] * sd + d[..., 2] * cd * cg,
        ),
        axis=-1,
    )


def krylov_rates_from_fixed_rates(
    angles, fixed_rates, tol: float = GIMBAL_LOCK_TOL
) -> np.ndarray:
    """Inverse of :func:`fixed_rates_from_krylov_rates`: ``γ̇ = q0 cosδ + r0 sinδ``,
    ``φ̇ = (r0 cosδ − q0 sinδ)/cosγ``, ``δ̇ = p0 − φ̇ sinγ``; raises
    :class:`GimbalLockError` when ``|cos γ| <= tol``.
    """
    a, w = _angles_and_rates(angles, fixed_rates, "Krylov angles", "fixed-frame rates")
    sg, cg = np.sin(a[..., 1]), np.cos(a[..., 1])
    _check_singular(cg, tol, "cos(gamma) (Krylov angle gamma near +-90 deg)")
    sd, cd = np.sin(a[..., 0]), np.cos(a[..., 0])
    phi_dot = (w[..., 2] * cd - w[..., 1] * sd) / cg
    return np.stack(
        (w[..., 0] - phi_dot * sg, w[..., 1] * cd + w[..., 2] * sd, phi_dot), axis=-1
    )


# --------------------------------------------------------------------------- matrix forms
def _matrix_from_rows(rows) -> np.ndarray:
    return np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)


def euler_zxz_body_rate_matrix(angles) -> np.ndarray:
    """(1-10)': M with ``(p, q, r) = M (ψ̇, θ̇, φ̇)``, shape (..., 3, 3).

    ``[[sinθ sinφ, cosφ, 0], [sinθ cosφ, −sinφ, 0], [cosθ, 0, 1]]``; det M = −sin θ.
    """
    a = as_vector_array(angles, "Euler angles")
    st, ct = np.sin(a[..., 1]), np.cos(a[..., 1])
    sf, cf = np.sin(a[..., 2]), np.cos(a[..., 2])
    z, o = np.zeros_like(st), np.ones_like(st)
    return _matrix_from_rows(((st * sf, cf, z), (st * cf, -sf, z), (ct, z, o)))


def euler_zxz_fixed_rate_matrix(angles) -> np.ndarray:
    """(1-11)': M with ``(p0, q0, r0) = M (ψ̇, θ̇, φ̇)``, shape (..., 3, 3).

    ``[[0, cosψ, sinθ sinψ], [0, sinψ, −sinθ cosψ], [1, 0, cosθ]]``.
    """
    a = as_vector_array(angles, "Euler angles")
    sp, cp = np.sin(a[..., 0]), np.cos(a[..., 0])
    st, ct = np.sin(a[..., 1]), np.cos(a[..., 1])
    z, o = np.zeros_like(st), np.ones_like(st)
    return _matrix_from_rows(((z, cp, st * sp), (z, sp, -st * cp), (o, z, ct)))


def krylov_body_rate_matrix(angles) -> np.ndarray:
    """(1-15)': M with ``(p, q, r) = M (δ̇, γ̇, φ̇)``, shape (..., 3, 3).

    ``[[cosγ cosφ, sinφ, 0], [−cosγ sinφ, cosφ, 0], [sinγ, 0, 1]]``; det M = cos γ.
    """
    a = as_vector_array(angles, "Krylov angles")
    sg, cg = np.sin(a[..., 1]), np.cos(a[..., 1])
    sf, cf = np.sin(a[..., 2]), np.cos(a[..., 2])
    z, o = np.zeros_like(sg), np.ones_like(sg)
    return _matrix_from_rows(((cg * cf, sf, z), (-cg * sf, cf, z), (sg, z, o)))


def krylov_body_rate_matrix_small_angle(angles) -> np.ndarray:
    """(1-16): ``[[1, φ, 0], [−φ, 1, 0], [γ, 0, 1]]`` for small Krylov angles."""
    a = as_vector_array(angles, "Krylov angles")
    g, f = a[..., 1], a[..., 2]
    z, o = np.zeros_like(g), np.ones_like(g)
    return _matrix_from_rows(((o, f, z), (-f, o, z), (g, z, o)))
