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

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.linalg import solveh_banded
from scipy.optimize import brentq

from gyro_attitude.core import earth
from gyro_attitude.core.motion import Motion, MotionSample

__all__ = [
    "PoseSeries",
    "check_poses",
    "smoothing_spline",
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
    bad = ~np.all(np.isfinite(p), axis=1)
    if bad.any():
        raise ValueError(f"{src}: {lab[int(np.argmax(bad))]}: position is not finite")
    norm = np.linalg.norm(q, axis=1)
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
    return PoseSeries(t, p, q / norm[:, None], lab, src)


# --------------------------------------------------------------------------- splines
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
    """Q γ, shape (n, m), for γ (n−2, m)."""
    m = gamma.shape[0]
    out = np.zeros((m + 2, gamma.shape[1]))
    out[:m] += a[:, None] * gamma
    out[1:m + 1] += b[:, None] * gamma
    out[2:] += c[:, None] * gamma
    return out


class _Reinsch:
    """Reinsch's banded system for knots ``t`` and data ``y (n, m)``: :meth:`residual`
    ``y − g`` of the smoothing spline with parameter λ (one pentadiagonal solve, O(n))."""

    def __init__(self, t: np.ndarray, y: np.ndarray):
        self.size = t.shape[0]
        self.a, self.b, self.c, self.r_diag, self.r_off = _reinsch_parts(t)
        a, b, c = self.a, self.b, self.c
        self.qty = a[:, None] * y[:-2] + b[:, None] * y[1:-1] + c[:, None] * y[2:]
        # QᵀQ bands (pentadiagonal, symmetric)
        self.qq0 = a * a + b * b + c * c
        self.qq1 = b[:-1] * a[1:] + c[:-1] * b[1:]
        self.qq2 = c[:-2] * a[2:]

    def residual(self, lam: float) -> np.ndarray:
        m = self.r_diag.shape[0]
        ab = np.zeros((3, m))
        ab[2] = self.r_diag + lam * self.qq0
        ab[1, 1:] = self.r_off + lam * self.qq1
        ab[0, 2:] = lam * self.qq2
        gamma = solveh_banded(ab, self.qty, check_finite=False)
        return lam * _q_times(self.a, self.b, self.c, gamma)


class _StackedReinsch:
    """Several independent Reinsch systems solved as one block-banded system (no coupling
    between the blocks): one LAPACK call per λ instead of one per window. :meth:`rss`
    sums each window's squared residual over its middle rows ``[edge, size − edge)``."""

    def __init__(self, parts: list[_Reinsch], edge: int):
        self.parts, self.edge = parts, edge

        def joined(name, pad):
            return np.concatenate([np.concatenate((getattr(w, name), np.zeros(pad)))
                                   for w in parts])[:-pad]

        self.r_diag = np.concatenate([w.r_diag for w in parts])
        self.qq0 = np.concatenate([w.qq0 for w in parts])
        self.r_off, self.qq1, self.qq2 = joined("r_off", 1), joined("qq1", 1), joined("qq2", 2)
        self.qty = np.concatenate([w.qty for w in parts])
        self.splits = np.cumsum([w.r_diag.shape[0] for w in parts])[:-1]

    def rss(self, lam: float) -> float:
        m = self.r_diag.shape[0]
        ab = np.zeros((3, m))
        ab[2] = self.r_diag + lam * self.qq0
        ab[1, 1:] = self.r_off + lam * self.qq1
        ab[0, 2:] = lam * self.qq2
        gammas = np.split(solveh_banded(ab, self.qty, check_finite=False), self.splits)
        e = self.edge
        return sum(float(np.sum((lam * _q_times(w.a, w.b, w.c, g))[e:w.size - e] ** 2))
                   for w, g in zip(self.parts, gammas, strict=True))


def reinsch_smooth(t: np.ndarray, y: np.ndarray, lam: float) -> np.ndarray:
    """Values ``g (n, m)`` at the knots of the cubic smoothing spline minimising
    Σ|y_i − g(t_i)|² + λ ∫|g''|² (the same criterion as scipy's ``make_smoothing_spline``)."""
    y = np.asarray(y, dtype=np.float64).reshape(len(t), -1)
    return y - _Reinsch(np.asarray(t, dtype=np.float64), y).residual(lam)


def smoothing_spline(t: np.ndarray, y: np.ndarray, rss_target: float) -> CubicSpline:
    """Cubic spline of ``y (n, m)`` over knots ``t``: interpolating (not-a-knot) when
    ``rss_target`` is 0, else the cubic smoothing spline whose residual Σ|y_i − g(t_i)|²
    equals ``rss_target`` (λ by root finding on log λ; the whole vector shares one λ).

    Written by hand (Reinsch's O(n) banded algorithm) because scipy's smoothing splines
    take λ, not the residual (``make_smoothing_spline``), or pick knots by FITPACK's
    iteration (``make_splrep``/``make_splprep`` with ``s``), and both cost 0.1–0.4 s per
    7200 poses — far from the 1 M IMU samples/s this fit must sustain. The result is the
    natural cubic through the smoothed values, which is exactly the smoothing spline.
    """
    if rss_target <= 0.0 or t.shape[0] < 4:
        return CubicSpline(t, y, bc_type="not-a-knot" if t.shape[0] >= 4 else "natural")
    system = _Reinsch(t, y)
    # λ is searched on up to LAMBDA_WINDOWS evenly spread windows of LAMBDA_WINDOW knots
    # (each a smoothing problem of its own, the residual target scaled by their share of
    # the knots), then the whole series is solved once with it: a long file costs a few
    # solves of its length instead of ~25, and the whole residual stays within ~6 % of
    # the target (test: test_smoothing_spline_residual_is_the_expected_noise).
    n = t.shape[0]
    windows = _StackedReinsch([system], 0)
    share = 1.0
    if n > LAMBDA_WINDOWS * LAMBDA_WINDOW:
        starts = np.linspace(0, n - LAMBDA_WINDOW, LAMBDA_WINDOWS).astype(int)
        # a window's ends fit the data more closely than the middle of a long series:
        # count the residual of its middle only
        edge = LAMBDA_WINDOW // 10
        windows = _StackedReinsch([_Reinsch(t[a:a + LAMBDA_WINDOW], y[a:a + LAMBDA_WINDOW])
                                   for a in starts], edge)
        share = LAMBDA_WINDOWS * (LAMBDA_WINDOW - 2 * edge) / n

    def log_excess(log_lam: float) -> float:
        rss = windows.rss(np.exp(log_lam))
        return np.log(max(rss, 1e-300)) - np.log(rss_target * share)

    # λ has units time³: the spline then smooths over (λ/h³)^¼ knots. Bracket that between
    # 0.01 and 1000 knots (8 s at 120 Hz: no motion is smoother); the banded system's
    # condition number is ~50 λ/h³, so the upper end also keeps Cholesky well conditioned.
    scale = float(np.mean(np.diff(t))) ** 3
    lo, hi = np.log(scale * 1e-8), np.log(scale * 1e12)
    if log_excess(hi) <= 0.0:  # the noise is larger than the motion: the straightest fit
        log_lam = hi
    elif log_excess(lo) >= 0.0:
        log_lam = lo
    else:
        # log λ to 0.02: the residual then matches to ~1 % (its own noise is ~1.5 %)
        log_lam = brentq(log_excess, lo, hi, xtol=0.02)
    return CubicSpline(t, y - system.residual(np.exp(log_lam)), bc_type="natural")


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


# Kernels on unit quaternions (scalar last) and (n,3) vectors, written out per component:
# these run once per IMU sample, and np.cross / generic einsum cost 3-5x more here.
def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1]
    out[..., 1] = a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2]
    out[..., 2] = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return out


def _rotate(q: np.ndarray, v: np.ndarray, inverse: bool = False) -> np.ndarray:
    """``C(q) v`` (or ``C(q)ᵀ v``) for unit ``q``: v + 2w (u×v) + 2 u×(u×v)."""
    u = -q[..., :3] if inverse else q[..., :3]
    t = 2.0 * _cross(u, v)
    return v + q[..., 3:] * t + _cross(u, t)


def _qmul(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    pv, pw, qv, qw = p[..., :3], p[..., 3:], q[..., :3], q[..., 3:]
    out = np.empty(np.broadcast_shapes(p.shape, q.shape))
    out[..., :3] = pw * qv + qw * pv + _cross(pv, qv)
    out[..., 3] = (pw * qw)[..., 0] - np.sum(pv * qv, axis=-1)
    return out


def _q_en(lat: np.ndarray, lon: np.ndarray) -> np.ndarray:
    """ENU → ECEF rotation as a quaternion: ``C_en = Rz(λ + π/2) Rx(π/2 − φ)``."""
    a = 0.5 * (lon + 0.5 * np.pi)
    b = 0.5 * (0.5 * np.pi - lat)
    ca, sa, cb, sb = np.cos(a), np.sin(a), np.cos(b), np.sin(b)
    return np.stack((ca * sb, sa * sb, sa * cb, ca * cb), axis=-1)


class TrajectoryMotion(Motion):
    """A fitted pose series (module docstring). ``t`` in :meth:`tangent` / :meth:`evaluate`
    is seconds since the first pose; ``t0_ns`` is that pose's stamp, ``span_s`` the time the
    poses cover; ``origin_llh`` the tangent frame's origin (rad, rad, m)."""

    name = "trajectory"
    moves = True

    def __init__(self, poses: PoseSeries, origin_llh, position_sigma_m: float = 0.0,
                 attitude_sigma_rad: float = 0.0, max_gap_s: float = DEFAULT_MAX_GAP_S):
        poses = check_poses(poses, max_gap_s)
        self.source = poses.source
        self.t0_ns = int(poses.t_ns[0])
        # float seconds from the first pose, exact integer-ns differences first
        self._t = (poses.t_ns - poses.t_ns[0]).astype(np.float64) / 1e9
        self.span_s = float(self._t[-1])
        self.pose_count = int(self._t.shape[0])
        self.position_sigma_m = float(position_sigma_m)
        self.attitude_sigma_rad = float(attitude_sigma_rad)
        n = self.pose_count
        self._pos = smoothing_spline(self._t, poses.p, 3.0 * n * self.position_sigma_m ** 2)
        self._vel = self._pos.derivative(1)
        self._acc = self._pos.derivative(2)
        # sign-continuous quaternions: q and −q are one rotation; the spline must not jump
        q = poses.q.copy()
        flip = np.sum(q[1:] * q[:-1], axis=1) < 0.0
        sign = np.concatenate(([1.0], np.where(np.cumsum(flip) % 2 == 1, -1.0, 1.0)))
        q *= sign[:, None]
        self._att = smoothing_spline(self._t, q, 0.75 * n * self.attitude_sigma_rad ** 2)
        self._att_rate = self._att.derivative(1)
        self.origin_llh = np.asarray(origin_llh, dtype=np.float64)
        self._r0 = earth.ecef_from_llh(self.origin_llh)
        self._c_et = earth.enu_to_ecef_matrix(self.origin_llh[0], self.origin_llh[1])
        self._q_et = _q_en(self.origin_llh[0], self.origin_llh[1])
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

    def tangent(self, t, need_accel: bool = False) -> TangentSample:
        """The fit at times ``t`` (s since the first pose)."""
        t = self._times(t)
        s = self._att(t)
        sd = self._att_rate(t)
        n2 = np.sum(s * s, axis=1)[:, None]
        q_tb = s / np.sqrt(n2)
        sv, sw, dv, dw = s[:, :3], s[:, 3:], sd[:, :3], sd[:, 3:]
        omega = 2.0 * (sw * dv - dw * sv - _cross(sv, dv)) / n2
        p = self._pos(t)
        v = self._vel(t)
        a = self._acc(t) if need_accel else None
        llh = earth.llh_from_ecef(self._r0 + p @ self._c_et.T)
        q_ne = _q_en(llh[:, 0], llh[:, 1])
        q_ne[:, :3] *= -1.0  # conjugate: ECEF → local-level ENU
        return TangentSample(q_tb, omega, p, v, a, llh, _qmul(q_ne, self._q_et))

    def imu(self, t, earth_rotation: bool = True, gravity: bool = True,
            need_force: bool = True, truth: bool = True) -> TrajectorySample:
        """Ideal sensors at times ``t`` (``omega_ib_b``, ``specific_force_b``): the module
        docstring's equations, each Earth term only when asked for; with ``truth`` also
        the local-level truth (else its fields are None)."""
        s = self.tangent(t, need_accel=need_force)
        w = s.omega_tb_b
        if earth_rotation:
            w = w + _rotate(s.q_tb, np.broadcast_to(self.omega_ie_t, w.shape), inverse=True)
        f = None
        if need_force:
            f_t = s.a.copy()
            if earth_rotation:
                f_t += 2.0 * _cross(self.omega_ie_t, s.v)
            if gravity:
                g_n = earth.gravity_enu(s.llh[:, 0], s.llh[:, 2])
                f_t -= _rotate(s.q_nt, g_n, inverse=True)  # g^t = C_tn g^n
            f = _rotate(s.q_tb, f_t, inverse=True)
        if not truth:
            return TrajectorySample(None, None, None, None, llh=s.llh, omega_ib_b=w,
                                    specific_force_b=f)
        return self._local_level(s, w, f)

    def _local_level(self, s: TangentSample, w_ib=None, f_b=None) -> TrajectorySample:
        q_nb = _qmul(s.q_nt, s.q_tb)
        v_n = _rotate(s.q_nt, s.v)
        w_en = earth.transport_rate_enu(s.llh[:, 0], s.llh[:, 2], v_n)
        omega_nb = s.omega_tb_b - _rotate(q_nb, w_en, inverse=True)
        acc = None
        if s.a is not None:
            acc = _rotate(s.q_nt, s.a) - _cross(w_en, v_n)
        return TrajectorySample(q_nb, omega_nb, v_n, acc, llh=s.llh, omega_ib_b=w_ib,
                                specific_force_b=f_b)

    def evaluate(self, t, need_accel: bool = False) -> MotionSample:
        """Truth in the local-level ENU frame ``n`` at the actual position: ``q_nb = C_nt
        q_tb``, ``v^n = C_nt v^t``, ``ω_nb^b = ω_tb^b − C_bn ω_en^n`` (the local-level frame
        turns against the Earth-fixed tangent frame at the transport rate) and
        ``dv^n/dt = C_nt a^t − ω_en^n × v^n``."""
        return self._local_level(self.tangent(t, need_accel=need_accel))

    def velocity(self, t) -> np.ndarray:
        s = self.tangent(t)
        return _rotate(s.q_nt, s.v)

    def position_llh(self, t) -> np.ndarray:
        """Geodetic position (rad, rad, m) of the fit at times ``t``: exact, no integration."""
        p = self._pos(self._times(t))
        return earth.llh_from_ecef(self._r0 + p @ self._c_et.T)


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
        q = q / norm
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
