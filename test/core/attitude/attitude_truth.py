"""Truth for the attitude tests: closed forms of docs/equations.md, scipy oracles and written-out
formulas — never the code under test."""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp
from scipy.spatial.transform import Rotation

from gyro_attitude.core.attitude import ALGORITHMS

Q0 = np.array([0.2, 0.1, -0.3, 0.9]) / np.linalg.norm([0.2, 0.1, -0.3, 0.9])


def angle_between(q1, q2):
    """Attitude error in rad, computed with scipy (independent of rotation.py)."""
    r = Rotation.from_quat(np.atleast_2d(q1)).inv() * Rotation.from_quat(np.atleast_2d(q2))
    return np.linalg.norm(r.as_rotvec(), axis=-1)


def coning_truth(alpha, omega_c, t):
    """docs/equations.md classical coning, converted to scalar-last: attitude and body rate."""
    s, c = math.sin(alpha / 2), math.cos(alpha / 2)
    q = np.stack([np.zeros_like(t), s * np.cos(omega_c * t), s * np.sin(omega_c * t),
                  np.full_like(t, c)], axis=-1)
    w = np.stack([np.full_like(t, -2 * omega_c * s * s),
                  -omega_c * math.sin(alpha) * np.sin(omega_c * t),
                  omega_c * math.sin(alpha) * np.cos(omega_c * t)], axis=-1)
    return q, w


def coning_increments(alpha, omega_c, t):
    """docs/equations.md exact coning angle increments over [t_k, t_{k+1}]."""
    h = np.diff(t)
    tm = t[:-1] + h / 2
    s2 = math.sin(alpha / 2) ** 2
    sa = math.sin(alpha)
    return np.stack([-2 * omega_c * h * s2,
                     -2 * sa * np.sin(omega_c * h / 2) * np.sin(omega_c * tm),
                     2 * sa * np.sin(omega_c * h / 2) * np.cos(omega_c * tm)], axis=-1)


def spinning_coning_truth(alpha, omega_c, spin, t):
    """Spin ``spin`` rad/s about body x, the axis that cones in docs/equations.md's coning case
    (a projectile): ``q = q_cone(t) ⊗ exp(spin t x)``, ``ω_b = C_spinᵀ ω_cone + spin x``
    (composed with scipy)."""
    q_cone, w_cone = coning_truth(alpha, omega_c, t)
    r_spin = Rotation.from_rotvec(np.outer(spin * t, [1.0, 0.0, 0.0]))
    q = (Rotation.from_quat(q_cone) * r_spin).as_quat()
    w = r_spin.inv().apply(w_cone)
    w[:, 0] += spin
    return q, w


# Smooth "random" motion: sums of sinusoids with analytic integrals.
_A = np.array([[1.1, 0.7, -0.4], [0.5, -0.9, 0.8], [-0.6, 0.4, 1.3]])
_F = np.array([[1.3, 2.1, 0.7], [1.7, 0.9, 2.6], [0.8, 1.9, 1.1]]) * 2 * np.pi / 4
_P = np.array([[0.3, 1.1, 2.0], [0.7, 0.2, 1.5], [1.9, 0.4, 0.9]])


def smooth_rate(t, scale=1.0):
    t = np.asarray(t)[..., None, None]
    return scale * (_A * np.sin(_F * t + _P)).sum(-1)


def smooth_increments(t0, t1, scale=1.0):
    a, b = t0[..., None, None], t1[..., None, None]
    return scale * (_A * (np.cos(_F * a + _P) - np.cos(_F * b + _P)) / _F).sum(-1)


def _qmul_ref(p, q):
    """Hamilton product written out here (not the package's) for the ODE right-hand side."""
    px, py, pz, pw = p
    qx, qy, qz, qw = q
    return np.array([pw * qx + px * qw + py * qz - pz * qy,
                     pw * qy - px * qz + py * qw + pz * qx,
                     pw * qz + px * qy - py * qx + pz * qw,
                     pw * qw - px * qx - py * qy - pz * qz])


def ode_truth(q0, t_eval, scale=1.0):
    """``q̇ = ½ q ⊗ ω`` for :func:`smooth_rate` by scipy DOP853 (rtol 1e-13)."""
    def f(t, q):
        return 0.5 * _qmul_ref(q, np.append(smooth_rate(t, scale), 0.0))

    sol = solve_ivp(f, (t_eval[0], t_eval[-1]), q0, method="DOP853", rtol=1e-13,
                    atol=1e-14, t_eval=t_eval)
    q = sol.y.T
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def uniform_times(n_steps, duration_s):
    step = int(round(duration_s * 1e9 / n_steps))
    return np.arange(n_steps + 1, dtype=np.int64) * step


# docs/equations.md "Conventions", written out here so the nav-frame tests do not take ω_in^n from
# the code under test (earth.nav_rate_enu).
_OMEGA_IE = 7.292115e-5
_A_WGS84 = 6378137.0
_F_WGS84 = 1.0 / 298.257223563
_E2 = _F_WGS84 * (2.0 - _F_WGS84)


def nav_rate_written_out(lat, h, v_enu):
    """``ω_ie^n + ω_en^n`` in ENU: ``[0, Ω cos L, Ω sin L] + [−v_N/(R_M+h), v_E/(R_N+h),
    v_E tan L/(R_N+h)]`` with ``R_M = a(1−e²)/(1−e² sin²L)^1.5``, ``R_N = a/(1−e² sin²L)^0.5``."""
    lat = np.asarray(lat, dtype=float)
    h = np.asarray(h, dtype=float)
    v = np.asarray(v_enu, dtype=float)
    s2 = np.sin(lat) ** 2
    r_m = _A_WGS84 * (1 - _E2) / (1 - _E2 * s2) ** 1.5
    r_n = _A_WGS84 / (1 - _E2 * s2) ** 0.5
    ve, vn = v[..., 0], v[..., 1]
    return np.stack((-vn / (r_m + h),
                     _OMEGA_IE * np.cos(lat) + ve / (r_n + h),
                     _OMEGA_IE * np.sin(lat) + ve * np.tan(lat) / (r_n + h)), axis=-1)


# Algorithm groups the tests parametrize over (what each algorithm declares of itself).
RATE_ALGS = [a for a, i in ALGORITHMS.items() if i.consumes == "rate"]
INCR_ALGS = [a for a, i in ALGORITHMS.items() if i.consumes == "increment"]
QUAT_RATE_ALGS = [a for a in RATE_ALGS if not ALGORITHMS[a].sequential]
CAUSAL_QUAT_RATE_ALGS = [a for a in QUAT_RATE_ALGS if ALGORITHMS[a].causal]

# A moving carrier for the nav-frame tests: latitude [rad], height [m], velocities ENU [m/s].
NAV_LAT, NAV_H = 0.87, 3000.0
NAV_VELS = [(120.0, 0.0, 0.0), (84.9, 84.9, 1.0), (0.0, 120.0, -2.0)]
