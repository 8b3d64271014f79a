"""A motion along the user's own poses: checked pose series, smoothing splines, Earth-fixed tangent frame.

Poses ``(t, p_t, q_tb)`` give the body's position and attitude in an Earth-fixed local ENU
frame ``t`` (the tangent frame at the scene's origin ``earth.latitude_deg/longitude_deg/
height_m``), ``q_tb`` mapping body vectors into ``t`` (scalar-last, as TUM files and ROS
write it). :func:`check_poses` refuses what cannot be differentiated (unsorted, repeated
or non-finite stamps, non-unit quaternions, a single pose, gaps longer than ``max_gap_s``),
naming the line or message. :class:`TrajectoryMotion` fits

- the position by a cubic smoothing spline (Reinsch: minimises Σ|p_i − g(t_i)|² +
  λ∫|g''|², λ chosen so the residual is the expected pose noise, Σ|p_i − g(t_i)|² =
  3 n σ_p², the discrepancy principle; ``position_sigma_m = 0`` interpolates, not-a-knot);
- the attitude by the same spline of the sign-continuous unit quaternions in R⁴ (residual
  target n · 3σ_θ²/4: a small rotation error δθ moves the unit quaternion by |δθ|/2),
  projected back onto the unit sphere, q(t) = s(t)/|s(t)|; the projection makes the fit a
  curve on the rotation group whatever the components do, and its exact derivative gives the
  body rate ``ω_tb^b = 2 vec(s* ⊗ ṡ)/|s|²`` (the radial part of ṡ drops out).

Body rate, velocity and acceleration come from the splines' analytic derivatives, not from
differences of the poses, so pose noise is not amplified by 1/Δt. The sensors see
(:meth:`TrajectoryMotion.imu`)::

    gyro:           ω_ib^b = ω_tb^b + C_bt ω_ie^t
    accelerometer:  f^b    = C_bt (a^t + 2 ω_ie^t × v^t − g^t(p))

with ``ω_ie^t`` the Earth rate in the tangent frame and ``g^t(p)`` normal gravity at the
actual position (its local vertical tilts against the tangent frame's up by the distance
travelled over the Earth's radius: 1.6e-4 rad per km), so trajectories of tens of km stay
right. Truth in the local-level ENU frame ``n`` at the actual position (what the package's
truth topics carry) follows from ``C_nt`` (:meth:`TrajectoryMotion.evaluate`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from gyro_attitude.core import earth, limits
from gyro_attitude.core.motion import Motion, MotionSample

if TYPE_CHECKING:
    from scipy.interpolate import PPoly

__all__ = [
    "PoseSeries",
    "check_poses",
    "check_positions",
    "smoothing_spline",
    "spline_coefficients",
    "reinsch_smooth",
    "TangentSample",
    "TrajectorySample",
    "TrajectoryMotion",
    "TrajectoryRequest",
    "LiveTrajectory",
    "TRAJECTORY_FORMATS",
    "DEFAULT_MAX_GAP_S",
    "UNIT_QUATERNION_TOLERANCE",
]

#: Times this close outside the poses (s) are taken at the end pose: a finite-difference step
#: of a consumer (the free gyro's base acceleration, 1e-5 s) may reach past the ends.
EDGE_S = 1e-3
#: IMU samples per pass of the evaluation (and poses per pass of the position check): the
#: pass's ~100 temporaries of this many doubles stay in the processor's L2 cache and are
#: reused by the allocator (a longer pass streams them through memory and page faults).
EVAL_CHUNK = 8192
#: Windows on which the smoothing parameter is searched (module docstring).
LAMBDA_WINDOWS = 8
LAMBDA_WINDOW = 1000
#: Pose inputs: TUM text, CSV with a header, a rosbag2 MCAP topic.
TRAJECTORY_FORMATS = ("tum", "csv", "mcap")
#: Longest gap between consecutive poses (s) a fit bridges by default: a motion-capture
#: dropout of a few frames is bridged; minutes are refused (split the file, or raise it).
DEFAULT_MAX_GAP_S = 1.0
#: Largest | |q| − 1 | accepted: files carry 6–9 digits, 1e-3 refuses a wrong column order
#: or a degree/radian mix-up and accepts rounding.
UNIT_QUATERNION_TOLERANCE = 1e-3


@dataclass(frozen=True)
class PoseSeries:
    """Poses read from a file or topic: stamps ``t_ns (n,)`` int64, positions ``p (n,3)`` m
    in the tangent frame, ``q (n,4)`` scalar-last ``q_tb``; ``labels`` names each row for
    error messages (``"line 12"``, ``"message 7"``); ``source`` names the input."""

    t_ns: np.ndarray
    p: np.ndarray
    q: np.ndarray
    labels: tuple[str, ...]
    source: str = "poses"


def _seconds(ns) -> str:
    """An int-ns stamp as exact decimal seconds (a float would round epoch stamps)."""
    ns = int(ns)
    sign = "-" if ns < 0 else ""
    return f"{sign}{abs(ns) // 10**9}.{abs(ns) % 10**9:09d}"


def check_poses(poses: PoseSeries, max_gap_s: float = DEFAULT_MAX_GAP_S) -> PoseSeries:
    """``poses`` with quaternions normalized, or ``ValueError`` naming the first bad row."""
    t, p, q, lab = poses.t_ns, poses.p, poses.q, poses.labels
    n = t.shape[0]
    src = poses.source
    if n < 2:
        raise ValueError(f"{src}: {n} pose{'s' if n != 1 else ''}; a trajectory needs at least "
                         "2 (4 or more for a cubic fit)")
    if p.shape != (n, 3) or q.shape != (n, 4) or len(lab) != n:
        raise ValueError(f"{src}: poses must be (n,3) positions and (n,4) quaternions")
    if not np.isfinite(p).all():
        bad = ~np.all(np.isfinite(p), axis=1)
        raise ValueError(f"{src}: {lab[int(np.argmax(bad))]}: position is not finite")
    qx, qy, qz, qw = q.T  # component by component: numpy's reductions over rows of 4 are slow
    with np.errstate(over="ignore"):  # a 1e300 component: |q| = inf, refused below
        norm = np.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
    bad = ~np.isfinite(norm) | (np.abs(norm - 1.0) > UNIT_QUATERNION_TOLERANCE)
    if bad.any():
        i = int(np.argmax(bad))
        raise ValueError(f"{src}: {lab[i]}: quaternion {q[i].tolist()} is not a unit "
                         f"quaternion (|q| = {norm[i]:.6g}; expected qx qy qz qw, scalar last)")
    dt = np.diff(t)
    bad = dt <= 0
    if bad.any():
        i = int(np.argmax(bad)) + 1
        what = "repeats" if dt[i - 1] == 0 else "goes back from"
        raise ValueError(f"{src}: {lab[i]}: timestamp {_seconds(t[i])} s {what} the previous "
                         f"one ({_seconds(t[i - 1])} s); poses must be in strictly increasing "
                         "time")
    gap = dt > max_gap_s * 1e9
    if gap.any():
        i = int(np.argmax(gap)) + 1
        raise ValueError(f"{src}: {lab[i]}: gap of {dt[i - 1] / 1e9:.6g} s after the previous "
                         f"pose (at {_seconds(t[i - 1])} s) is longer than max_gap_s = "
                         f"{max_gap_s:g} s; a fit cannot bridge it: split the file or raise "
                         "motion.max_gap_s")
    # pose to pose faster than any carrier: a glitch (squared lengths: a 1e300 m step
    # overflows to inf, which is refused too; hypot for the message)
    dx, dy, dz = np.diff(p, axis=0).T
    reach = limits.MAX_SPEED_MPS * (dt / 1e9)
    with np.errstate(over="ignore"):
        bad = dx * dx + dy * dy + dz * dz > reach * reach
    if bad.any():
        i = int(np.argmax(bad)) + 1
        step = math.hypot(dx[i - 1], dy[i - 1], dz[i - 1])
        raise ValueError(f"{src}: {lab[i]}: {_too_fast(step, dt[i - 1] / 1e9)}")
    q = q / norm[:, None]
    # pose to pose a turn faster than any motion may spin: a glitch or a re-sent pose a few
    # ns after the original (0.1° in 1 ns would be a 1.7e6 rad/s gyro); |q·q'|: q ≡ −q
    qx, qy, qz, qw = q.T
    turn = _turn_angle(np.abs(qx[1:] * qx[:-1] + qy[1:] * qy[:-1] + qz[1:] * qz[:-1]
                              + qw[1:] * qw[:-1]))
    bad = turn > limits.MAX_BODY_RATE_RAD_S * (dt / 1e9)
    if bad.any():
        i = int(np.argmax(bad)) + 1
        raise ValueError(f"{src}: {lab[i]}: {_too_quick_turn(turn[i - 1], dt[i - 1] / 1e9)}")
    return PoseSeries(t, p, q, lab, src)


def _turn_angle(dot):
    """Rotation angle (rad) between unit quaternions of ``|q · q'|`` = ``dot``."""
    dot = np.minimum(dot, 1.0)
    return 2.0 * np.arctan2(np.sqrt(1.0 - dot * dot), dot)


def _too_quick_turn(angle: float, dt: float) -> str:
    return (f"turned {math.degrees(angle):.6g}° in {dt:.6g} s ({angle / dt:.6g} rad/s) since "
            f"the previous pose, faster than {limits.MAX_BODY_RATE_RAD_S:.6g} rad/s (the "
            "fastest rotation of a scene): a glitch or a repeated pose?")


def _too_fast(step: float, dt: float) -> str:
    return (f"moved {step:.6g} m in {dt:.6g} s ({step / dt:.6g} m/s) since the previous pose, "
            f"faster than {limits.MAX_SPEED_MPS:g} m/s (a scene's fastest carrier): a "
            "glitch in the poses?")


def _position_refusal(p, lat: float, h: float) -> str | None:
    """Why a position (ENU ``p``, geodetic ``lat``, ``h``) is refused, or None."""
    if not limits.MIN_HEIGHT_M <= h <= limits.MAX_HEIGHT_M:
        return (f"position {list(map(float, p))} m has a height of {h:.6g} m, outside the "
                f"scene's {limits.MIN_HEIGHT_M:g} … {limits.MAX_HEIGHT_M:g} m (positions are ENU "
                "at the scene's earth origin)")
    if abs(lat) >= 0.5 * np.pi - limits.POLE_MARGIN_RAD:
        return (f"the trajectory reaches the {'North' if lat > 0 else 'South'} pole (latitude "
                f"{math.degrees(lat):.6f}°): the local-level frame has no East or North "
                "there, so a scene cannot pass over one")
    return None


def check_positions(poses: PoseSeries, origin_llh) -> None:
    """``ValueError`` naming the first pose whose position (ENU at ``origin_llh``) lies
    outside a scene's heights or within ``POLE_MARGIN_RAD`` of a pole, as built-in motions
    are refused: the normal-gravity model holds near the Earth only, and the local-level
    truth frame has no East or North at a pole."""
    origin = np.asarray(origin_llh, dtype=np.float64)
    r0 = earth.ecef_from_llh(origin)
    c_et = earth.enu_to_ecef_matrix(origin[0], origin[1])
    pt = poses.p.T
    for lo in range(0, pt.shape[1], EVAL_CHUNK):  # chunks: as the evaluation (EVAL_CHUNK)
        with np.errstate(over="ignore"):
            x, y, z = _ecef(r0, c_et, pt[:, lo:lo + EVAL_CHUNK])
        lat, h = _latitude_height(x, y, z)
        bad = ~((h >= limits.MIN_HEIGHT_M) & (h <= limits.MAX_HEIGHT_M)
                & (np.abs(lat) < 0.5 * np.pi - limits.POLE_MARGIN_RAD))
        if bad.any():
            i = int(np.argmax(bad))
            raise ValueError(f"{poses.source}: {poses.labels[lo + i]}: "
                             f"{_position_refusal(pt[:, lo + i], float(lat[i]), float(h[i]))}")


def _latitude_height(x, y, z):
    """Geodetic latitude and height of ECEF ``x, y, z`` for the position checks; a position
    too far out for :func:`~gyro_attitude.core.earth.geodetic_from_ecef`'s squares
    (~1e145 m) gets its distance as the height (refused: above any scene) and no warning."""
    with np.errstate(over="ignore", invalid="ignore"):
        lat, _, h, _, _ = earth.geodetic_from_ecef(x, y, z)
    far = ~np.isfinite(h)
    if np.any(far):
        h = np.where(far, np.hypot(np.hypot(x, y), z), h)
    return lat, h


def _ecef(r0, c_et, p):
    """ECEF components ``x, y, z`` of tangent-frame positions ``p = (east, north, up)``
    (arrays) for the frame's origin ``r0`` and its ``C_et``: scalar times array, component
    by component (an (n,3) @ (3,3) product goes to BLAS, whose threads cost more than the
    product on a shared 2-core machine)."""
    return tuple(r0[k] + (c_et[k, 0] * p[0] + c_et[k, 1] * p[1] + c_et[k, 2] * p[2])
                 for k in range(3))


# --------------------------------------------------------------------------- splines
# The fit works on components in rows, y (k, n): each component's knots are contiguous, and
# y.T is the Fortran-ordered (n, k) right-hand side LAPACK takes without a copy.
def _reinsch_parts(t: np.ndarray):
    """Band entries of Q (n × n−2, columns a, b, c) and R (tridiagonal) of Reinsch's
    algorithm (Green & Silverman 1994, §2.3) for knots ``t``."""
    h = np.diff(t)
    a = 1.0 / h[:-1]
    c = 1.0 / h[1:]
    b = -a - c
    r_diag = (h[:-1] + h[1:]) / 3.0
    r_off = h[1:-1] / 6.0
    return a, b, c, r_diag, r_off


def _q_times(a, b, c, gamma: np.ndarray) -> np.ndarray:
    """Q γ, shape (k, n), for γ (k, n−2)."""
    m = gamma.shape[1]
    out = np.zeros((gamma.shape[0], m + 2))
    out[:, :m] += a * gamma
    out[:, 1:m + 1] += b * gamma
    out[:, 2:] += c * gamma
    return out


def _pentadiagonal(r_diag, r_off, qq0, qq1, qq2, lam: float) -> np.ndarray:
    """R + λ QᵀQ in ``solveh_banded``'s upper form."""
    ab = np.zeros((3, r_diag.shape[0]))
    ab[2] = r_diag + lam * qq0
    ab[1, 1:] = r_off + lam * qq1
    ab[0, 2:] = lam * qq2
    return ab


class _Reinsch:
    """Reinsch's banded system for knots ``t`` and data ``y (k, n)``: :meth:`residual`
    ``y − g`` of the smoothing spline with parameter λ (one pentadiagonal solve, O(n))."""

    def __init__(self, t: np.ndarray, y: np.ndarray):
        self.size = t.shape[0]
        self.a, self.b, self.c, self.r_diag, self.r_off = _reinsch_parts(t)
        a, b, c = self.a, self.b, self.c
        self.qty = a * y[:, :-2] + b * y[:, 1:-1] + c * y[:, 2:]
        # QᵀQ bands (pentadiagonal, symmetric)
        self.qq0 = a * a + b * b + c * c
        self.qq1 = b[:-1] * a[1:] + c[:-1] * b[1:]
        self.qq2 = c[:-2] * a[2:]

    def second_derivatives(self, lam: float) -> np.ndarray:
        """γ (k, n−2): the smoothing spline's second derivatives at the inner knots."""
        from scipy.linalg import solveh_banded  # (imported where used: see sensor_errors)

        ab = _pentadiagonal(self.r_diag, self.r_off, self.qq0, self.qq1, self.qq2, lam)
        return solveh_banded(ab, self.qty.T, check_finite=False).T

    def residual(self, lam: float, gamma: np.ndarray | None = None) -> np.ndarray:
        if gamma is None:
            gamma = self.second_derivatives(lam)
        return lam * _q_times(self.a, self.b, self.c, gamma)


class _StackedReinsch:
    """The Reinsch systems of windows of ``size`` knots starting at the knots ``starts`` of
    ``system``, solved as one block-banded system (no coupling between the blocks): one
    LAPACK call per λ instead of one per window. Each window's bands are a slice of the
    whole system's (they depend on the neighbouring knots only). :meth:`rss` sums each
    window's squared residual over its middle rows ``[edge, size − edge)`` (edge ≥ 2:
    there Q γ has all three terms inside the window, one vector expression over the
    stacked γ)."""

    def __init__(self, system: _Reinsch, starts, size: int, edge: int):
        m = size - 2  # inner knots (γ) per window

        def joined(band, cut):
            parts = []
            for a in starts:
                parts += [band[a:a + m - cut], np.zeros(cut)]
            return np.concatenate(parts)[:-cut]

        def windows(band):  # (windows, m): row w is window w's slice of the band
            return np.stack([band[a:a + m] for a in starts])

        self.r_diag, self.qq0 = windows(system.r_diag).ravel(), windows(system.qq0).ravel()
        self.r_off, self.qq1 = joined(system.r_off, 1), joined(system.qq1, 1)
        self.qq2 = joined(system.qq2, 2)
        self.qty = np.concatenate([system.qty[:, a:a + m] for a in starts], axis=1)
        # row r of a window's Q γ: a_r γ_r + b_{r−1} γ_{r−1} + c_{r−2} γ_{r−2}; over the
        # middle rows r these are three shifted slices of each window's γ (strided views
        # of the solution reshaped to (k, windows, m), no gathered copies)
        self.shape = (len(starts), m)
        self.cuts = tuple(slice(edge - d, size - edge - d) for d in range(3))
        self.qa, self.qb, self.qc = (windows(band)[:, cut] for band, cut in
                                     zip((system.a, system.b, system.c), self.cuts, strict=True))

    def rss(self, lam: float) -> float:
        from scipy.linalg import solveh_banded

        ab = _pentadiagonal(self.r_diag, self.r_off, self.qq0, self.qq1, self.qq2, lam)
        g = solveh_banded(ab, self.qty.T, check_finite=False).T.reshape(-1, *self.shape)
        c0, c1, c2 = self.cuts
        r = self.qa * g[:, :, c0] + self.qb * g[:, :, c1] + self.qc * g[:, :, c2]
        return lam * lam * float(np.sum(r * r))  # (not np.vdot: BLAS threads cost ms here)


def _increasing_root(f, x: float, lo: float, hi: float, xtol: float, step: float = 3.0,
                     slope: float | None = None) -> tuple[float, float | None]:
    """A root of ``f``, increasing on ``[lo, hi]``, searched from ``x``: ``(root, slope)``,
    the slope being the last secant's (a start for the search of a similar ``f``).

    Until the sign changes, secant steps (the first with ``slope`` when given; a walk of
    ``step``, doubling, while there is no usable slope), stretched by :data:`_OVERSHOOT`
    so that they pass the root: f increasing, a point where f < 0 lies below it, so two
    points of opposite signs bracket it. Then false-position steps inside the bracket
    with the Anderson–Björck rule (when the same end is kept twice its f is scaled down,
    so the steps do not stall on one side of a curved f: superlinear, ~1.7). Ends when
    the next secant step is shorter than ``xtol`` (:func:`_close`), when the bracket is,
    or at ``lo`` / ``hi`` when f has no sign change inside (f's closest end)."""
    fx = f(x)
    points = [(x, fx)]
    while fx != 0.0:  # --- walk to a sign change
        if len(points) > 1:
            (x0, f0), (x1, f1) = points[-2:]
            slope = (f1 - f0) / (x1 - x0) if f1 != f0 else None
        if slope is not None and math.isfinite(slope) and slope > 0.0:
            t = x - _OVERSHOOT * fx / slope
        else:
            t = x + (step if fx < 0.0 else -step)
            step *= 2.0
        t = min(max(t, lo), hi)
        if t == x:  # at lo or hi, no sign change
            return x, slope
        ft = f(t)
        points.append((t, ft))
        slope = (ft - fx) / (t - x) if ft != fx else slope
        if _close(t, ft, slope, xtol):
            return t - ft / slope, slope
        if (ft > 0.0) != (fx > 0.0) or ft == 0.0:
            break
        x, fx = t, ft
    (x, fx), (t, ft) = points[-2], points[-1]
    if ft == 0.0 or fx == 0.0:
        return (t if ft == 0.0 else x), slope
    (a, fa), (b, fb) = sorted(points[-2:])  # fa < 0 < fb
    side = 0
    for _ in range(200):  # --- Anderson–Björck false position on [a, b]
        t = (a * fb - b * fa) / (fb - fa)
        if not a < t < b:  # rounding at a bracket of a few ulps
            return t, slope
        ft = f(t)
        (x0, f0), (x1, f1) = points[-1], (t, ft)
        points.append((t, ft))
        if f1 != f0:
            slope = (f1 - f0) / (x1 - x0)
        if ft == 0.0:
            return t, slope
        if _close(t, ft, slope, xtol):
            return t - ft / slope, slope
        if ft < 0.0:
            if side < 0:
                m = 1.0 - ft / fa
                fb *= m if m > 0.0 else 0.5
            a, fa, side = t, ft, -1
        else:
            if side > 0:
                m = 1.0 - ft / fb
                fa *= m if m > 0.0 else 0.5
            b, fb, side = t, ft, 1
        if b - a < xtol:
            return t, slope
    return t, slope


def _close(x: float, fx: float, slope: float | None, xtol: float) -> bool:
    """Whether ``x`` is within ``xtol`` of the root by the secant's estimate: the next
    step, ``fx / slope``, is shorter than ``xtol`` (then taken without evaluating f: the
    secant's error is of higher order than the step)."""
    return slope is not None and math.isfinite(slope) and slope > 0.0 and \
        abs(fx / slope) < xtol


#: Secant steps towards a root not yet bracketed are stretched by this, to pass it.
_OVERSHOOT = 1.2


def reinsch_smooth(t: np.ndarray, y: np.ndarray, lam: float) -> np.ndarray:
    """Values ``g (n, m)`` at the knots of the cubic smoothing spline minimising
    Σ|y_i − g(t_i)|² + λ ∫|g''|² (the same criterion as scipy's ``make_smoothing_spline``)."""
    y = np.asarray(y, dtype=np.float64).reshape(len(t), -1).T
    return (y - _Reinsch(np.asarray(t, dtype=np.float64), y).residual(lam)).T


def smoothing_spline(t: np.ndarray, y: np.ndarray, rss_target: float) -> PPoly:
    """Cubic spline of ``y (n, m)`` over knots ``t``: interpolating (not-a-knot) when
    ``rss_target`` is 0, else the cubic smoothing spline whose residual Σ|y_i − g(t_i)|²
    equals ``rss_target`` (λ by root finding on log λ; the whole vector shares one λ).
    A scipy ``PPoly`` of :func:`spline_coefficients`."""
    from scipy.interpolate import PPoly

    y = np.asarray(y, dtype=np.float64).reshape(len(t), -1)
    c = spline_coefficients(np.asarray(t, dtype=np.float64), np.ascontiguousarray(y.T),
                            rss_target)
    return PPoly.construct_fast(c.transpose(1, 2, 0), t)


def _hermite(dx: np.ndarray, y: np.ndarray, slope: np.ndarray, s: np.ndarray,
             out: np.ndarray) -> np.ndarray:
    """Coefficients ``out`` (k, 4, n−1) of the cubics with values ``y`` and slopes ``s``
    (k, n) at the knots (scipy ``CubicHermiteSpline``'s formulas)."""
    t = (s[:, :-1] + s[:, 1:] - 2 * slope) / dx
    out[:, 0] = t / dx
    out[:, 1] = (slope - s[:, :-1]) / dx - t
    out[:, 2] = s[:, :-1]
    out[:, 3] = y[:, :-1]
    return out


def _not_a_knot(t: np.ndarray, y: np.ndarray, out: np.ndarray) -> np.ndarray:
    """Coefficients (k, 4, n−1) of scipy ``CubicSpline(t, y.T, bc_type="not-a-knot")``
    for ``n ≥ 4`` knots: its slope equations and solve, written out for rows of
    components because ``CubicSpline`` spends ~4/5 of its time outside the solve (input
    checks, axis moves and copies of the (n, k) arrays) — most of the fit's cost."""
    dx = np.diff(t)
    slope = np.diff(y, axis=1) / dx
    band = np.zeros((3, t.shape[0]))
    band[1, 1:-1] = 2 * (dx[:-1] + dx[1:])  # the diagonal
    band[0, 2:] = dx[:-1]                   # the upper diagonal
    band[-1, :-2] = dx[1:]                  # the lower diagonal
    b = np.empty_like(y)
    b[:, 1:-1] = 3 * (dx[1:] * slope[:, :-1] + dx[:-1] * slope[:, 1:])
    d = t[2] - t[0]
    band[1, 0] = dx[1]
    band[0, 1] = d
    b[:, 0] = ((dx[0] + 2 * d) * dx[1] * slope[:, 0] + dx[0] ** 2 * slope[:, 1]) / d
    d = t[-1] - t[-3]
    band[1, -1] = dx[-2]
    band[-1, -2] = d
    b[:, -1] = (dx[-1] ** 2 * slope[:, -2] + (2 * d + dx[-1]) * dx[-2] * slope[:, -1]) / d
    from scipy.linalg import solve_banded

    s = solve_banded((1, 1), band, b.T, overwrite_ab=True, overwrite_b=True,
                     check_finite=False).T
    return _hermite(dx, y, slope, s, out)


def spline_coefficients(t: np.ndarray, y: np.ndarray, rss_target: float,
                        out: np.ndarray | None = None) -> np.ndarray:
    """The piecewise-cubic coefficients ``(k, 4, n−1)`` of the components ``y (k, n)``
    over knots ``t`` (per component scipy ``PPoly`` order: highest power first, in the
    local coordinate t − t_i) of :func:`smoothing_spline`, written into ``out`` when
    given (a view into a larger table: no copy of the result).

    Interpolation is scipy ``CubicSpline``'s not-a-knot spline (:func:`_not_a_knot`).
    Smoothing is written by hand (Reinsch's O(n) banded algorithm) because scipy's
    smoothing splines take λ, not the residual (``make_smoothing_spline``), or pick knots by
    FITPACK's iteration (``make_splrep``/``make_splprep`` with ``s``), and both cost
    0.1–0.4 s per 7200 poses — far from the 1 M IMU samples/s this fit must sustain.
    Reinsch's solve gives the fit's values g and its second derivatives γ at the knots
    (Green & Silverman 1994, Thm 2.1: the natural cubic with Qᵀg = Rγ), so the
    coefficients follow in closed form, without the second banded solve a natural
    ``CubicSpline`` through g would make.
    """
    n = t.shape[0]
    if out is None:
        out = np.empty((y.shape[0], 4, n - 1))
    if n < 4:
        from scipy.interpolate import CubicSpline

        out[...] = CubicSpline(t, y.T, bc_type="natural").c.transpose(2, 0, 1)
        return out
    if rss_target <= 0.0:
        return _not_a_knot(t, y, out)
    system = _Reinsch(t, y)
    # λ is searched on up to LAMBDA_WINDOWS evenly spread windows of LAMBDA_WINDOW knots
    # (each a smoothing problem of its own, the residual target scaled by their share of
    # the knots), then the whole series is solved once with it: a long file costs a few
    # solves of its length instead of ~25, and the whole residual stays within ~6 % of
    # the target (test: test_smoothing_spline_residual_is_the_expected_noise). The root
    # is first estimated on windows a fifth as long (same knots, so the same λ up to
    # their noise: a few % of residual, ~0.1–0.5 in log λ), then refined from there.
    problems = []
    for size in (LAMBDA_WINDOW // 5, LAMBDA_WINDOW):
        if n > LAMBDA_WINDOWS * size:
            starts = np.linspace(0, n - size, LAMBDA_WINDOWS).astype(int)
            # a window's ends fit the data more closely than the middle of a long series:
            # count the residual of its middle only
            edge = size // 10
            problems.append((_StackedReinsch(system, starts, size, edge).rss,
                             LAMBDA_WINDOWS * (size - 2 * edge) / n))
    if len(problems) < 2:
        def rss_all(lam: float) -> float:
            r = system.residual(lam)
            return float(np.sum(r * r))

        problems.append((rss_all, 1.0))

    # λ has units time³: the spline then smooths over (λ/h³)^¼ knots. λ lies between
    # 0.01 and 1000 knots (8 s at 120 Hz: no motion is smoother); the banded system's
    # condition number is ~50 λ/h³, so the upper end also keeps Cholesky well conditioned.
    # The residual grows with λ: the first search starts at one knot (λ = h³; pose files
    # land within e^±9 of it), the next at the first's root and slope.
    log_h3 = np.log(float(np.mean(np.diff(t))) ** 3)
    lo, hi = log_h3 + np.log(1e-8), log_h3 + np.log(1e12)
    log_lam, slope = log_h3, None
    for k, (rss, share) in enumerate(problems):
        def log_excess(log_lam: float, rss=rss, share=share) -> float:
            return np.log(max(rss(np.exp(log_lam)), 1e-300)) - np.log(rss_target * share)

        # log λ to 1e-4 at the end (the residual to 0.01 %, far inside its own noise of
        # ~1.5 %: the fit no longer depends on the search); 0.05 for the estimate
        xtol = 1e-4 if k == len(problems) - 1 else 0.05
        log_lam, slope = _increasing_root(log_excess, log_lam, lo, hi, xtol, slope=slope)
    lam = np.exp(log_lam)
    inner = system.second_derivatives(lam)
    g = system.residual(lam, inner)
    np.subtract(y, g, out=g)  # the fit's values at the knots
    gamma = np.zeros_like(g)  # natural ends: γ = 0 at the first and last knot
    gamma[:, 1:-1] = inner
    h = np.diff(t)
    # the cubic on [t_i, t_i+1] from its end values g and second derivatives γ, written
    # in place (fresh multi-MB temporaries cost more in page faults than in arithmetic):
    # c0 = (γ_i+1 − γ_i) / 6h, c1 = γ_i / 2, c2 = (g_i+1 − g_i) / h − h (2γ_i + γ_i+1) / 6,
    # c3 = g_i
    c0, c1, c2, c3 = (out[:, d] for d in range(4))
    np.subtract(gamma[:, 1:], gamma[:, :-1], out=c0)
    c0 /= 6.0 * h
    np.multiply(gamma[:, :-1], 0.5, out=c1)
    np.multiply(gamma[:, :-1], 2.0, out=c2)
    c2 += gamma[:, 1:]
    c2 *= h / 6.0
    np.subtract(g[:, 1:], g[:, :-1], out=c3)
    c3 /= h
    np.subtract(c3, c2, out=c2)
    c3[...] = g[:, :-1]
    return out


# --------------------------------------------------------------------------- motion
@dataclass(frozen=True)
class TangentSample:
    """The fit at ``n`` times in the tangent frame: ``q_tb (n,4)``, ``omega_tb_b (n,3)``,
    ``p (n,3)``, ``v (n,3)``, ``a (n,3)`` (None unless asked), geodetic ``llh (n,3)``, and
    ``q_nt (n,4)`` (tangent-frame vectors into the local-level ENU frame at ``llh``)."""

    q_tb: np.ndarray
    omega_tb_b: np.ndarray
    p: np.ndarray
    v: np.ndarray
    a: np.ndarray | None
    llh: np.ndarray
    q_nt: np.ndarray


@dataclass(frozen=True)
class TrajectorySample(MotionSample):
    """:class:`MotionSample` (local-level truth) plus the exact position ``llh (n,3)`` and,
    from :meth:`TrajectoryMotion.imu`, the ideal ``omega_ib_b`` and ``specific_force_b``."""

    llh: np.ndarray | None = None
    omega_ib_b: np.ndarray | None = None
    specific_force_b: np.ndarray | None = None


# Kernels on component tuples: a vector is (x, y, z), a unit quaternion (x, y, z, w) (scalar
# last), each a contiguous 1-D array over the samples of one evaluation pass. The kernels
# run once per IMU sample; on (n,3) arrays every column is a strided view and np.cross /
# einsum cost 3-5x more, so the pass keeps each component in an array of its own.
def _cross(ax, ay, az, bx, by, bz):
    return ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx


def _rotate(q, v, inverse: bool = False):
    """``C(q) v`` (or ``C(q)ᵀ v``) for unit ``q``: v + 2w (u×v) + 2 u×(u×v); the inverse
    is the same with u → −u, i.e. v − w t + u×t for t = 2 u×v (the same bits)."""
    ux, uy, uz, w = q
    vx, vy, vz = v
    tx, ty, tz = _cross(ux, uy, uz, vx, vy, vz)
    tx, ty, tz = 2.0 * tx, 2.0 * ty, 2.0 * tz
    cx, cy, cz = _cross(ux, uy, uz, tx, ty, tz)
    if inverse:
        return vx - w * tx + cx, vy - w * ty + cy, vz - w * tz + cz
    return vx + w * tx + cx, vy + w * ty + cy, vz + w * tz + cz


def _qmul(p, q):
    px, py, pz, pw = p
    qx, qy, qz, qw = q
    cx, cy, cz = _cross(px, py, pz, qx, qy, qz)
    return (pw * qx + qw * px + cx, pw * qy + qw * py + cy, pw * qz + qw * pz + cz,
            pw * qw - (px * qx + py * qy + pz * qz))


def _q_en(sl, cl, so, co):
    """ENU → ECEF rotation as a quaternion, ``C_en = Rz(λ + π/2) Rx(π/2 − φ)``, from the
    sines and cosines of latitude φ and longitude λ: (cos, sin) of the half angles
    a = (λ + π/2)/2 ∈ (−π/4, 3π/4] and b = (π/2 − φ)/2 ∈ [0, π/2] by the half-angle
    formulas, no trigonometry (four sin/cos per sample were the pass's dearest step). Of
    each pair the larger magnitude is √((1 + |cos 2x|)/2) (no cancellation), its sign
    that of the quadrant, and the other sin 2x / (2 · it)."""
    # b: cos 2b = sin φ, sin 2b = cos φ ≥ 0 (both halves ≥ 0); cos b is the larger north
    big = np.sqrt(0.5 * (1.0 + np.abs(sl)))
    other = 0.5 * cl / big
    north = sl >= 0.0
    cb, sb = np.where(north, big, other), np.where(north, other, big)
    # a: cos 2a = −sin λ, sin 2a = cos λ; sin λ > 0: a ∈ (π/4, 3π/4), sin a the larger
    # (> 0); else a ∈ (−π/4, π/4], cos a the larger (> 0); the other takes cos λ's sign
    big = np.sqrt(0.5 * (1.0 + np.abs(so)))
    other = 0.5 * co / big
    east = so > 0.0
    ca, sa = np.where(east, other, big), np.where(east, big, other)
    return ca * sb, sa * sb, sa * cb, ca * cb


#: What :meth:`TrajectoryMotion._fields` can compute, with its columns.
_FIELD_WIDTH = {"q_tb": 4, "omega_tb_b": 3, "p": 3, "v": 3, "a": 3, "llh": 3, "q_nt": 4,
                "omega_ib_b": 3, "f_b": 3, "q_nb": 4, "omega_nb_b": 3, "v_n": 3,
                "acc_n": 3}


class TrajectoryMotion(Motion):
    """A fitted pose series (module docstring). ``t`` in :meth:`tangent` / :meth:`evaluate`
    is seconds since the first pose; ``t0_ns`` is that pose's stamp, ``span_s`` the time the
    poses cover; ``origin_llh`` the tangent frame's origin (rad, rad, m)."""

    name = "trajectory"
    moves = True

    def __init__(self, poses: PoseSeries, origin_llh, position_sigma_m: float = 0.0,
                 attitude_sigma_rad: float = 0.0, max_gap_s: float = DEFAULT_MAX_GAP_S):
        poses = check_poses(poses, max_gap_s)
        check_positions(poses, origin_llh)
        self.source = poses.source
        self.t0_ns = int(poses.t_ns[0])
        # float seconds from the first pose, exact integer-ns differences first
        self._t = (poses.t_ns - poses.t_ns[0]).astype(np.float64) / 1e9
        self.span_s = float(self._t[-1])
        self.pose_count = int(self._t.shape[0])
        self.position_sigma_m = float(position_sigma_m)
        self.attitude_sigma_rad = float(attitude_sigma_rad)
        n = self.pose_count
        rss_p = 3.0 * n * self.position_sigma_m ** 2
        rss_q = 0.75 * n * self.attitude_sigma_rad ** 2
        # the fit's layout: components in rows, positions then quaternions. Positions
        # relative to the first pose: the fit is the same shifted (splines reproduce
        # constants), but differences of km-sized coordinates lose digits — at 35 km the
        # acceleration's rounding is ~1e-7 m/s² uncentred, ~1e-13 centred.
        y = np.empty((7, n))
        p0 = poses.p[0].copy()
        np.subtract(poses.p.T, p0[:, None], out=y[:3])
        # sign-continuous quaternions: q and −q are one rotation; the spline must not jump
        qx, qy, qz, qw = poses.q.T
        flip = (qx[1:] * qx[:-1] + qy[1:] * qy[:-1] + qz[1:] * qz[:-1] + qw[1:] * qw[:-1]) < 0.0
        sign = np.concatenate(([1.0], np.where(np.cumsum(flip) % 2 == 1, -1.0, 1.0)))
        np.multiply(poses.q.T, sign, out=y[3:])
        c = np.empty((7, 4, n - 1))
        if rss_p <= 0.0 and rss_q <= 0.0:  # both interpolated: one spline of 7 rows
            spline_coefficients(self._t, y, 0.0, out=c)
        else:
            spline_coefficients(self._t, y[:3], rss_p, out=c[:3])
            spline_coefficients(self._t, y[3:], rss_q, out=c[3:])
        c[:3, 3] += p0[:, None]
        # the coefficient table of the evaluation: row 4 j + d is power 3 − d of component
        # j (x, y, z position, then the 4 quaternion components) over the intervals
        self._coef = c.reshape(28, n - 1)
        self.origin_llh = np.asarray(origin_llh, dtype=np.float64)
        self._r0 = earth.ecef_from_llh(self.origin_llh)
        self._c_et = earth.enu_to_ecef_matrix(self.origin_llh[0], self.origin_llh[1])
        lat0, lon0 = self.origin_llh[0], self.origin_llh[1]
        self._q_et = _q_en(np.sin(lat0), np.cos(lat0), np.sin(lon0), np.cos(lon0))
        self.omega_ie_t = earth.earth_rate_enu(self.origin_llh[0])  # constant in t

    # ------------------------------------------------------------------ evaluation
    def _times(self, t) -> np.ndarray:
        t = np.asarray(t, dtype=np.float64)
        if t.ndim != 1 or not np.all(np.isfinite(t)):
            raise ValueError("times must be a 1-D array of finite values")
        if t.size and (t.min() < -EDGE_S or t.max() > self.span_s + EDGE_S):
            raise ValueError(f"{self.source}: time {t.max() if t.max() > self.span_s else t.min():.9g}"
                             f" s is outside the {self.span_s:.9g} s the poses cover")
        return np.clip(t, 0.0, self.span_s)

    def _fields(self, t, want: frozenset, earth_rotation: bool = True,
                gravity: bool = True) -> dict[str, np.ndarray]:
        """The fields named in ``want`` (:data:`_FIELD_WIDTH`) at times ``t``, each
        ``(n, width)``, evaluated in passes of :data:`EVAL_CHUNK` samples."""
        t = self._times(t)
        n = t.shape[0]
        out = {name: np.empty((n, _FIELD_WIDTH[name])) for name in want}
        for lo in range(0, n, EVAL_CHUNK):
            part = self._pass(t[lo:lo + EVAL_CHUNK], want, earth_rotation, gravity)
            for name, cols in part.items():
                dest = out[name][lo:lo + EVAL_CHUNK]
                for k, col in enumerate(cols):
                    dest[:, k] = col
        return out

    def _pass(self, t: np.ndarray, want: frozenset, earth_rotation: bool,
              gravity: bool) -> dict[str, tuple]:
        """One pass of :meth:`_fields`: the fit and the Earth geometry at ``t``, component
        by component (the kernels above), only what ``want`` needs."""
        truth = bool(want & {"q_nt", "q_nb", "omega_nb_b", "v_n", "acc_n"})
        force = "f_b" in want
        need_q = truth or bool(want & {"q_tb", "omega_tb_b", "omega_ib_b", "f_b"})
        need_v = force or truth or "v" in want
        need_a = force or bool(want & {"a", "acc_n"})
        # one interval search for all 7 components, then Horner on their coefficients
        # (scipy's PPoly would search again for each spline and each derivative order)
        i = np.searchsorted(self._t, t, side="right") - 1
        np.clip(i, 0, self._t.shape[0] - 2, out=i)
        dx = t - self._t[i]
        c = self._coef.take(i, axis=1) if need_q else self._coef[:12].take(i, axis=1)

        def value(j):
            return ((c[4 * j] * dx + c[4 * j + 1]) * dx + c[4 * j + 2]) * dx + c[4 * j + 3]

        def rate(j):
            return ((3.0 * c[4 * j]) * dx + 2.0 * c[4 * j + 1]) * dx + c[4 * j + 2]

        def accel(j):
            return (6.0 * c[4 * j]) * dx + 2.0 * c[4 * j + 1]

        got: dict[str, tuple] = {}
        p = (value(0), value(1), value(2))
        v = (rate(0), rate(1), rate(2)) if need_v else None
        a = (accel(0), accel(1), accel(2)) if need_a else None
        got.update(p=p, v=v, a=a)
        if need_q:
            s = (value(3), value(4), value(5), value(6))
            sd = (rate(3), rate(4), rate(5), rate(6))
            sx, sy, sz, sw = s
            n2 = sx * sx + sy * sy + sz * sz + sw * sw
            norm = np.sqrt(n2)
            q_tb = (sx / norm, sy / norm, sz / norm, sw / norm)
            cx, cy, cz = _cross(sx, sy, sz, sd[0], sd[1], sd[2])
            w_tb = tuple(2.0 * (sw * d - sd[3] * sv - cr) / n2
                         for sv, d, cr in zip(s[:3], sd[:3], (cx, cy, cz), strict=True))
            got.update(q_tb=q_tb, omega_tb_b=w_tb)
        # the Earth geometry at the position: ECEF, geodetic, the local vertical in t
        c_et = self._c_et
        x, y, z = _ecef(self._r0, c_et, p)
        lat, lon, h, sl, cl = earth.geodetic_from_ecef(x, y, z)
        got["llh"] = (lat, lon, h)
        # 1 / distance from the polar axis: x, y times it are cos λ, sin λ (no pole: refused)
        inv_p = 1.0 / np.sqrt(x * x + y * y) if truth or (force and gravity) else None
        if "omega_ib_b" in want:
            w = w_tb
            if earth_rotation:
                rot = _rotate(q_tb, self.omega_ie_t, inverse=True)
                w = tuple(wk + rk for wk, rk in zip(w_tb, rot, strict=True))
            got["omega_ib_b"] = w
        if force:
            f_t = a
            if earth_rotation:
                cor = _cross(*self.omega_ie_t, *v)
                f_t = tuple(ak + 2.0 * ck for ak, ck in zip(a, cor, strict=True))
            if gravity:
                # g^t = C_tn g^n = −g up^t, the geodetic normal (x, y, N)/|(p, N)| in t
                g = earth.normal_gravity(sl * sl, h)
                k = cl * inv_p
                ne = (x * k, y * k, sl)
                up = tuple(c_et[0, j] * ne[0] + c_et[1, j] * ne[1] + c_et[2, j] * ne[2]
                           for j in range(3))
                f_t = tuple(fk + g * uk for fk, uk in zip(f_t, up, strict=True))
            got["f_b"] = _rotate(q_tb, f_t, inverse=True)
        if truth:
            qx, qy, qz, qw = _q_en(sl, cl, y * inv_p, x * inv_p)
            q_nt = _qmul((-qx, -qy, -qz, qw), self._q_et)  # C_nt = C_ne C_et
            got["q_nt"] = q_nt
            if want & {"q_nb", "omega_nb_b", "v_n", "acc_n"}:
                q_nb = _qmul(q_nt, q_tb)
                v_n = _rotate(q_nt, v)
                w_en = earth.transport_rate_components(sl, cl, h, v_n[0], v_n[1])
                rot = _rotate(q_nb, w_en, inverse=True)
                got.update(q_nb=q_nb, v_n=v_n, omega_nb_b=tuple(
                    wk - rk for wk, rk in zip(w_tb, rot, strict=True)))
                if "acc_n" in want:
                    an = _rotate(q_nt, a)
                    cr = _cross(*w_en, *v_n)
                    got["acc_n"] = tuple(ak - ck for ak, ck in zip(an, cr, strict=True))
        return {name: got[name] for name in want}

    def tangent(self, t, need_accel: bool = False) -> TangentSample:
        """The fit at times ``t`` (s since the first pose)."""
        want = {"q_tb", "omega_tb_b", "p", "v", "llh", "q_nt"} | ({"a"} if need_accel else set())
        f = self._fields(t, frozenset(want))
        return TangentSample(f["q_tb"], f["omega_tb_b"], f["p"], f["v"], f.get("a"),
                             f["llh"], f["q_nt"])

    def imu(self, t, earth_rotation: bool = True, gravity: bool = True,
            need_force: bool = True, truth: bool = True) -> TrajectorySample:
        """Ideal sensors at times ``t`` (``omega_ib_b``, ``specific_force_b``): the module
        docstring's equations, each Earth term only when asked for; with ``truth`` also
        the local-level truth (else its fields are None)."""
        want = {"omega_ib_b", "llh"}
        if need_force:
            want |= {"f_b"}
        if truth:
            want |= {"q_nb", "omega_nb_b", "v_n"} | ({"acc_n"} if need_force else set())
        f = self._fields(t, frozenset(want), earth_rotation, gravity)
        if not truth:
            return TrajectorySample(None, None, None, None, llh=f["llh"],
                                    omega_ib_b=f["omega_ib_b"], specific_force_b=f.get("f_b"))
        return TrajectorySample(f["q_nb"], f["omega_nb_b"], f["v_n"], f.get("acc_n"),
                                llh=f["llh"], omega_ib_b=f["omega_ib_b"],
                                specific_force_b=f.get("f_b"))

    def evaluate(self, t, need_accel: bool = False) -> MotionSample:
        """Truth in the local-level ENU frame ``n`` at the actual position: ``q_nb = C_nt
        q_tb``, ``v^n = C_nt v^t``, ``ω_nb^b = ω_tb^b − C_bn ω_en^n`` (the local-level frame
        turns against the Earth-fixed tangent frame at the transport rate) and
        ``dv^n/dt = C_nt a^t − ω_en^n × v^n``."""
        want = {"q_nb", "omega_nb_b", "v_n", "llh"} | ({"acc_n"} if need_accel else set())
        f = self._fields(t, frozenset(want))
        return TrajectorySample(f["q_nb"], f["omega_nb_b"], f["v_n"], f.get("acc_n"),
                                llh=f["llh"])

    def velocity(self, t) -> np.ndarray:
        return self._fields(t, frozenset({"v_n"}))["v_n"]

    def position_llh(self, t) -> np.ndarray:
        """Geodetic position (rad, rad, m) of the fit at times ``t``: exact, no integration."""
        return self._fields(t, frozenset({"llh"}))["llh"]


class TrajectoryRequest(Motion):
    """A ``motion: {type: trajectory, ...}`` as validated, before its file is read: the
    file and fit options. Core reads no files; :func:`gyro_attitude.io.trajectory_file.
    resolve_trajectory` (called by ``io.scene_file.load_scene``) turns it into a
    :class:`TrajectoryMotion`."""

    name = "trajectory"
    moves = True

    def __init__(self, file: str | None = None, format: str | None = None,
                 topic: str | None = None, child_frame_id: str | None = None,
                 position_sigma_m: float = 0.0, attitude_sigma_rad: float = 0.0,
                 max_gap_s: float = DEFAULT_MAX_GAP_S):
        self.file = file
        self.format = format
        self.topic = topic
        self.child_frame_id = child_frame_id
        self.position_sigma_m = position_sigma_m
        self.attitude_sigma_rad = attitude_sigma_rad
        self.max_gap_s = max_gap_s

    def evaluate(self, t, need_accel: bool = False) -> MotionSample:
        raise ValueError("motion: the trajectory file has not been read (load the scene with "
                         "gyro_attitude.io.scene_file.load_scene, or give --trajectory)")


class LiveTrajectory(TrajectoryMotion):
    """A trajectory that grows while it is used (``gyro_sim motion_topic``): poses arrive one
    by one (:meth:`add`), and the fit is that of the last ``window_s`` of them, refitted
    when new ones came. Times are seconds since ``t0_ns`` (the first pose's stamp). A
    sample at t is only asked for once the poses reach t + delay (the caller's bounded
    delay), where later poses no longer move the interpolating fit noticeably (a cubic
    spline's influence decays ~3.7x per knot)."""

    def __init__(self, origin_llh, t0_ns: int, window_s: float = 2.0,
                 position_sigma_m: float = 0.0, attitude_sigma_rad: float = 0.0):
        self.origin_llh = np.asarray(origin_llh, dtype=np.float64)
        self._r0 = earth.ecef_from_llh(self.origin_llh)
        self._c_et = earth.enu_to_ecef_matrix(self.origin_llh[0], self.origin_llh[1])
        self.t0_ns = int(t0_ns)
        self.window_ns = int(window_s * 1e9)
        self.position_sigma_m = float(position_sigma_m)
        self.attitude_sigma_rad = float(attitude_sigma_rad)
        self.source = "motion_topic"
        self._t: list[int] = []
        self._p: list = []
        self._q: list = []
        self._fit: TrajectoryMotion | None = None
        self.pose_count = 0
        self.span_s = 0.0

    def add(self, t_ns: int, p, q) -> str | None:
        """Append one pose; returns why it was refused (None when taken)."""
        p = np.asarray(p, dtype=np.float64)
        q = np.asarray(q, dtype=np.float64)
        if not np.all(np.isfinite(p)):
            return "position is not finite"
        norm = float(np.linalg.norm(q))
        if not abs(norm - 1.0) <= UNIT_QUATERNION_TOLERANCE:
            return f"quaternion is not a unit quaternion (|q| = {norm:.6g})"
        if self._t and t_ns <= self._t[-1]:
            return "stamp not after the previous pose"
        # the file's checks, on this pose and the one before: speed, height, poles
        if self._t:
            step, dt = math.dist(p, self._p[-1]), (t_ns - self._t[-1]) / 1e9
            if step / dt > limits.MAX_SPEED_MPS:
                return _too_fast(step, dt)
        x, y, z = self._r0 + self._c_et @ p
        lat, h = _latitude_height(x, y, z)
        refusal = _position_refusal(p, float(lat), float(h))
        if refusal is not None:
            return refusal
        q = q / norm
        if self._t:
            turn = float(_turn_angle(abs(float(np.dot(q, self._q[-1])))))
            if turn > limits.MAX_BODY_RATE_RAD_S * dt:
                return _too_quick_turn(turn, dt)
        if self._q and float(np.dot(q, self._q[-1])) < 0.0:
            q = -q  # sign-continuous, as the file fit does
        self._t.append(int(t_ns))
        self._p.append(p)
        self._q.append(q)
        cut = 0
        while len(self._t) - cut > 8 and self._t[-1] - self._t[cut] > self.window_ns:
            cut += 1
        if cut:
            del self._t[:cut], self._p[:cut], self._q[:cut]
        self._fit = None
        self.pose_count += 1
        self.span_s = (self._t[-1] - self.t0_ns) / 1e9
        return None

    @property
    def last_stamp_ns(self) -> int | None:
        """Stamp of the latest pose taken (None before the first)."""
        return self._t[-1] if self._t else None

    def covers(self) -> tuple[float, float]:
        """(first, last) time (s since t0) the buffered poses cover."""
        if not self._t:
            return (0.0, -1.0)
        return ((self._t[0] - self.t0_ns) / 1e9, (self._t[-1] - self.t0_ns) / 1e9)

    def _current(self) -> tuple[TrajectoryMotion, float]:
        if len(self._t) < 2:
            raise ValueError("motion_topic: fewer than 2 poses to fit")
        if self._fit is None:
            labels = tuple(f"pose {i}" for i in range(len(self._t)))
            poses = PoseSeries(np.array(self._t, dtype=np.int64), np.array(self._p),
                               np.array(self._q), labels, self.source)
            self._fit = TrajectoryMotion(poses, self.origin_llh, self.position_sigma_m,
                                         self.attitude_sigma_rad, max_gap_s=math.inf)
        return self._fit, (self._t[0] - self.t0_ns) / 1e9

    def tangent(self, t, need_accel: bool = False) -> TangentSample:
        fit, shift = self._current()
        return fit.tangent(np.asarray(t, dtype=np.float64) - shift, need_accel)

    def imu(self, t, earth_rotation: bool = True, gravity: bool = True,
            need_force: bool = True, truth: bool = True) -> TrajectorySample:
        fit, shift = self._current()
        return fit.imu(np.asarray(t, dtype=np.float64) - shift, earth_rotation, gravity,
                       need_force, truth)

    def evaluate(self, t, need_accel: bool = False) -> MotionSample:
        fit, shift = self._current()
        return fit.evaluate(np.asarray(t, dtype=np.float64) - shift, need_accel)

    def velocity(self, t) -> np.ndarray:
        fit, shift = self._current()
        return fit.velocity(np.asarray(t, dtype=np.float64) - shift)

    def position_llh(self, t) -> np.ndarray:
        fit, shift = self._current()
        return fit.position_llh(np.asarray(t, dtype=np.float64) - shift)
