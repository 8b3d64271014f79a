"""Rotations after seed chapter 1: quaternions, direction-cosine matrices, rotation vectors.

Conventions (see DESIGN.md):

* Quaternions are scalar-last ``(x, y, z, w)`` arrays of shape ``(..., 4)``, as in
  geometry_msgs and ``scipy.spatial.transform.Rotation``. The seed's Rodrigues-Hamilton
  parameters (λ0, λ1, λ2, λ3) are scalar-first: ``q = [λ1, λ2, λ3, λ0]``.
* A quaternion ``q_ab`` and its matrix ``C_ab = quat_as_matrix(q_ab)`` map vectors
  resolved in frame ``b`` into frame ``a``: ``v_a = C_ab v_b`` (active rotation, the same
  as ``Rotation.from_quat(q).as_matrix()``).  The seed's matrix A of (1-4), ``x = A ξ``
  (fixed coordinates to body coordinates), is ``C_bn = C_nbᵀ``.
* Composition is the Hamilton product: ``q_ac = q_ab ⊗ q_bc`` and ``C_ac = C_ab C_bc``
  (seed 1-24: ``A = C B`` applies B first, then C).
* Everything is batched over leading axes and returns new arrays.

Bad input (wrong trailing shape, non-finite values, zero-norm quaternions, matrices
that are not rotations beyond a tolerance) raises ``ValueError`` naming the problem.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "as_quat_array",
    "as_vector_array",
    "as_matrix_array",
    "quat_identity",
    "quat_normalize",
    "quat_canonical",
    "quat_conjugate",
    "quat_inverse",
    "quat_multiply",
    "quat_from_rotvec",
    "quat_as_rotvec",
    "quat_from_matrix",
    "quat_as_matrix",
    "quat_rotate",
    "quat_angle_between",
    "quat_from_seed",
    "quat_as_seed",
    "matrix_from_rotvec",
    "rotvec_from_matrix",
    "skew",
]

# Below this rotation angle sin(θ/2)/θ and θ/sin(θ/2) use their Taylor series: the
# direct quotient loses relative accuracy as θ → 0 (and is 0/0 at θ = 0).
_SMALL_ANGLE = 1e-4


# --------------------------------------------------------------------------- validation
def _as_float_array(x, name: str, trailing: tuple[int, ...]) -> np.ndarray:
    a = np.asarray(x, dtype=np.float64)
    n = len(trailing)
    if a.ndim < n or a.shape[a.ndim - n:] != trailing:
        raise ValueError(
            f"{name} must have shape (..., {', '.join(map(str, trailing))}), got {a.shape}"
        )
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} contains non-finite values (NaN or inf)")
    return a


def as_quat_array(q, name: str = "quaternion") -> np.ndarray:
    """Validate a ``(..., 4)`` scalar-last quaternion array (finite, not normalized)."""
    return _as_float_array(q, name, (4,))


def as_vector_array(v, name: str = "vector") -> np.ndarray:
    """Validate a ``(..., 3)`` finite vector array."""
    return _as_float_array(v, name, (3,))


def as_matrix_array(m, name: str = "matrix") -> np.ndarray:
    """Validate a ``(..., 3, 3)`` finite matrix array (orthogonality is not checked)."""
    return _as_float_array(m, name, (3, 3))


# --------------------------------------------------------------------------- basics
def quat_identity(shape: tuple[int, ...] = ()) -> np.ndarray:
    """Identity quaternions ``[0, 0, 0, 1]`` of shape ``shape + (4,)``."""
    q = np.zeros(tuple(shape) + (4,))
    q[..., 3] = 1.0
    return q


def quat_normalize(q) -> np.ndarray:
    """Unit quaternions; raises ``ValueError`` on a zero-norm (or non-finite) input."""
    q = as_quat_array(q)
    n = np.linalg.norm(q, axis=-1, keepdims=True)
    if np.any(n < 1e-300):
        raise ValueError("quaternion has zero norm and cannot be normalized")
    return q / n


def quat_canonical(q) -> np.ndarray:
    """Choose the sign with ``w >= 0`` (q and −q are the same rotation).

    Ties at ``w == 0`` are broken by the first nonzero of x, y, z being positive, so the
    result is unique for every rotation.
    """
    q = as_quat_array(q)
    sign = np.where(q[..., 3] != 0, np.sign(q[..., 3]), 0.0)
    for k in range(3):
        sign = np.where(sign == 0, np.sign(q[..., k]), sign)
    sign = np.where(sign == 0, 1.0, sign)
    return q * sign[..., None]


def quat_conjugate(q) -> np.ndarray:
    """Conjugate ``[-x, -y, -z, w]`` (the inverse of a unit quaternion)."""
    q = as_quat_array(q)
    return q * np.array([-1.0, -1.0, -1.0, 1.0])


def quat_inverse(q) -> np.ndarray:
    """Inverse ``q* / |q|²``; raises on zero norm."""
    q = as_quat_array(q)
    n2 = np.sum(q * q, axis=-1, keepdims=True)
    if np.any(n2 < 1e-300):
        raise ValueError("quaternion has zero norm and has no inverse")
    return quat_conjugate(q) / n2


def _qmul(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton product without validation (hot path for the integrators)."""
    px, py, pz, pw = p[..., 0], p[..., 1], p[..., 2], p[..., 3]
    qx, qy, qz, qw = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack(
        (
            pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx,
            pw * qz + px * qy - py * qx + pz * qw,
            pw * qw - px * qx - py * qy - pz * qz,
        ),
        axis=-1,
    )


def quat_multiply(p, q) -> np.ndarray:
    """Hamilton product ``p ⊗ q`` (apply q first, then p), broadcasting over ``...``."""
    return _qmul(as_quat_array(p, "p"), as_quat_array(q, "q"))


def skew(v) -> np.ndarray:
    """Cross-product matrix ``[v×]`` with ``[v×] u = v × u``, shape ``(..., 3, 3)``."""
    v = as_vector_array(v)
    z = np.zeros(v.shape[:-1])
    x, y, w = v[..., 0], v[..., 1], v[..., 2]
    return np.stack(
        (
            np.stack((z, -w, y), axis=-1),
            np.stack((w, z, -x), axis=-1),
            np.stack((-y, x, z), axis=-1),
        ),
        axis=-2,
    )


# --------------------------------------------------------------------------- rotation vector
def _exp_rotvec(v: np.ndarray) -> np.ndarray:
    """Exponential map without validation: ``[sin(θ/2) v/θ, cos(θ/2)]``, θ = |v|."""
    theta2 = np.einsum("...i,...i->...", v, v)
    theta = np.sqrt(theta2)
    small = theta < _SMALL_ANGLE
    # Taylor branch: sin(θ/2)/θ = 1/2 − θ²/48 + θ⁴/3840 − …, exact to < 1e-20 here.
    safe = np.where(small, 1.0, theta)
    k = np.where(small, 0.5 - theta2 / 48.0 + theta2 * theta2 / 3840.0, np.sin(0.5 * safe) / safe)
    out = np.empty(v.shape[:-1] + (4,))
    out[..., :3] = v * k[..., None]
    out[..., 3] = np.cos(0.5 * theta)
    return out


def quat_from_rotvec(rotvec) -> np.ndarray:
    """Unit quaternion of the rotation vector ``θ e`` (angle θ in rad about unit axis e).

    Any angle is accepted (θ > π wraps around); small angles use a Taylor branch so that
    1e-12 rad keeps full relative accuracy.
    """
    return _exp_rotvec(as_vector_array(rotvec, "rotvec"))


def _log_quat(q: np.ndarray) -> np.ndarray:
    """Logarithm without validation for unit quaternions: rotation vector, |θ| <= π."""
    # Take the shortest rotation: w >= 0. atan2 keeps full accuracy at both ends,
    # where acos(w) loses half the digits near θ = 0 and asin(|v|) near θ = π.
    q = np.where(q[..., 3:4] < 0, -q, q)
    v = q[..., :3]
    s = np.linalg.norm(v, axis=-1)
    w = q[..., 3]
    theta = 2.0 * np.arctan2(s, w)
    small = theta < _SMALL_ANGLE
    # θ/sin(θ/2) with sin(θ/2) = s/|q|; Taylor branch 2(1 + θ²/24 + 7θ⁴/5760) divided by |q|.
    norm = np.sqrt(s * s + w * w)
    safe_s = np.where(small, 1.0, s)
    k = np.where(
        small,
        (2.0 + theta * theta / 12.0 + 7.0 * theta**4 / 2880.0) / np.where(small, norm, 1.0),
        theta / safe_s,
    )
    return v * k[..., None]


def quat_as_rotvec(q) -> np.ndarray:
    """Rotation vector (angle ≤ π) of a quaternion (normalized first; zero norm raises)."""
    return _log_quat(quat_normalize(q))


def matrix_from_rotvec(rotvec) -> np.ndarray:
    """Direction-cosine matrix of a rotation vector (via the quaternion)."""
    return quat_as_matrix(quat_from_rotvec(rotvec))


def rotvec_from_matrix(matrix, atol: float = 1e-6) -> np.ndarray:
    """Rotation vector of a direction-cosine matrix (Markley branch, then atan2 log)."""
    return _log_quat(quat_from_matrix(matrix, atol=atol))


# --------------------------------------------------------------------------- matrices
def quat_as_matrix(q) -> np.ndarray:
    """Direction-cosine matrix ``C`` with ``v_a = C v_b`` for ``q = q_ab`` (normalized first)."""
    q = quat_normalize(q)
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    xx, yy, zz = x * x, y * y, z * z
    xy, xz, yz = x * y, x * z, y * z
    wx, wy, wz = w * x, w * y, w * z
    return np.stack(
        (
            np.stack((1 - 2 * (yy + zz), 2 * (xy - wz), 2 * (xz + wy)), axis=-1),
            np.stack((2 * (xy + wz), 1 - 2 * (xx + zz), 2 * (yz - wx)), axis=-1),
            np.stack((2 * (xz - wy), 2 * (yz + wx), 1 - 2 * (xx + yy)), axis=-1),
        ),
        axis=-2,
    )


def check_rotation_matrix(matrix, atol: float = 1e-6, name: str = "matrix") -> np.ndarray:
    """Validate ``(..., 3, 3)`` proper rotation matrices: ``CᵀC = I`` and ``det C = +1``.

    These are the orthogonality relations (1-6) of the seed; ``atol`` bounds the largest
    element of ``CᵀC − I``.
    """
    m = as_matrix_array(matrix, name)
    if m.size == 0:
        return m
    err = np.abs(np.swapaxes(m, -1, -2) @ m - np.eye(3)).max(axis=(-2, -1))
    if np.any(err > atol):
        raise ValueError(
            f"{name} is not orthogonal: max |CᵀC − I| = {float(np.max(err)):.3g} > atol={atol:g}"
        )
    if np.any(np.linalg.det(m) < 0):
        raise ValueError(f"{name} is a reflection (det = -1), not a rotation")
    return m


def quat_from_matrix(matrix, atol: float = 1e-6) -> np.ndarray:
    """Unit quaternion (``w >= 0``) of a direction-cosine matrix.

    Shepperd/Markley: compute the quaternion from whichever of (C11, C22, C33, trace) is
    largest, so the divisor is never small — the trace-only formula fails near 180°.
    A slightly non-orthogonal input (within ``atol``) gets the nearest quaternion.
    """
    m = check_rotation_matrix(matrix, atol=atol)
    c = m
    tr = c[..., 0, 0] + c[..., 1, 1] + c[..., 2, 2]
    cand = np.stack((c[..., 0, 0], c[..., 1, 1], c[..., 2, 2], tr), axis=-1)
    choice = np.argmax(cand, axis=-1)
    q = np.empty(m.shape[:-2] + (4,))
    # Each branch: 4·q_k² = 1 + 2·C_kk − tr (or 1 + tr for w); the others follow from
    # symmetric/antisymmetric parts divided by the large 4·q_k.
    for k in range(3):
        i, j, l = k, (k + 1) % 3, (k + 2) % 3
        sel = choice == k
        if not np.any(sel):
            continue
        cs = c[sel]
        qk = np.empty(cs.shape[:-2] + (4,))
        qk[..., i] = 1.0 + 2.0 * cs[..., i, i] - (cs[..., 0, 0] + cs[..., 1, 1] + cs[..., 2, 2])
        qk[..., j] = cs[..., j, i] + cs[..., i, j]
        qk[..., l] = cs[..., l, i] + cs[..., i, l]
        qk[..., 3] = cs[..., l, j] - cs[..., j, l]
        q[sel] = qk
    sel = choice == 3
    if np.any(sel):
        cs = c[sel]
        qk = np.empty(cs.shape[:-2] + (4,))
        qk[..., 0] = cs[..., 2, 1] - cs[..., 1, 2]
        qk[..., 1] = cs[..., 0, 2] - cs[..., 2, 0]
        qk[..., 2] = cs[..., 1, 0] - cs[..., 0, 1]
        qk[..., 3] = 1.0 + cs[..., 0, 0] + cs[..., 1, 1] + cs[..., 2, 2]
        q[sel] = qk
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(q[..., 3:4] < 0, -q, q)


# --------------------------------------------------------------------------- vectors, errors
def quat_rotate(q, v) -> np.ndarray:
    """Rotate vectors: ``C(q) v`` (for ``q = q_ab``: b-frame vector into frame a)."""
    q = quat_normalize(q)
    v = as_vector_array(v)
    u = q[..., :3]
    w = q[..., 3:4]
    # v' = v + 2w (u×v) + 2 u×(u×v): two cross products, cheaper than building C.
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def quat_angle_between(q1, q2) -> np.ndarray:
    """Attitude-error angle in rad between two attitudes, in [0, π].

    ``2·atan2(|v|, |w|)`` of ``q1⁻¹ ⊗ q2``: immune to the q/−q sign and accurate at both
    tiny and near-π errors.
    """
    d = _qmul(quat_conjugate(quat_normalize(q1)), quat_normalize(q2))
    return 2.0 * np.arctan2(np.linalg.norm(d[..., :3], axis=-1), np.abs(d[..., 3]))


# --------------------------------------------------------------------------- seed order
def quat_from_seed(lam) -> np.ndarray:
    """Scalar-last quaternion from the seed's scalar-first (λ0, λ1, λ2, λ3) (§1-5)."""
    lam = as_quat_array(lam, "Rodrigues-Hamilton parameters")
    return np.concatenate((lam[..., 1:], lam[..., :1]), axis=-1)


def quat_as_seed(q) -> np.ndarray:
    """The seed's scalar-first Rodrigues-Hamilton parameters (λ0, λ1, λ2, λ3) of ``q``."""
    q = as_quat_array(q)
    return np.concatenate((q[..., 3:], q[..., :3]), axis=-1)
