"""Rotation algebra: quaternions, direction-cosine matrices, rotation vectors, attitude error.

Conventions (``docs/conventions.md``):

* Quaternions are scalar-last ``(x, y, z, w)`` arrays of shape ``(..., 4)``, as in
  geometry_msgs and ``scipy.spatial.transform.Rotation``.
* A quaternion ``q_ab`` and its matrix ``C_ab = quat_as_matrix(q_ab)`` map vectors
  resolved in frame ``b`` into frame ``a``: ``v_a = C_ab v_b`` (active rotation, the same
  as ``Rotation.from_quat(q).as_matrix()``).
* Composition is the Hamilton product: ``q_ac = q_ab ⊗ q_bc`` and ``C_ac = C_ab C_bc``.
* Everything is batched over leading axes and returns new arrays.
* The textbook's chapter-1 forms (matrix A with passive R1/R2/R3, Euler z-x-z and Krylov
  x-y-z angles, kinematic equations, Rodrigues–Hamilton parameters) are in
  :mod:`gyro_attitude.core.euler_kinematics`.

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
    "matrix_from_rotvec",
    "rotvec_from_matrix",
    "skew",
    "check_rotation_matrix",
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
    # sqrt of the sum of squares: same result as np.linalg.norm (no overflow risk for
    # quaternion-sized numbers) at a third of its per-call overhead.
    n = np.sqrt(np.sum(q * q, axis=-1, keepdims=True))
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
    # Filling a preallocated array is about twice as fast as np.stack of the four parts.
    out = np.empty(np.broadcast_shapes(p.shape, q.shape))
    out[..., 0] = pw * qx + px * qw + py * qz - pz * qy
    out[..., 1] = pw * qy - px * qz + py * qw + pz * qx
    out[..., 2] = pw * qz + px * qy - py * qx + pz * qw
    out[..., 3] = pw * qw - px * qx - py * qy - pz * qz
    return out


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
    # Only the branch that some element takes is evaluated (a sensor's increments are
    # usually all small, a coarse step all large): the same values as np.where of both.
    if small.all():
        k = 0.5 - theta2 / 48.0 + theta2 * theta2 / 3840.0
    elif not small.any():
        k = np.sin(0.5 * theta) / theta
    else:
        safe = np.where(small, 1.0, theta)
        k = np.where(small, 0.5 - theta2 / 48.0 + theta2 * theta2 / 3840.0,
                     np.sin(0.5 * safe) / safe)
    out = np.empty(v.shape[:-1] + (4,))
    # written in place: no (M, 3) temporary
    np.multiply(v, k[..., None], out=out[..., :3])
    np.cos(0.5 * theta, out=out[..., 3])
    return out


def quat_from_rotvec(rotvec) -> np.ndarray:
    """Unit quaternion of the rotation vector ``θ e`` (angle θ in rad about unit axis e).

    Any angle is accepted (θ > π wraps around); small angles use a Taylor branch so that
    1e-12 rad keeps full relative accuracy.
    """
    return _exp_rotvec(as_vector_array(rotvec, "rotvec"))


def _log_quat(q: np.ndarray) -> np.ndarray:
    """Logarithm without validation: rotation vector, |θ| <= π, of a quaternion of any
    nonzero norm (the angle from atan2 and the axis v/|v| do not depend on it)."""
    # The shortest rotation: that of ±q with w >= 0 (its sign applied to k at the end, one
    # 1-D pass instead of flipping q). atan2 keeps full accuracy at both ends, where acos(w)
    # loses half the digits near θ = 0 and asin(|v|) near θ = π.
    v = q[..., :3]
    w = q[..., 3]
    s = np.sqrt(np.einsum("...i,...i->...", v, v))
    theta = 2.0 * np.arctan2(s, np.abs(w))
    small = theta < _SMALL_ANGLE
    # θ/sin(θ/2) with sin(θ/2) = s/|q|; Taylor branch 2(1 + θ²/24 + 7θ⁴/5760) divided by |q|
    # (evaluated only when some element takes it).
    if small.all():
        k = (2.0 + theta * theta / 12.0 + 7.0 * theta**4 / 2880.0) / np.sqrt(s * s + w * w)
    elif small.any():
        norm = np.sqrt(s * s + w * w)
        safe_s = np.where(small, 1.0, s)
        k = np.where(
            small,
            (2.0 + theta * theta / 12.0 + 7.0 * theta**4 / 2880.0) / np.where(small, norm, 1.0),
            theta / safe_s,
        )
    else:
        k = theta / s
    k = np.where(w < 0, -k, k)
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
    c = np.empty(q.shape[:-1] + (3, 3))
    c[..., 0, 0] = 1 - 2 * (yy + zz)
    c[..., 0, 1] = 2 * (xy - wz)
    c[..., 0, 2] = 2 * (xz + wy)
    c[..., 1, 0] = 2 * (xy + wz)
    c[..., 1, 1] = 1 - 2 * (xx + zz)
    c[..., 1, 2] = 2 * (yz - wx)
    c[..., 2, 0] = 2 * (xz - wy)
    c[..., 2, 1] = 2 * (yz + wx)
    c[..., 2, 2] = 1 - 2 * (xx + yy)
    return c


def check_rotation_matrix(matrix, atol: float = 1e-6, name: str = "matrix") -> np.ndarray:
    """Validate ``(..., 3, 3)`` proper rotation matrices: ``CᵀC = I`` and ``det C = +1``.

    These are the orthogonality relations (1-6) of the textbook; ``atol`` bounds the largest
    element of ``CᵀC − I``.
    """
    m = as_matrix_array(matrix, name)
    if m.size == 0:
        return m
    c0, c1, c2 = m[..., :, 0], m[..., :, 1], m[..., :, 2]
    # The six distinct entries of CᵀC, written out: batched 3×3 matmul and
    # np.linalg.det cost ~10× more per matrix than these element-wise products.
    gram = (
        np.sum(c0 * c0, axis=-1) - 1.0,
        np.sum(c1 * c1, axis=-1) - 1.0,
        np.sum(c2 * c2, axis=-1) - 1.0,
        np.sum(c0 * c1, axis=-1),
        np.sum(c0 * c2, axis=-1),
        np.sum(c1 * c2, axis=-1),
    )
    err = np.max(np.abs(np.stack(gram)))
    if err > atol:
        raise ValueError(f"{name} is not orthogonal: max |CᵀC − I| = {float(err):.3g} > atol={atol:g}")
    # det C = c0 · (c1 × c2); orthogonal input has det = ±1, so the sign decides.
    det = (
        c0[..., 0] * (c1[..., 1] * c2[..., 2] - c1[..., 2] * c2[..., 1])
        - c0[..., 1] * (c1[..., 0] * c2[..., 2] - c1[..., 2] * c2[..., 0])
        + c0[..., 2] * (c1[..., 0] * c2[..., 1] - c1[..., 1] * c2[..., 0])
    )
    if np.any(det < 0):
        raise ValueError(f"{name} is a reflection (det = -1), not a rotation")
    return m


def quat_from_matrix(matrix, atol: float = 1e-6) -> np.ndarray:
    """Unit quaternion (``w >= 0``) of a direction-cosine matrix.

    Shepperd/Markley: compute the quaternion from whichever of (C11, C22, C33, trace) is
    largest, so the divisor is never small — the trace-only formula fails near 180°.
    A slightly non-orthogonal input (within ``atol``) gets the nearest quaternion.
    """
    c = check_rotation_matrix(matrix, atol=atol)
    c00, c01, c02 = c[..., 0, 0], c[..., 0, 1], c[..., 0, 2]
    c10, c11, c12 = c[..., 1, 0], c[..., 1, 1], c[..., 1, 2]
    c20, c21, c22 = c[..., 2, 0], c[..., 2, 1], c[..., 2, 2]
    tr = c00 + c11 + c22
    # k[..., i, j] = 4 q_i q_j (x, y, z, w order): the diagonal is 1 + 2 C_ii − tr and
    # 1 + tr, the rest come from the symmetric and antisymmetric parts of C.  Row i is
    # 4 q_i · q, so normalising the row with the largest diagonal gives ±q with a divisor
    # of at least 1 (4 q_i² >= 1 for the largest) — all four rows are built and one is
    # picked per matrix, which vectorises better than masked branches.
    k = np.empty(c.shape[:-2] + (4, 4))
    k[..., 0, 0] = 1.0 + 2.0 * c00 - tr
    k[..., 1, 1] = 1.0 + 2.0 * c11 - tr
    k[..., 2, 2] = 1.0 + 2.0 * c22 - tr
    k[..., 3, 3] = 1.0 + tr
    k[..., 0, 1] = k[..., 1, 0] = c10 + c01
    k[..., 0, 2] = k[..., 2, 0] = c20 + c02
    k[..., 1, 2] = k[..., 2, 1] = c21 + c12
    k[..., 0, 3] = k[..., 3, 0] = c21 - c12
    k[..., 1, 3] = k[..., 3, 1] = c02 - c20
    k[..., 2, 3] = k[..., 3, 2] = c10 - c01
    choice = np.argmax(np.diagonal(k, axis1=-2, axis2=-1), axis=-1)
    q = np.take_along_axis(k, choice[..., None, None], axis=-2)[..., 0, :]
    q /= np.sqrt(np.sum(q * q, axis=-1, keepdims=True))
    return np.where(q[..., 3:4] < 0, -q, q)


# --------------------------------------------------------------------------- vectors, errors
def quat_rotate(q, v) -> np.ndarray:
    """Rotate vectors: ``C(q) v`` (for ``q = q_ab``: b-frame vector into frame a)."""
    return _qrot(quat_normalize(q), as_vector_array(v))


def _qrot(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``C(q) v`` for unit quaternions, without validation (hot path of the offline passes)."""
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    vx, vy, vz = v[..., 0], v[..., 1], v[..., 2]
    # v' = v + w t + u × t with t = 2 u × v: two cross products, cheaper than building
    # C; written out because np.cross has large per-call overhead on small arrays.
    tx = 2.0 * (y * vz - z * vy)
    ty = 2.0 * (z * vx - x * vz)
    tz = 2.0 * (x * vy - y * vx)
    out = np.empty(np.broadcast_shapes(q.shape[:-1], v.shape[:-1]) + (3,))
    out[..., 0] = vx + w * tx + (y * tz - z * ty)
    out[..., 1] = vy + w * ty + (z * tx - x * tz)
    out[..., 2] = vz + w * tz + (x * ty - y * tx)
    return out


def quat_angle_between(q1, q2) -> np.ndarray:
    """Attitude-error angle in rad between two attitudes, in [0, π].

    ``2·atan2(|v|, |w|)`` of ``q1⁻¹ ⊗ q2``: immune to the q/−q sign and accurate at both
    tiny and near-π errors.
    """
    d = _qmul(quat_conjugate(quat_normalize(q1)), quat_normalize(q2))
    return 2.0 * np.arctan2(np.linalg.norm(d[..., :3], axis=-1), np.abs(d[..., 3]))
