"""Causal AHRS aiding: tilt from the specific force filtered in an almost-inertial frame, heading
from the magnetometer, with acceleration and magnetic-disturbance rejection (no ROS, plain floats).

Contract (streaming, the aiding stage): ``AhrsFilter.update(t_ns, rate, accel, q_nb, mag=None)
-> rate`` once per accepted sample, as :class:`.gravity_aiding.GravityAiding`: ``rate`` (3,)
rad/s is the gyro rate with the known bias removed, ``accel`` the specific force (3,) m/s² or
None, ``q_nb`` the current attitude estimate (body→ENU, scalar last), ``mag`` the magnetic field
(3,) tesla in the body frame or None; the returned rate (a 3-tuple) is what the attitude
integrator integrates for the interval ending at this sample.  The filter owns no attitude: it
expresses every correction as an added body rate, so the stream's integrator (any causal
algorithm) stays the one home of the attitude.  :func:`ahrs_attitude` is the batch form over
whole arrays (the same per-sample step: the filter is a feedback loop, so it cannot be
vectorized).

Tilt (the structure of VQF, Laidig & Seel 2023, written from the paper):

* The specific force is rotated into the nav frame with the current attitude and low-passed
  there by a second-order Butterworth filter (time constant ``accel_tau_s``).  Every correction
  the filter applies to the attitude is applied to the filter's state too (a rotation of its
  delay elements), so the state lives in the frame the gyro alone would give — the
  "almost-inertial" frame: gyro errors are not fed back into the average, and accelerations of a
  motion average out (their integral is the velocity change) while gravity does not.
* The tilt is then pulled toward the filtered vertical with time constant ``tilt_tau_s``
  (0: the full correction every sample, as VQF).
* Acceleration rejection: while the filtered vertical is more than ``accel_reject_deg`` from the
  estimated one, or ``|‖f‖ − g| > accel_norm_tol``, the tilt is gyro-only (counted in
  ``accel_rejected``).  Recovery: at a rest (rate below ``rest_rate_max`` and force within
  ``rest_accel_tol`` of g for ``rest_min_s``) the filter trusts the accelerometer at once and
  with the short time constant ``rest_accel_tau_s`` (rest-adaptive); and after
  ``accel_recovery_s`` of continuous rejection in motion (a gyro that really drifted) the
  correction resumes (``accel_recoveries``).  So a sustained acceleration pulls the tilt by at
  most the rejection angle, never by its full ``atan(a/g)``.
* A slow bias integral (``bias_gain``, 1/s) removes the rate the corrections keep applying.

Heading (``mag`` given): the field minus the hard-iron offset is rotated into the nav frame;
the angle of its horizontal part east of north, minus ``declination_deg`` (true north; 0 gives
magnetic north) is the heading error, taken out about the vertical with time constant
``mag_tau_s`` (the first usable field sets the heading at once when ``initial_heading_from_mag``;
the first ``mag_tau_s`` after it converge faster).  A field whose norm differs from the
reference by more than ``mag_norm_tol`` (relative) or whose dip (inclination, positive down)
differs by more than ``mag_dip_tol_deg`` is a disturbance: counted (``mag_disturbed``), heading
gyro-only.  The reference is given (``mag_ref_norm_t``, ``mag_ref_dip_deg``) or learned from the
first ``mag_ref_s`` of field; a disturbed field that stays steady (same norm and dip within the
tolerances) for ``mag_recovery_s`` becomes the new reference (``mag_reference_changes``), unless
its dip has the other sign (a field cannot cross the magnetic equator under a robot).  Fields that
are not 3 finite numbers, beyond ``MAG_ABSURD_T`` or below ``MAG_ZERO_T`` are counted
(``mag_invalid``) and not used.

Hard iron: ``hard_iron_t`` given, or ``estimate_hard_iron``: the sphere fit
``‖m − b‖² = r²`` (linear least squares in ``b`` and ``r² − ‖b‖²``) over sums accumulated per
sample and solved every ``HARD_IRON_SOLVE_S`` with exponential forgetting; a solution is taken
only when the field has been seen from directions spread enough (the smallest eigenvalue of the
field's scatter above a quarter of r²... see :meth:`AhrsFilter._solve_hard_iron`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gyro_attitude.core.angles import wrap_pi
from gyro_attitude.core.attitude.modes import SettingError
from gyro_attitude.core.attitude.settings import setting
from gyro_attitude.core.earth import STANDARD_GRAVITY

__all__ = ["AhrsFilter", "AhrsParams", "ahrs_attitude", "MAG_ABSURD_T", "MAG_ZERO_T"]

MAG_ABSURD_T = 1e-2  # tesla: 10 mT, beyond any magnetometer's range (Earth's field ~25-65 µT)
MAG_ZERO_T = 1e-7  # tesla: 0.1 µT, no magnetometer in a geomagnetic field reads this little
HARD_IRON_SOLVE_S = 1.0
HEADING_INIT_TAU_S = 0.3
HEADING_INIT_S = 2.0
_SQRT2 = math.sqrt(2.0)


# AhrsParams field -> the estimator setting (core/attitude/settings.py) that is its one home:
# default, range and help come from there.
SETTING_OF = {
    "accel_tau_s": "ahrs_accel_tau_s",
    "accel_reject_deg": "ahrs_accel_reject_deg",
    "accel_norm_tol": "ahrs_accel_norm_tol",
    "accel_recovery_s": "ahrs_accel_recovery_s",
    "accel_recovery_rate_deg_s": "ahrs_recovery_rate_deg_s",
    "tilt_rate_max_deg_s": "ahrs_tilt_rate_max_deg_s",
    "bias_gain": "ahrs_bias_gain",
    "mag_tau_s": "ahrs_mag_tau_s",
    "declination_deg": "magnetic_declination_deg",
    "mag_norm_tol": "mag_norm_tol",
    "mag_dip_tol_deg": "mag_dip_tol_deg",
    "mag_recovery_s": "mag_recovery_s",
    "hard_iron_t": "mag_hard_iron_t",
    "estimate_hard_iron": "mag_hard_iron_estimate",
}


def _default(name: str):
    return setting(SETTING_OF[name]).default


@dataclass(frozen=True)
class AhrsParams:
    """Settings of :class:`AhrsFilter` (module docstring); SI units, angles in degrees.  The
    user-facing ones are rows of the estimator's settings table (:data:`SETTING_OF`); the rest
    are the filter's internals: ``tilt_tau_s`` (0: the full correction every sample, as VQF),
    the filter's own rest test (``rest_*``), ``initial_heading_from_mag`` (the first usable
    field sets the heading at once), the field reference (``mag_ref_norm_t``,
    ``mag_ref_dip_deg``; None: learned over ``mag_ref_s``) and the hard-iron fit's memory."""

    accel_tau_s: float = _default("accel_tau_s")
    accel_reject_deg: float = _default("accel_reject_deg")
    accel_norm_tol: float = _default("accel_norm_tol")
    accel_recovery_s: float = _default("accel_recovery_s")
    accel_recovery_rate_deg_s: float = _default("accel_recovery_rate_deg_s")
    tilt_rate_max_deg_s: float = _default("tilt_rate_max_deg_s")
    bias_gain: float = _default("bias_gain")
    mag_tau_s: float = _default("mag_tau_s")
    declination_deg: float = _default("declination_deg")
    mag_norm_tol: float = _default("mag_norm_tol")
    mag_dip_tol_deg: float = _default("mag_dip_tol_deg")
    mag_recovery_s: float = _default("mag_recovery_s")
    hard_iron_t: tuple = _default("hard_iron_t")
    estimate_hard_iron: bool = _default("estimate_hard_iron")
    tilt_tau_s: float = 0.0
    rest_accel_tau_s: float = 0.5
    rest_rate_max: float = 0.05
    rest_accel_tol: float = 0.3
    rest_min_s: float = 1.0
    gravity: float = STANDARD_GRAVITY
    initial_heading_from_mag: bool = True
    mag_ref_norm_t: float | None = None
    mag_ref_dip_deg: float | None = None
    mag_ref_s: float = 1.0
    hard_iron_window_s: float = 60.0

    def __post_init__(self):
        for name, row in SETTING_OF.items():
            object.__setattr__(self, name, setting(row).check(getattr(self, name)))
        limits = {"tilt_tau_s": (0.0, 1e3), "rest_accel_tau_s": (1e-3, 1e3),
                  "rest_rate_max": (0.0, 10.0), "rest_accel_tol": (0.0, 100.0),
                  "rest_min_s": (0.0, 1e3), "gravity": (1.0, 100.0), "mag_ref_s": (0.0, 1e3),
                  "hard_iron_window_s": (1.0, 1e6)}
        for name, (lo, hi) in limits.items():
            _check_num(name, getattr(self, name), lo, hi)
        if self.mag_ref_norm_t is not None:
            _check_num("mag_ref_norm_t", self.mag_ref_norm_t, MAG_ZERO_T, MAG_ABSURD_T)
        if self.mag_ref_dip_deg is not None:
            _check_num("mag_ref_dip_deg", self.mag_ref_dip_deg, -90.0, 90.0)
        if not isinstance(self.initial_heading_from_mag, bool):
            raise ValueError("initial_heading_from_mag must be true or false, got "
                             f"{self.initial_heading_from_mag!r}")

    @classmethod
    def from_config(cls, cfg) -> AhrsParams:
        """The filter's parameters of a :class:`~.settings.StreamConfig`: the table's rows, the
        field reference from ``mag_reference_enu_t`` (zeros: learned), and the heading set from
        the field when the stream levels (a given initial attitude keeps its heading and the
        field pulls it slowly)."""
        kw = {name: getattr(cfg, row) for name, row in SETTING_OF.items()}
        e, n, u = cfg.mag_reference_enu_t
        norm = math.sqrt(e * e + n * n + u * u)
        if norm > 0.0:
            if norm < MAG_ZERO_T:
                raise SettingError("mag_reference_enu_t", "mag_reference_enu_t must be zeros "
                                   f"(learn it) or a field of at least {MAG_ZERO_T:g} T")
            kw["mag_ref_norm_t"] = norm
            kw["mag_ref_dip_deg"] = math.degrees(math.atan2(-u, math.hypot(e, n)))
        return cls(initial_heading_from_mag=cfg.levelling, **kw)


def _check_num(name, v, lo, hi) -> float:
    if isinstance(v, bool) or not isinstance(v, int | float | np.integer | np.floating) \
            or not (math.isfinite(v) and lo <= v <= hi):
        raise ValueError(f"{name} must be a finite number in [{lo:g}, {hi:g}], got {v!r}")
    return float(v)


def _butterworth2(tau: float, dt: float) -> tuple[float, float, float, float, float]:
    """(b0, b1, b2, a1, a2) of the second-order Butterworth low-pass by the bilinear transform,
    cutoff ``√2 / (2π τ)`` (so that its step response settles like a first-order filter of
    time constant τ), for sample time ``dt``."""
    fc = _SQRT2 / (2.0 * math.pi * tau)
    c = math.tan(math.pi * min(fc * dt, 0.49))  # prewarped; a cutoff at Nyquist is clamped
    d = c * c + _SQRT2 * c + 1.0
    b0 = c * c / d
    return b0, 2.0 * b0, b0, 2.0 * (c * c - 1.0) / d, (1.0 - _SQRT2 * c + c * c) / d


def _as_floats(v) -> tuple[float, float, float] | None:
    """3 finite floats, or None (absent, wrong shape, non-finite)."""
    if v is None:
        return None
    try:
        x, y, z = v.tolist() if isinstance(v, np.ndarray) else v
        x, y, z = float(x), float(y), float(z)
    except (TypeError, ValueError):
        return None
    if math.isfinite(x) and math.isfinite(y) and math.isfinite(z):
        return x, y, z
    return None


class AhrsFilter:
    """The causal AHRS aiding stage (see the module docstring).  Counters and state are public
    attributes: ``accel_rejected``, ``accel_recoveries``, ``aided_samples`` (samples whose tilt
    was corrected), ``mag_used``, ``mag_disturbed``, ``mag_invalid``, ``mag_reference_changes``,
    ``at_rest``, ``bias`` (rad/s, subtracted), ``hard_iron`` (tesla), ``mag_ref_norm`` (tesla)
    and ``mag_ref_dip`` (rad) once known, ``heading_initialized``."""

    def __init__(self, params: AhrsParams | None = None, **kw):
        self.params = p = params if params is not None else AhrsParams(**kw)
        if params is not None and kw:
            raise ValueError("give AhrsParams or keyword settings, not both")
        # the tilt's effective gain for the covariance stage: the low-pass sets the time constant
        self.kp = 1.0 / max(p.accel_tau_s, p.tilt_tau_s)
        self._decl = math.radians(p.declination_deg)
        self._reject_cos = math.cos(math.radians(p.accel_reject_deg))
        self._tilt_rate = math.radians(p.tilt_rate_max_deg_s)
        self._settle_s = 2.0 * p.accel_tau_s
        self._recovery_rate = math.radians(p.accel_recovery_rate_deg_s)
        self._dip_tol = math.radians(p.mag_dip_tol_deg)
        self.reset()

    def reset(self) -> None:
        p = self.params
        self.last_t_ns: int | None = None
        self.bias = [0.0, 0.0, 0.0]
        self.aided_samples = 0
        self.accel_rejected = 0
        self.accel_recoveries = 0
        self.mag_used = 0
        self.mag_disturbed = 0
        self.mag_invalid = 0
        self.mag_reference_changes = 0
        self.at_rest = False
        self.heading_initialized = not p.initial_heading_from_mag
        self.hard_iron = [float(c) for c in p.hard_iron_t]
        self.mag_ref_norm = p.mag_ref_norm_t
        self.mag_ref_dip = None if p.mag_ref_dip_deg is None else math.radians(p.mag_ref_dip_deg)
        self._lp = None  # [s1x, s1y, s1z, s2x, s2y, s2z] of the Butterworth, nav frame
        self._coef_key = None
        self._coef = None
        self._rest_s = 0.0
        self._reject_s = 0.0
        self._run_s = 0.0  # seconds since the low-pass started
        self._since_heading_s = 0.0
        self._ref_acc = [0.0, 0.0, 0.0]  # Σ norm, Σ dip, Σ seconds while learning the reference
        self._cand = None  # (norm, dip, seconds) of a steady disturbed field
        self._hi_sums = [0.0] * 14 if p.estimate_hard_iron else None
        self._hi_since_s = 0.0
        self.hard_iron_fits = 0

    def heading_from_field(self, seconds: float, norm_t: float, dip_rad: float) -> None:
        """The heading was just set from the mean field over ``seconds`` of rest (the static
        alignment, with the levelled attitude): the filter goes on from it as a running average
        that has already seen that much field (no fast first phase, the time constant starts at
        ``seconds``), and that field (norm, dip) is the reference unless one is given."""
        self.heading_initialized = True
        self._since_heading_s = HEADING_INIT_S + seconds
        if self.mag_ref_norm is None:
            self.mag_ref_norm = norm_t
        if self.mag_ref_dip is None:
            self.mag_ref_dip = dip_rad

    def restart(self) -> None:
        """A new time base (gap, reset): the low-pass starts again from the next sample; the
        references, the bias and the hard iron are kept."""
        self.last_t_ns = None

    # ------------------------------------------------------------------ one sample
    def update(self, t_ns: int, rate, accel, q_nb, mag=None):
        w = rate.tolist() if isinstance(rate, np.ndarray) else rate
        x, y, z, s = q_nb.tolist() if isinstance(q_nb, np.ndarray) else q_nb
        t = int(t_ns)
        last = self.last_t_ns
        dt = 0.0 if last is None else (t - last) * 1e-9
        if last is not None and dt <= 0.0:
            raise ValueError(f"t_ns must increase: {t} after {last}")
        self.last_t_ns = t
        b = self.bias
        ox, oy, oz = w[0] - b[0], w[1] - b[1], w[2] - b[2]
        if dt == 0.0:
            self._lp = None  # a new time base: the low-pass starts again
        # C_nb of the (normalized) attitude: body -> nav
        k = 2.0 / (x * x + y * y + z * z + s * s)
        c00 = 1.0 - k * (y * y + z * z)
        c01 = k * (x * y - z * s)
        c02 = k * (x * z + y * s)
        c10 = k * (x * y + z * s)
        c11 = 1.0 - k * (x * x + z * z)
        c12 = k * (y * z - x * s)
        c20 = k * (x * z - y * s)
        c21 = k * (y * z + x * s)
        c22 = 1.0 - k * (x * x + y * y)
        dx = dy = dz = 0.0  # the nav-frame correction (rotation vector) of this sample
        learn_tilt = learn_heading = False
        hdt = dt
        if accel is not None:
            fx, fy, fz = accel.tolist() if isinstance(accel, np.ndarray) else accel
            # q_nb is the attitude at the previous sample: the vector seen then is, to first
            # order, v + (ω dt) × v (half-steps: the mean rate of the interval is not known yet,
            # the current one over half the step is its midpoint estimate); without this a body
            # turning at 1 rad/s reads the vertical 0.3° late at 200 Hz
            fx, fy, fz = (fx + hdt * (oy * fz - oz * fy), fy + hdt * (oz * fx - ox * fz),
                          fz + hdt * (ox * fy - oy * fx))
            dx, dy, learn_tilt = self._tilt(dt, ox, oy, oz, fx, fy, fz, c00, c01, c02, c10, c11,
                                            c12, c20, c21, c22)
        if dt == 0.0:
            return ox, oy, oz  # a new time base: no interval to correct over
        if mag is not None:
            dz, learn_heading = self._heading(dt, mag, ox * hdt, oy * hdt, oz * hdt, c00, c01,
                                              c02, c10, c11, c12, c20, c21, c22)
        if dx == 0.0 and dy == 0.0 and dz == 0.0:
            return ox, oy, oz
        lp = self._lp
        if lp is not None:  # the same rotation applied to the filter's state (almost-inertial)
            for i in (0, 3):
                ax, ay, az = lp[i], lp[i + 1], lp[i + 2]
                lp[i] = ax + dy * az - dz * ay
                lp[i + 1] = ay + dz * ax - dx * az
                lp[i + 2] = az + dx * ay - dy * ax
        # the nav-frame rotation as a body rate over this interval: C_bn δ / dt
        ex = c00 * dx + c10 * dy + c20 * dz
        ey = c01 * dx + c11 * dy + c21 * dz
        ez = c02 * dx + c12 * dy + c22 * dz
        g = self.params.bias_gain
        if g > 0.0 and (learn_tilt or learn_heading):
            # the bias integral learns from the steady corrections only (not from the first
            # seconds of a low-pass, a recovery or the heading set from the field)
            lx, ly, lz = (dx, dy, 0.0) if learn_tilt else (0.0, 0.0, 0.0)
            if learn_heading:
                lz = dz
            b[0] -= g * (c00 * lx + c10 * ly + c20 * lz)
            b[1] -= g * (c01 * lx + c11 * ly + c21 * lz)
            b[2] -= g * (c02 * lx + c12 * ly + c22 * lz)
        inv = 1.0 / dt
        return ox + ex * inv, oy + ey * inv, oz + ez * inv

    step = update  # the stage's step on checked inputs (the stream's chain): the same step

    def _tilt(self, dt, ox, oy, oz, fx, fy, fz, c00, c01, c02, c10, c11, c12, c20, c21, c22):
        """The tilt correction (nav x, y rotation) of one accelerometer sample."""
        p = self.params
        if not (abs(fx) <= 1e6 and abs(fy) <= 1e6 and abs(fz) <= 1e6):
            return 0.0, 0.0, False  # not finite or absurd: the stream counts it
        nx = c00 * fx + c01 * fy + c02 * fz
        ny = c10 * fx + c11 * fy + c12 * fz
        nz = c20 * fx + c21 * fy + c22 * fz
        fn = math.sqrt(fx * fx + fy * fy + fz * fz)
        g0 = p.gravity
        if ox * ox + oy * oy + oz * oz < p.rest_rate_max * p.rest_rate_max \
                and abs(fn - g0) < p.rest_accel_tol:
            self._rest_s += dt
        else:
            self._rest_s = 0.0
        rest = self.at_rest = self._rest_s >= p.rest_min_s
        lp = self._lp
        if lp is None:
            # steady state at the estimate's vertical, not at this one sample: the low-pass then
            # moves from what the attitude says to what the accelerometer says over accel_tau_s
            # (one noisy or moving sample would otherwise set the tilt)
            c = self._coefficients(p.accel_tau_s, 0.0035)
            r1 = (c[1] - c[3] + c[2] - c[4]) * fn
            r2 = (c[2] - c[4]) * fn
            self._lp = [0.0, 0.0, r1, 0.0, 0.0, r2]
            self._run_s = 0.0
            return 0.0, 0.0, False
        self._run_s += dt
        b0, b1, b2, a1, a2 = self._coefficients(p.rest_accel_tau_s if rest else p.accel_tau_s,
                                                dt)
        gx = b0 * nx + lp[0]
        gy = b0 * ny + lp[1]
        gz = b0 * nz + lp[2]
        lp[0] = b1 * nx - a1 * gx + lp[3]
        lp[1] = b1 * ny - a1 * gy + lp[4]
        lp[2] = b1 * nz - a1 * gz + lp[5]
        lp[3] = b2 * nx - a2 * gx
        lp[4] = b2 * ny - a2 * gy
        lp[5] = b2 * nz - a2 * gz
        gn = math.sqrt(gx * gx + gy * gy + gz * gz)
        if gn < 1e-9:
            return 0.0, 0.0, False
        h = math.sqrt(gx * gx + gy * gy)
        if h < 1e-12 * gn:
            return 0.0, 0.0, False
        # the rotation about the horizontal axis ĝ × e_up taking ĝ to the vertical
        angle = math.atan2(h, gz)
        learn = False
        if self._run_s < self._settle_s:
            pass  # a new low-pass: the accelerometer is all there is, trusted in full
        elif gz < self._reject_cos * gn or abs(fn - g0) > p.accel_norm_tol:
            self._reject_s += dt
            if self._reject_s < p.accel_recovery_s:
                self.accel_rejected += 1
                return 0.0, 0.0, False
            if self._reject_s - dt < p.accel_recovery_s:
                self.accel_recoveries += 1
            # recovering: no faster than a gyro can drift, so that an acceleration that lasts
            # pulls the tilt by that rate only
            angle = min(angle, self._recovery_rate * dt)
        else:
            self._reject_s = 0.0
            if p.tilt_tau_s > 0.0 and not rest:
                angle *= min(1.0, dt / p.tilt_tau_s)
            angle = min(angle, self._tilt_rate * dt)
            learn = True
        self.aided_samples += 1
        f = angle / h
        return f * gy, -f * gx, learn

    def _coefficients(self, tau, dt):
        key = (tau, round(dt * 1e7))  # 0.1 µs steps: a jittery clock reuses coefficients
        if key != self._coef_key:
            self._coef_key = key
            self._coef = _butterworth2(tau, dt)
        return self._coef

    def _heading(self, dt, mag, hx, hy, hz, c00, c01, c02, c10, c11, c12, c20, c21, c22):
        """(heading correction (nav z rotation), steady) of one magnetometer sample (tesla);
        ``h`` the body rotation over half the step (see update)."""
        p = self.params
        m = _as_floats(mag)
        if m is None or not max(abs(m[0]), abs(m[1]), abs(m[2])) <= MAG_ABSURD_T:
            self.mag_invalid += 1
            return 0.0, False
        hi = self.hard_iron
        mx, my, mz = m[0] - hi[0], m[1] - hi[1], m[2] - hi[2]
        norm = math.sqrt(mx * mx + my * my + mz * mz)
        if norm < MAG_ZERO_T or m[0] * m[0] + m[1] * m[1] + m[2] * m[2] < MAG_ZERO_T * MAG_ZERO_T:
            # a reading of (almost) zero is no reading, whatever the hard iron
            self.mag_invalid += 1
            return 0.0, False
        if self._hi_sums is not None:
            self._hard_iron_step(dt, m)
        mx, my, mz = mx + hy * mz - hz * my, my + hz * mx - hx * mz, mz + hx * my - hy * mx
        ex = c00 * mx + c01 * my + c02 * mz
        ey = c10 * mx + c11 * my + c12 * mz
        ez = c20 * mx + c21 * my + c22 * mz
        horiz = math.sqrt(ex * ex + ey * ey)
        dip = math.atan2(-ez, horiz)
        learned = self.mag_ref_norm is not None and self.mag_ref_dip is not None
        if not self._reference_ok(dt, norm, dip) and (learned or self.heading_initialized):
            # disturbed, or the reference not learned yet once the heading is set (the first
            # field sets the heading at once: waiting for the reference would set it in motion)
            return 0.0, False
        if horiz < 1e-3 * norm:
            return 0.0, False  # at a magnetic pole the horizontal field gives no heading
        err = wrap_pi(math.atan2(ex, ey) - self._decl)
        self.mag_used += 1
        if not self.heading_initialized:
            self.heading_initialized = True
            self._since_heading_s = 0.0
        self._since_heading_s += dt
        # The heading is set from the field by a fast first phase (time constant
        # HEADING_INIT_TAU_S for HEADING_INIT_S: any initial error falls by e^-6.7), then the
        # time constant grows with the time since (a running average) up to mag_tau_s.  Not
        # one jump: a correction is a body rate, and a 90° spike in one interval is not
        # integrated faithfully by the higher-order integrators.
        since = self._since_heading_s - HEADING_INIT_S
        tau = min(p.mag_tau_s, max(HEADING_INIT_TAU_S, since))
        return err * min(1.0, dt / tau), since >= p.mag_tau_s

    def _reference_ok(self, dt, norm, dip) -> bool:
        """Whether the field agrees with the reference (learning or replacing it as needed)."""
        p = self.params
        ref_n, ref_d = self.mag_ref_norm, self.mag_ref_dip
        if ref_n is None or ref_d is None:
            acc = self._ref_acc
            if acc[2] > 0.0 and (abs(norm - acc[0] / acc[2]) > p.mag_norm_tol * norm
                                 or abs(dip - acc[1] / acc[2]) > self._dip_tol):
                self._ref_acc = acc = [0.0, 0.0, 0.0]  # not steady: learn again
            w = max(dt, 1e-3)
            acc[0] += norm * w
            acc[1] += dip * w
            acc[2] += w
            if acc[2] >= p.mag_ref_s:
                if ref_n is None:
                    self.mag_ref_norm = acc[0] / acc[2]
                if ref_d is None:
                    self.mag_ref_dip = acc[1] / acc[2]
            return False
        if abs(norm - ref_n) <= p.mag_norm_tol * ref_n and abs(dip - ref_d) <= self._dip_tol:
            self._cand = None
            return True
        self.mag_disturbed += 1
        cand = self._cand
        if cand is None or abs(norm - cand[0]) > p.mag_norm_tol * cand[0] \
                or abs(dip - cand[1]) > self._dip_tol:
            self._cand = (norm, dip, 0.0)
        else:
            self._cand = cand = (cand[0], cand[1], cand[2] + dt)
            if cand[2] >= p.mag_recovery_s and (cand[1] > 0.0) == (ref_d > 0.0):
                self.mag_ref_norm, self.mag_ref_dip = cand[0], cand[1]
                self.mag_reference_changes += 1
                self._cand = None
        return False

    # ------------------------------------------------------------------ hard iron
    def _hard_iron_step(self, dt, m) -> None:
        """Accumulate the sphere-fit sums in µT (well scaled) and solve every second."""
        x, y, z = m[0] * 1e6, m[1] * 1e6, m[2] * 1e6
        r = x * x + y * y + z * z
        sm = self._hi_sums
        sm[0] += x * x
        sm[1] += x * y
        sm[2] += x * z
        sm[3] += y * y
        sm[4] += y * z
        sm[5] += z * z
        sm[6] += x
        sm[7] += y
        sm[8] += z
        sm[9] += 1.0
        sm[10] += r * x
        sm[11] += r * y
        sm[12] += r * z
        sm[13] += r
        self._hi_since_s += dt
        if self._hi_since_s >= HARD_IRON_SOLVE_S:
            forget = math.exp(-self._hi_since_s / self.params.hard_iron_window_s)
            self._hi_since_s = 0.0
            self._solve_hard_iron()
            for i in range(14):
                sm[i] *= forget

    def _solve_hard_iron(self) -> None:
        """Solve ``m·m = 2 b·m + c`` in the least-squares sense from the sums (numpy, once a
        second): accepted when the field's directions are spread (the smallest eigenvalue of
        the scatter of m is at least (r/3)², as from rotations of ±40° or more about two axes)
        and the fit is of Earth-field size."""
        sm = self._hi_sums
        n = sm[9]
        if n < 50:
            return
        sxx = np.array([[sm[0], sm[1], sm[2]], [sm[1], sm[3], sm[4]], [sm[2], sm[4], sm[5]]])
        sx = np.array(sm[6:9])
        mean = sx / n
        scatter = sxx / n - np.outer(mean, mean)
        a = np.empty((4, 4))
        a[:3, :3] = 4.0 * sxx
        a[:3, 3] = a[3, :3] = 2.0 * sx
        a[3, 3] = n
        rhs = np.array([2.0 * sm[10], 2.0 * sm[11], 2.0 * sm[12], sm[13]])
        try:
            sol = np.linalg.solve(a, rhs)
        except np.linalg.LinAlgError:
            return
        bvec = sol[:3]
        r2 = sol[3] + float(bvec @ bvec)
        if not np.all(np.isfinite(sol)) or not r2 > 0:
            return
        r = math.sqrt(r2)
        if not 5.0 <= r <= 1000.0:  # µT: an Earth-like field (and a nearby steel structure)
            return
        if np.linalg.eigvalsh(scatter)[0] < (r / 3.0) ** 2 / 3.0:
            return
        self.hard_iron = [float(c) * 1e-6 for c in bvec]
        self.hard_iron_fits += 1
        if self.params.mag_ref_norm_t is None:
            self.mag_ref_norm = r * 1e-6


def ahrs_attitude(t_ns, gyro, accel, q0, mag=None, *, params: AhrsParams | None = None,
                  algorithm: str = "exp_map") -> tuple[np.ndarray, AhrsFilter]:
    """Batch: attitudes (N, 4) of the filter over bias-free ``gyro`` (N, 3) rad/s, ``accel``
    (N, 3) m/s², ``mag`` (N, 3) tesla or None (rows of NaN: no field at that sample), from
    ``q0``; the filter is returned for its counters.  Integrated with ``algorithm`` (a causal
    one of the registry); the aiding sees the attitude at the previous sample."""
    from gyro_attitude.core.attitude.rest import check_samples
    from gyro_attitude.core.attitude.streaming import StreamingIntegrator

    t, w, f = check_samples(t_ns, gyro, accel)
    m = None
    if mag is not None:
        m = np.asarray(mag, dtype=np.float64)
        if m.shape != (t.size, 3):
            raise ValueError(f"mag must have shape ({t.size}, 3), got {m.shape}")
    aid = AhrsFilter(params)
    integ = StreamingIntegrator(algorithm, q0=q0)
    q = np.empty((t.size, 4))
    cur = integ.quaternion
    tl = t.tolist()
    wl = w.tolist()
    fl = None if f is None else f.tolist()
    ml = None if m is None else m.tolist()
    for k in range(t.size):
        rate = aid.update(tl[k], wl[k], None if fl is None else fl[k], cur,
                          None if ml is None else ml[k])
        cur = integ.update(tl[k], rate)
        q[k] = cur
    return q, aid
