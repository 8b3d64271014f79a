"""The causal attitude estimator of the live node and replay: :class:`AttitudeStream`, whose
push() takes one Imu sample through the chain's step (:mod:`.chain`) and run() a recording
through the same step in a compiled loop; the words of what the step did are made here
(docs/architecture.md, "The causal estimator")."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, replace

import numpy as np

from gyro_attitude.core.attitude import DEFAULT_ALGORITHM, NavFrame, chain, get_algorithm
from gyro_attitude.core.attitude import validation as v
from gyro_attitude.core.attitude.ahrs import MAG_ABSENT, MAG_GIVEN, MAG_NOT_FLOATS, AhrsFilter
from gyro_attitude.core.attitude.alignment import (
    ALIGN_RING_DTYPE,
    AlignmentResult,
    aligner_start,
    alignment_result,
    failure_words,
    heading_of,
    level_quaternion,
)
from gyro_attitude.core.attitude.chain import ACCEL_ABSURD  # one home: the step's
from gyro_attitude.core.attitude.covariance import V_TT, covariance_start
from gyro_attitude.core.attitude.gyro_bias import GyroBiasReport, bias_report, bias_start
from gyro_attitude.core.attitude.modes import (
    Aiding,
    Frame,
    GyroBiasMode,
    HeadingSource,
    InitialAttitudeSource,
    Phase,
    SettingError,
)
from gyro_attitude.core.attitude.rest import R_COUNT, RING_START, detect_rest, grown_ring
from gyro_attitude.core.attitude.settings import StreamConfig, check_gyrocompass_feasible
from gyro_attitude.core.attitude.streaming import C_HAS_LAST, C_LAST_T, constant_nav_rate
from gyro_attitude.core.earth import STANDARD_GRAVITY, check_latitude, earth_rate_enu
from gyro_attitude.core.jit import compiled, direct, precompiled
from gyro_attitude.core.rotation import quat_normalize

__all__ = ["AttitudeStream", "StreamConfig", "StreamResult", "aiding_note", "bias_summary",
           "compile_kernels"]

INVALID_COVARIANCE = "invalid_covariance"
INTEGRATOR_ERROR = "integrator_error"
INVALID_ACCEL = "invalid_accel"
MAG_MISSING = "mag_missing"  # aiding magnetometer: no field within mag_max_age_s
INVALID_MAG = "invalid_mag"  # a field that is no reading (non-finite, absurd, zero)
MAG_DISTURBED = "mag_disturbed"  # a field that disagrees with the reference
SATURATED = "saturated"  # accepted samples pinned at a repeated extreme: a clipped gyro
# intervals whose rate fit could not be trusted: integrated toward the exponential map
RATE_FIT_FALLBACK = "rate_fit_fallback"
GYRO_NOISE_UNKNOWN = "gyro_noise_unknown"  # a detail (said once), not a count

ALIGNING, RUNNING, FAILED = Phase.ALIGNING, Phase.RUNNING, Phase.FAILED
#: the chain's events: (index into run()'s first rows, bit of the step's events, detail key)
_EVENTS = ((chain.EV_INVALID_COV, chain.E_INVALID_COV, INVALID_COVARIANCE),
           (chain.EV_INVALID_ACCEL, chain.E_INVALID_ACCEL, INVALID_ACCEL),
           (chain.EV_SATURATED, chain.E_SATURATED, SATURATED),
           (chain.EV_FALLBACK, chain.E_FALLBACK, RATE_FIT_FALLBACK),
           (chain.EV_MAG_MISSING, chain.E_MAG_MISSING, MAG_MISSING),
           (chain.EV_NOISE_UNKNOWN, chain.E_NOISE_UNKNOWN, GYRO_NOISE_UNKNOWN))
_MAG_NOTES = ((INVALID_MAG, "a magnetic field sample not finite, beyond 10 mT or below 0.1 µT"),
              (MAG_DISTURBED, "a field whose norm or dip is off the reference"))
START_NOTE = ("initial attitude: roll and pitch from the first accelerometer sample, the "
              "heading of initial_attitude ({:.4g}° from north)")


def _values(x) -> str:
    """A sample's values as a list of floats in a log line (its repr when not numbers)."""
    try:
        return str(np.asarray(x, dtype=np.float64).reshape(-1).tolist())
    except (TypeError, ValueError, OverflowError):
        return repr(x)


def invalid_covariance_note(covariance) -> str:
    return (f"angular_velocity_covariance {_values(covariance)} has a non-finite, negative or "
            "absurd diagonal: treated as unknown")


def unknown_noise_note(cfg: StreamConfig) -> str:
    """What the covariance assumes for samples whose gyro covariance says "no estimate"."""
    n = cfg.gyro_noise_density
    return ("angular_velocity_covariance says no estimate (REP-145: element 0 is -1): the "
            + (f"orientation variance grows with gyro_noise_density = {n:g} rad/s/sqrt(Hz)"
               if n > 0 else "gyro noise is taken as unknown and adds nothing to the orientation "
               "variance (set gyro_noise_density)"))


def saturation_note(axis: int, value: float) -> str:
    return (f"gyro pinned at {value:g} rad/s on axis {'xyz'[axis]} (a repeated extreme: the "
            "gyro saturated; the attitude is unreliable there)")


def rate_fit_note(t_ns: int) -> str:
    return (f"rate fit not trusted at stamp {t_ns}: the samples alias the motion (the rate "
            "turns by nearly half a turn between samples) or the fit leaves their range; the "
            "step moved toward the exponential map (the attitude is unreliable there: sample "
            "faster)")


def starts_from_accelerometer(cfg: StreamConfig, q0) -> bool:
    """The tilt starts from the first accelerometer sample: ``initial_attitude_source``
    accelerometer, or auto resolved to it with no attitude ``q0`` given to the estimator."""
    if cfg.initial_attitude_source is InitialAttitudeSource.ACCELEROMETER:
        return True
    return q0 is None and cfg.start_source is InitialAttitudeSource.ACCELEROMETER


def aiding_note(cfg: StreamConfig, accel_seen: bool | None, unused: str | None = None) -> str:
    """Which aiding runs and why, in one line: ``accel_seen`` whether the Imu carried a
    usable linear acceleration (None: not known yet); ``unused`` why the Imu's accelerometer
    was left out, when it was (else: it carries none)."""
    name = f"aiding {cfg.aiding}"
    if not cfg.aided:
        return f"{name}: gyro-only"
    if cfg.aiding is Aiding.MAGNETOMETER:
        return (f"{name}: the AHRS filter, tilt from the accelerometer and heading from the "
                "magnetometer")
    if accel_seen is False or unused:
        return (f"{name}: gyro-only, " + (unused or "the Imu carries no linear acceleration "
                                            "(REP-145: linear_acceleration_covariance[0] = -1)"))
    return (f"{name}: the AHRS filter, tilt from the accelerometer (heading gyro-only; aiding "
            "magnetometer adds the magnetometer)")


def bias_summary(report: GyroBiasReport) -> str:
    """One line on the gyro bias for a summary or a log (rad/s and °/s)."""
    if report.mode != GyroBiasMode.AUTO or report.rests_used == 0:
        return f"gyro bias {report.mode}: {np.round(report.bias, 6).tolist()} rad/s ({report.note})"
    return (f"gyro bias auto: {np.round(report.bias, 6).tolist()} rad/s "
            f"(± {np.round(report.standard_error, 7).tolist()}, {report.rests_used} rest(s), "
            f"{report.rest_samples} samples); {report.note}")


@dataclass
class StreamResult:
    """Attitudes of :meth:`AttitudeStream.run` over N input samples: ``index`` (M,) the
    input rows that got one (the others were skipped, or came while aligning); ``q`` (M, 4)
    scalar-last, finite and unit; ``variance`` (M, 3) per-axis orientation variance [rad²]
    and ``variance_known`` (M,) whether it is an estimate (None, None when nothing gives one);
    ``action`` (N,) verdict codes (:data:`.validation.ACTION_CODES`); ``details`` the first
    log line per reason; ``notes`` what the estimator did, in words."""

    index: np.ndarray
    q: np.ndarray
    variance: np.ndarray | None
    variance_known: np.ndarray | None
    action: np.ndarray
    counts: dict[str, int]
    time_jump_resets: int
    details: dict[str, str] = field(default_factory=dict)
    bias: GyroBiasReport | None = None
    alignment: AlignmentResult | None = None
    notes: list[str] = field(default_factory=list)

    @property
    def skipped(self) -> int:
        return int(self.action.shape[0] - self.index.shape[0])


#: the algorithms compiled into the chain's step (the integration library has the others:
#: integrate_batch, bench)
STEP_ALGORITHMS = {"rotvec_cubic": chain.ALG_CUBIC, "exp_map": chain.ALG_EXP_MAP}


class AttitudeStream:
    """Imu samples in, attitude out, through the chain's step.  ``algorithm`` one of
    :data:`STEP_ALGORITHMS`; ``q0`` the initial attitude (also the one a time jump resets
    to; None: ``initial_attitude``, whose tilt the first accelerometer sample replaces when
    :func:`starts_from_accelerometer`); ``nav`` a :class:`NavFrame` for q_nb (default: the
    one of ``config`` with frame enu) or None for q_ib.  The whole state is :attr:`state`
    (one record of :data:`.chain.STATE_DTYPE`) and three rings; the settings are
    :attr:`coef` (:data:`.chain.COEF_DTYPE`), computed once."""

    def __init__(self, algorithm: str = DEFAULT_ALGORITHM, q0=None,
                 nav: NavFrame | None = None, config: StreamConfig | None = None):
        self.config = cfg = config if config is not None else StreamConfig()
        q_initial = _unit_quat(cfg.initial_attitude if q0 is None else q0)
        self._level_first = starts_from_accelerometer(cfg, q0)
        if nav is None and cfg.frame is Frame.ENU:
            nav = cfg.nav_frame()
        if nav is not None and not isinstance(nav, NavFrame):
            raise ValueError(f"nav must be a NavFrame or None, got {type(nav).__name__}")
        self.nav = nav
        self._check_algorithm(algorithm)
        self.algorithm = algorithm
        lat = nav.latitude_rad if nav is not None else (
            cfg.latitude_rad if cfg.latitude_known else None)
        self.latitude_rad = None if lat is None else float(np.asarray(lat).reshape(-1)[0])
        if cfg.heading_source is HeadingSource.GYROCOMPASS:
            check_gyrocompass_feasible(cfg.gyro_bias_sigma_rad_s, self.latitude_rad,
                                       cfg.heading_error_limit_deg)
        self.coef = np.zeros(1, chain.COEF_DTYPE).view(np.recarray)
        self.state = np.zeros(1, chain.STATE_DTYPE).view(np.recarray)
        self.bias_ring = np.zeros(RING_START, chain.BIAS_RING_DTYPE).view(np.recarray)
        self.align_ring = np.zeros(RING_START, ALIGN_RING_DTYPE).view(np.recarray)
        self.align_buffer = np.zeros(RING_START, chain.ALIGN_BUFFER_DTYPE).view(np.recarray)
        self._set_coefficients(cfg, q_initial)
        self._init_state(cfg, q_initial)
        self.frame_id: str | None = None  # the frame the time base locked in (validation)
        self._pushed = False
        self.details: dict[str, str] = {}  # the first log line per reason
        self.alignment_error: str | None = None
        self._step = None  # the compiled step, at the first push() (run() needs none)

    @staticmethod
    def _check_algorithm(algorithm) -> None:
        info = get_algorithm(algorithm)  # ValueError naming the choices for an unknown one
        if not info.causal:
            raise ValueError(f"{algorithm} is an offline algorithm (it needs the samples after "
                             "each interval): the causal estimator takes a causal one (or use "
                             "the offline estimator)")
        if algorithm not in STEP_ALGORITHMS:
            raise ValueError(f"the causal estimator integrates with {sorted(STEP_ALGORITHMS)} "
                             f"(compiled into its step), not {algorithm}; the integration "
                             "library (integrate_batch, gyro-attitude bench) has every "
                             "algorithm")

    def _set_checks(self) -> None:
        """The validation thresholds of :attr:`config` into the coefficients."""
        chk, c = self.config, self.coef[0]
        c.max_gap_ns, c.time_jump_ns = chk.max_gap_ns, chk.time_jump_ns
        c.max_rate, c.max_missing = chk.max_rate_rad_s, chk.max_missing_samples
        self._max_rate = float(c.max_rate)

    def _set_coefficients(self, cfg: StreamConfig, q_initial: np.ndarray) -> None:
        c = self.coef[0]
        self._set_checks()
        c.bias_mode = {GyroBiasMode.NONE: chain.BIAS_NONE,
                       GyroBiasMode.PARAMETER: chain.BIAS_PARAMETER,
                       GyroBiasMode.AUTO: chain.BIAS_AUTO}[cfg.gyro_bias]
        c.earth = self.latitude_rad is not None
        if c.earth:
            c.earth_n = earth_rate_enu(check_latitude(self.latitude_rad, "latitude_rad"))
        c.min_rest_ns = int(round(cfg.min_rest_s * 1e9))
        c.heading = math.radians(cfg.initial_heading_deg)
        if self._level_first:
            c.heading = heading_of(q_initial)
        c.levelling = cfg.levelling
        c.mag_mode = cfg.aiding is Aiding.MAGNETOMETER
        c.algorithm = STEP_ALGORITHMS[self.algorithm]
        c.n2 = cfg.gyro_noise_density * cfg.gyro_noise_density
        c.k2 = float(cfg.gyro_bias_rw) ** 2
        c.accel_floor_var = (cfg.accel_bias_sigma / STANDARD_GRAVITY) ** 2
        c.level_first = self._level_first
        c.aiding = chain.AID_NONE
        if cfg.aided:
            aid = AhrsFilter(cfg)
            c.aiding, c.ahrs, c.kp = chain.AID_AHRS, aid.pa, aid.kp

    def _init_state(self, cfg: StreamConfig, q_initial: np.ndarray) -> None:
        s = self.state[0]
        s.q = s.q_initial = q_initial
        s.phase = chain.ALIGNING if cfg.levelling else chain.RUNNING
        s.accel_present = -1
        s.first_rest_pending = cfg.gyro_bias is GyroBiasMode.AUTO and not cfg.levelling
        s.variance_known = bool(cfg.gyro_noise_density > 0 or cfg.gyro_bias_sigma_rad_s > 0
                                or cfg.levelling)
        s.sat = [0.0] * 3 + [math.nan] * 3
        s.rest_f, s.rest_i, s.bias_f, s.bias_i = bias_start(cfg)
        if cfg.levelling:
            gc = cfg.heading_source is HeadingSource.GYROCOMPASS
            self.state.aligner[0] = aligner_start(cfg, self.latitude_rad if gc else None)[0]
        s.level_pending = self.coef.level_first[0]
        self.aiding = None
        if cfg.aided:
            self.aiding = AhrsFilter(cfg)
            s.ahrs_f, s.ahrs_i = self.aiding.af, self.aiding.ai
            self.aiding.af, self.aiding.ai = self.state.ahrs_f[0], self.state.ahrs_i[0]
        # the nav rate ω_in^n of a constant frame (a series is fed row by row: run())
        s.has_nav = self.nav is not None
        if self.nav is not None and self.nav.series_length() is None:
            s.nav_rate = self.nav.rate_enu(None)
        # one-off steps run as the kernels' Python form: no compiler for a reset
        chain.integrator_reset(self.coef[0], s, *q_initial.tolist(), False, 0)
        s.cov, s.initial_tt = covariance_start(cfg)
        self.intervals = v.IntervalStatistics(self.state.intervals[0],
                                              self.state.interval_fill[0])

    # ------------------------------------------------------------------ queries
    @property
    def phase(self) -> Phase:
        return (Phase.RUNNING, Phase.ALIGNING, Phase.FAILED)[int(self.state.phase[0])]

    @property
    def q_initial(self) -> np.ndarray:
        return np.array(self.state.q_initial[0])

    @property
    def counts(self) -> dict[str, int]:
        s = self.state[0]
        st = s.stamps
        out = {r: int(st.counts[i + 1]) for i, r in enumerate(v.REJECT_REASONS)}
        out.update({INVALID_COVARIANCE: int(s.invalid_covariance),
                    INVALID_ACCEL: int(s.invalid_accel),
                    INTEGRATOR_ERROR: int(s.integrator_error), SATURATED: int(s.saturated),
                    RATE_FIT_FALLBACK: int(s.rate_fit_fallback),
                    v.MISSING_SAMPLES: int(st.missing)})
        if self.config.aiding is Aiding.MAGNETOMETER:
            out[MAG_MISSING] = int(s.mag_missing)
            out[INVALID_MAG] = self.aiding.mag_invalid
            out[MAG_DISTURBED] = self.aiding.mag_disturbed
            for key, text in _MAG_NOTES:
                if out[key]:
                    self.details.setdefault(key, text)
        return out

    @property
    def rejected_total(self) -> int:
        c = self.state.stamps[0].counts
        return int(sum(c[i + 1] for i, r in enumerate(v.REJECT_REASONS) if r != v.GAP))

    @property
    def accepted(self) -> int:
        return int(self.state.stamps[0].accepted)

    @property
    def time_jump_resets(self) -> int:
        return int(self.state.stamps[0].jump_resets)

    @property
    def last_t_ns(self) -> int | None:
        st = self.state.stamps[0]
        return int(st.last) if st.has_last else None

    @property
    def quaternion(self) -> np.ndarray:
        return np.array(self.state.q[0], dtype=np.float64)

    @property
    def variance(self) -> np.ndarray | None:  # per axis [rad²]; None: nothing gives one
        s = self.state[0]
        return np.array(s.cov[V_TT:V_TT + 3]) if s.variance_known else None

    @property
    def bias_report(self) -> GyroBiasReport:
        s = self.state[0]
        return bias_report(self.config.gyro_bias, s.bias_f, s.bias_i, int(self.coef.min_rest_ns[0]))

    @property
    def alignment(self) -> AlignmentResult | None:
        r = self.state.aligner[0]
        return alignment_result(r) if r.aligned else None

    @property
    def aiding_note(self) -> str:
        """Which aiding runs and why, in one line (said once by the node and by replay)."""
        present = int(self.state.accel_present[0])
        seen = None if present < 0 else present == 1
        if self.aiding is not None and self.aiding.aided_samples > 0:
            seen = True
        return aiding_note(self.config, seen)

    @property
    def start_note(self) -> str | None:
        """How the attitude started when the accelerometer gave its tilt, else None."""
        return START_NOTE.format(math.degrees(self.coef.heading[0])) \
            if self.state.levelled_first[0] else None

    # ------------------------------------------------------------------ settings
    def set_config(self, config: StreamConfig) -> None:
        """New validation thresholds from the next sample on (the rest of ``config`` is
        that of construction)."""
        self.config = replace(self.config, max_gap_s=config.max_gap_s,
                              time_jump_threshold_s=config.time_jump_threshold_s,
                              max_rate_rad_s=config.max_rate_rad_s,
                              max_missing_samples=config.max_missing_samples)
        self._set_checks()

    def set_algorithm(self, algorithm: str) -> None:
        """Switch the algorithm, keeping the attitude and the time base (raises ValueError and
        changes nothing for an unknown or unsuitable algorithm)."""
        self._check_algorithm(algorithm)
        if algorithm == self.algorithm:
            return  # nothing to switch (the integrator's history kept)
        s = self.state[0]
        ci = s.cubic_i
        has_t = bool(ci[C_HAS_LAST])
        q = s.cubic_f[:4].tolist()
        self.algorithm = algorithm
        self.coef.algorithm[0] = STEP_ALGORITHMS[algorithm]
        chain.integrator_reset(self.coef[0], s, *q, has_t, int(ci[C_LAST_T]) if has_t else 0)

    def update_nav(self, nav: NavFrame) -> None:
        """Constant nav frame from the next sample on (its rate ω_in^n evaluated here, once)."""
        rate = constant_nav_rate(self.nav, nav)
        self.nav = nav
        self.state.nav_rate[0] = rate

    def restart(self, q0=None) -> None:
        """Forget the time base (and the locked frame): the next sample starts from ``q0``
        (which also becomes the initial attitude), or from the initial attitude."""
        s = self.state[0]
        if q0 is not None:
            s.q_initial = _unit_quat(q0)
            s.q = s.q_initial
            s.level_pending = False  # a given attitude, not the accelerometer's
        s.has_resume = False
        s.has_start = False  # the start the first rest's estimate may go back to: the next
        v.stamps_reset(s.stamps)
        self.frame_id = None
        s.interval_fill = 0
        chain.break_windows(self.coef[0], s)

    # ------------------------------------------------------------------ one sample
    def push(self, t_ns: int, omega, frame_id: str = "", angular_velocity_covariance=None,
             accel=None, mag=None) -> tuple[v.Verdict, np.ndarray | None]:
        """One sample through the chain: its verdict and the attitude at ``t_ns`` (None when it
        was skipped or while aligning).  ``accel`` the specific force (3,) m/s² or None; ``mag``
        the magnetic field (3,) tesla time-aligned to ``t_ns`` or None."""
        w = _floats(omega)
        t = t_ns if type(t_ns) is int and -2**63 <= t_ns < 2**63 else self._stamp(t_ns, w)
        w0, w1, w2 = w if w is not None else (math.nan, math.nan, math.nan)
        frame_ok = self.frame_id is None or frame_id == self.frame_id
        a = None if accel is None else _floats(accel) or (math.nan, math.nan, math.nan)
        a0, a1, a2 = a if a is not None else (0.0, 0.0, 0.0)
        cv = _ZERO9
        if angular_velocity_covariance is not None:
            cv = _covariance_row(angular_velocity_covariance)
        ms, m = _field(mag) if self.config.aiding is Aiding.MAGNETOMETER else (MAG_ABSENT, None)
        m0, m1, m2 = m if m is not None else (0.0, 0.0, 0.0)
        if self._step is None:
            self._step = compiled(chain.step)
        while True:
            code, reason, got, ev, x, y, z, u = self._step(
                self.coef, self.state, self.bias_ring, self.align_ring, self.align_buffer, t,
                w0, w1, w2, frame_ok, a is not None, a0, a1, a2,
                angular_velocity_covariance is not None, cv, ms, m0, m1, m2)
            if code >= 0:
                break
            self._grow(code)
        if not self._pushed:
            self._step = direct(self._step)
        if code == v.A_START and self.frame_id is None:
            self.frame_id = frame_id
        self._pushed = True
        verdict = v.PLAIN_VERDICTS[code]
        if reason:
            detail = self._reason_note(reason, t_ns, omega, w, frame_id, self.state[0].stamps)
            verdict = v.Verdict(v.ACTIONS[code], v.REASON_NAMES[reason], detail)
        if ev:
            sat_axis = int(self.state.ev_sat_axis[0])
            for e, bit, key in _EVENTS:
                if ev & bit:
                    self._event_note(e, key, t_ns, w, angular_velocity_covariance, accel,
                                     sat_axis)
            if ev & chain.E_ALIGN:
                self._align_note()
        return verdict, np.array((x, y, z, u)) if got else None

    def _stamp(self, t_ns, w) -> int:
        """``t_ns`` as an int; a stamp that is not an integer is refused (ValueError) unless
        the sample's values are refused first (they are checked before the stamp)."""
        if w is None or not (abs(w[0]) <= self._max_rate and abs(w[1]) <= self._max_rate
                             and abs(w[2]) <= self._max_rate):
            return 0
        if isinstance(t_ns, bool) or not isinstance(t_ns, int | np.integer) or \
                not -2**63 <= int(t_ns) < 2**63:
            raise ValueError(f"t_ns must be an integer number of nanoseconds within int64, got "
                             f"{t_ns!r}")
        return int(t_ns)

    def _grow(self, code: int) -> None:
        """Double the ring the step found full (its entries kept in order from slot 0)."""
        s = self.state[0]
        if code == chain.BIAS_RING_FULL:
            self.bias_ring = grown_ring(self.bias_ring, s.rest_i)
        else:
            al = s.aligner
            if al.rest_i[R_COUNT] == self.align_ring.shape[0]:
                self.align_ring = grown_ring(self.align_ring, al.rest_i)
            if s.align_count == self.align_buffer.shape[0]:
                head, count = int(s.align_head), int(s.align_count)
                order = (head + np.arange(count)) % self.align_buffer.shape[0]
                new = np.zeros(2 * count, self.align_buffer.dtype).view(np.recarray)
                new[:count] = self.align_buffer[order]
                self.align_buffer, s.align_head = new, 0

    # ------------------------------------------------------------------ words
    # texts are made here, at the edge, from the step's codes: the first per reason is kept
    def _reason_note(self, reason: int, t_ns, omega, w, frame_id, figures) -> str:
        """The validator's words for ``reason`` (its figures from the step)."""
        name = v.REASON_NAMES[reason]
        if name == v.NON_FINITE and w is None:
            text = f"not numbers: {omega!r}"
        else:
            text = v.reason_words(name, t_ns, w, frame_id, self.frame_id, figures,
                                  self.config.max_rate_rad_s, self.config.max_gap_ns)
        self.details.setdefault(name, text)
        return text

    def _event_note(self, e: int, key: str, t_ns, w, covariance, accel, axis: int) -> None:
        """The words of the chain's event ``e`` (:data:`.chain.EV_*`) at a sample."""
        if key in self.details:
            return
        if e == chain.EV_INVALID_COV:
            text = invalid_covariance_note(covariance)
        elif e == chain.EV_INVALID_ACCEL:
            text = (f"accelerometer sample {_values(accel)} is not 3 finite numbers: not used "
                    "for rests or aiding")
        elif e == chain.EV_SATURATED:
            text = saturation_note(axis, w[axis])
        elif e == chain.EV_FALLBACK:
            text = rate_fit_note(int(t_ns))
        elif e == chain.EV_MAG_MISSING:
            text = f"no field sample at stamp {int(t_ns)} (none within mag_max_age_s)"
        else:
            text = unknown_noise_note(self.config)
        self.details[key] = text

    def _align_note(self) -> None:
        """:attr:`alignment_error` from the step's code."""
        s = self.state[0]
        code = int(s.align_error)
        if code == 1:
            self.alignment_error = "alignment needs the accelerometer: no usable linear_acceleration"
        else:
            self.alignment_error = failure_words(s.aligner, code - 1) if code else None

    # ------------------------------------------------------------------ a whole recording
    def run(self, t_ns, omega, frame_id: str | list[str] | None = "",
            angular_velocity_covariance=None, accel=None, mag=None,
            empty=np.empty) -> StreamResult:
        """All samples of a recording, in file order, on a fresh stream: the step of
        :meth:`push` in a compiled loop over the rows (the same code, the same numbers).
        Arguments as push()'s, one row per sample (``mag`` rows of NaN: no field;
        ``frame_id`` one for all or one per sample); ``empty(shape, dtype)`` allocates the
        arrays of the recording's length.  ValueError when levelling cannot align."""
        if self._pushed:
            raise ValueError("run() needs a fresh AttitudeStream (it replays a whole recording)")
        t = np.asarray(t_ns)
        w = np.asarray(omega, dtype=np.float64)
        n = w.shape[0]
        if t.ndim != 1 or not (np.issubdtype(t.dtype, np.integer) or t.size == 0) or \
                w.shape != (t.shape[0], 3):
            raise ValueError(f"t_ns must be a 1-D integer array of nanoseconds and omega must "
                             f"have shape (N, 3); got {t.dtype} {t.shape} and shape {w.shape}")
        if t.dtype.kind == "u" and t.size and int(t.max()) >= 2**63:
            raise ValueError(f"t_ns must be nanoseconds within int64, got {int(t.max())}")
        # C-contiguous rows: what the loop was compiled for (precompiled: exactly those types)
        t, w = np.ascontiguousarray(t, np.int64), np.ascontiguousarray(w)
        cov, acc = recording_arrays(n, angular_velocity_covariance, accel)
        ms, mg = _field_rows(mag, n, self.config.aiding is Aiding.MAGNETOMETER)
        codes, names = v._frame_codes(frame_id, n)
        frames = np.zeros(n, np.int64) if codes is None else codes
        nav_rates = None
        if self.nav is not None and self.nav.series_length() is not None:
            if self.nav.series_length() != n:
                raise ValueError(f"nav time series must have one row per sample ({n}), got "
                                 f"{self.nav.series_length()}")
            nav_rates = self.nav.rate_enu(n)
        action = empty(n, np.int8)
        got, q = empty(n, np.int64), empty((n, 4), np.float64)
        var, known = empty((n, 3), np.float64), empty(n, np.bool_)
        first_row = np.full(chain.N_EVENTS, -1, np.int64)
        first_fig = np.zeros((chain.N_EVENTS, 5), np.int64)
        loop = precompiled(chain.run_rows) or compiled(chain.run_rows)
        rest = (acc is not None, _ZERO3x1 if acc is None else acc, cov is not None,
                _ZERO9x1 if cov is None else cov, mg is not None, ms,
                _ZERO3x1 if mg is None else mg, action, got, q, var, known, first_row,
                first_fig)
        k = m = 0
        locked = -1
        step_rows = n if nav_rates is None else 1
        while k < n:
            if nav_rates is not None:
                self.state.nav_rate[0] = nav_rates[k]
            stop = min(k + step_rows, n)
            r, m, locked = loop(self.coef, self.state, self.bias_ring, self.align_ring,
                                self.align_buffer, k, t[:stop], w, frames, locked, *rest, m)
            if r < stop:
                self._grow(chain.BIAS_RING_FULL if self.state.rest_i[0][R_COUNT]
                           == self.bias_ring.shape[0] else chain.ALIGN_RING_FULL)
            k = r
        self.frame_id = names[locked] if locked >= 0 else None
        self._pushed = True
        for reason in range(1, len(v.REASON_NAMES)):  # the words of each event's first row
            k = int(first_row[reason])
            if k >= 0:
                self._reason_note(reason, int(t[k]), w[k], tuple(w[k].tolist()),
                                  names[int(frames[k])], first_fig[reason])
        for e, _, key in _EVENTS:
            k = int(first_row[e])
            if k >= 0:
                self._event_note(e, key, t[k], w[k], None if cov is None else cov[k],
                                 None if acc is None else acc[k], int(first_fig[e, 0]))
        self._align_note()
        if self.state.phase[0] != chain.RUNNING:
            raise ValueError(self.alignment_error or (
                f"cannot align: no rest of at least {self.config.min_rest_s:g} s followed by "
                "motion in the recording (initial_attitude_source 'level' needs the IMU still "
                "at the start)"))
        any_known = bool(known[:m].any())
        return StreamResult(got[:m], q[:m], var[:m] if any_known else None,
                            known[:m] if any_known else None, action, self.counts,
                            self.time_jump_resets, dict(self.details), self.bias_report,
                            self.alignment)


_ZERO9 = np.zeros(9)
_ZERO9x1 = np.zeros((1, 9))
_ZERO3x1 = np.zeros((1, 3))
_F64 = np.dtype(np.float64)


def _floats(x) -> tuple[float, float, float] | None:
    """3 floats of a sample (NaN stays NaN), or None when it is not 3 numbers."""
    if type(x) is np.ndarray:
        if x.dtype is _F64 and x.shape == (3,):  # a message's array: the common case
            a, b, c = x.tolist()
            return a, b, c
        if x.dtype.kind not in "iuf":
            return None
    elif isinstance(x, str | bytes | dict):
        return None
    try:
        a, b, c = x.tolist() if type(x) is np.ndarray and x.ndim == 1 else x
        if isinstance(a, str | bytes) or isinstance(b, str | bytes) or isinstance(c, str | bytes):
            return None
        return float(a), float(b), float(c)
    except (TypeError, ValueError, OverflowError):
        return None


def _covariance_row(covariance) -> np.ndarray:
    """A covariance as a writable contiguous float64 array of 9 (what the step was compiled
    for; a message's array as is), NaN when it is not 9 numbers (judged invalid)."""
    c = covariance
    if type(c) is np.ndarray and c.dtype == np.float64 and c.shape == (9,) and \
            c.flags.c_contiguous and c.flags.writeable:
        return c
    try:  # (text and mappings are refused here too)
        c = np.array(covariance, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError, OverflowError):
        return np.full(9, np.nan)
    return c if c.shape == (9,) else np.full(9, np.nan)


def _field(mag) -> tuple[int, tuple | None]:
    """(state, 3 floats) of a magnetometer sample: absent (None or a row of NaN), not 3 finite
    numbers, or given."""
    m = None if mag is None else _floats(mag)
    if m is None:
        return (MAG_ABSENT if mag is None else MAG_NOT_FLOATS), None
    if math.isfinite(m[0]) and math.isfinite(m[1]) and math.isfinite(m[2]):
        return MAG_GIVEN, m
    if math.isnan(m[0]) and math.isnan(m[1]) and math.isnan(m[2]):
        return MAG_ABSENT, None  # a row of NaN: no field at this sample
    return MAG_NOT_FLOATS, None


def _field_rows(mag, n: int, use: bool):
    """Per-row field states (N,) and the field (N, 3) of a recording (:func:`_field`)."""
    mg = _recording_rows(mag, n, 3, "mag")
    ms = np.full(n, MAG_ABSENT, np.int64)
    if mg is None or not use:
        return ms, None
    finite = np.isfinite(mg).all(axis=1)
    ms[finite] = MAG_GIVEN
    ms[~finite & ~np.isnan(mg).all(axis=1)] = MAG_NOT_FLOATS
    return ms, mg


def _recording_rows(x, n: int, width: int, name: str) -> np.ndarray | None:
    """``x`` (None stays None) as a contiguous float array (n, width), or ValueError."""
    if x is None:
        return None
    a = np.ascontiguousarray(x, dtype=np.float64)
    if a.shape != (n, width):
        raise ValueError(f"{name} must have shape ({n}, {width}), got {a.shape}")
    return a


def recording_arrays(n: int, angular_velocity_covariance, accel):
    """``(covariance (n, 9) or None, accel (n, 3) or None)`` of a recording of n samples."""
    return (_recording_rows(angular_velocity_covariance, n, 9, "angular_velocity_covariance"),
            _recording_rows(accel, n, 3, "accel"))


def covariance_rows(cov: np.ndarray, valid: np.ndarray, counts: dict, details: dict):
    """Per-axis gyro variances (M, 3) and whether each is known (M,) for the accepted rows
    ``valid`` of ``cov`` (N, 9), by the causal step's verdict; the invalid ones counted in
    ``counts``, the first described in ``details``."""
    c = np.asarray(cov, dtype=np.float64)
    var_all, code_all = _verdicts(c)
    code = rows(code_all, valid)
    inv = code == chain.COV_INVALID
    counts[INVALID_COVARIANCE] = int(np.count_nonzero(inv))
    if counts[INVALID_COVARIANCE]:
        k = int(valid[np.flatnonzero(inv)[0]])
        details.setdefault(INVALID_COVARIANCE, invalid_covariance_note(cov[k]))
    return rows(var_all, valid), code == chain.COV_KNOWN


#: past this many distinct covariance rows the verdicts run compiled
_FEW_DISTINCT_ROWS = 4096


def _verdicts(c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The covariance verdicts (:func:`.chain.covariance_verdicts`) of every row of ``c``
    (N, 9), judged once per distinct row (by its bits): a driver sends one covariance, or a
    few, so the interpreter judges them and a replay that runs no other compiled code does
    not load numba (two thirds of a second in a fresh process)."""
    if c.shape[0] > 1 and c.strides[0] == 0:  # one row repeated (a broadcast view)
        var, code = _judge(c[:1], chain.covariance_verdicts)
        return np.broadcast_to(var, (c.shape[0], 3)), np.broadcast_to(code, c.shape[:1])
    bits = np.ascontiguousarray(c).view(np.dtype((np.void, c.dtype.itemsize * c.shape[1])))
    distinct, first, inverse = np.unique(bits[:, 0], return_index=True, return_inverse=True)
    if distinct.size > _FEW_DISTINCT_ROWS:
        return _judge(c, compiled(chain.covariance_verdicts))
    var, code = _judge(c[first], chain.covariance_verdicts)
    return var[inverse], code[inverse]


def _judge(c: np.ndarray, loop) -> tuple[np.ndarray, np.ndarray]:
    var = np.zeros((c.shape[0], 3))
    code = np.zeros(c.shape[0], np.int8)
    loop(np.ascontiguousarray(c), var, code)
    return var, code


def rows(a: np.ndarray, index: np.ndarray, empty=None) -> np.ndarray:
    """``a[index]`` for sorted row indices: a view when they are consecutive (the usual
    case), else a copy (into ``empty(shape, dtype)`` when given)."""
    if index.size and int(index[-1]) - int(index[0]) == index.size - 1:
        return a[int(index[0]):int(index[-1]) + 1]
    if empty is None or a.strides[0] == 0:
        return a[index]
    return np.take(a, index, axis=0, out=empty((index.size, *a.shape[1:]), a.dtype))


def usable_accel(a: np.ndarray) -> np.ndarray:
    """Rows of specific force (M, 3) that are finite and within ACCEL_ABSURD (one pass:
    NaN fails the comparison, as inf does)."""
    if v.all_within(a, ACCEL_ABSURD):
        return np.ones(a.shape[0], dtype=bool)
    with np.errstate(invalid="ignore"):
        return (np.abs(a) <= ACCEL_ABSURD).all(axis=1)


def _unit_quat(q) -> np.ndarray:
    try:
        a = np.asarray(q, dtype=np.float64)
    except (TypeError, ValueError):
        a = np.full(1, np.nan)
    if a.shape != (4,) or not np.all(np.isfinite(a)) or not np.any(a != 0):
        raise SettingError("initial_attitude", "initial_attitude must be 4 finite numbers, not "
                           f"all zero; got {q!r}")
    # scaled first: the norm of (1e300, 0, 0, 1) would overflow
    return quat_normalize(a / np.max(np.abs(a)))


def nav_rows(nav: NavFrame | None, index: np.ndarray, n: int) -> NavFrame | None:
    """``nav`` restricted to the input rows ``index`` (time series of length n are sliced)."""
    if nav is None:
        return None
    changes = {}
    for f in fields(nav):
        a = np.asarray(getattr(nav, f.name))
        if a.ndim >= 1 and a.shape[0] == n and not (f.name == "velocity_enu" and a.ndim == 1):
            changes[f.name] = a[index]
    return replace(nav, **changes) if changes else nav


def compile_kernels(config: StreamConfig | None = None, algorithm: str | None = None) -> None:
    """Compile (or load from numba's cache) what the chain and the offline estimator's loops run
    compiled, so that no sample waits for the compiler: a synthetic recording (rest, turn,
    rest) run and pushed through a stream with ``config``, or with every aiding mode (from the
    given attitude: a levelling start might never align on it; its kernels are the same)."""
    n = 800
    t = 1_000_000_000 + np.arange(n, dtype=np.int64) * 5_000_000
    rng = np.random.default_rng(0)
    w = 1e-3 * rng.standard_normal((n, 3))
    w[300:500, 2] += 0.5
    a = np.array([0.0, 0.0, STANDARD_GRAVITY]) + 0.01 * rng.standard_normal((n, 3))
    mag = np.array([2e-5, 0.0, -4e-5]) + 1e-8 * rng.standard_normal((n, 3))
    cov = np.tile(np.diag([1e-6] * 3).reshape(9), (n, 1))
    configs = [config] if config is not None else [
        StreamConfig(aiding=aiding, gyro_noise_density=1e-4, mag_hard_iron_estimate=True)
        for aiding in Aiding]
    level_quaternion((0.0, 0.0, STANDARD_GRAVITY), 0.0)  # levelling's own call (alignment)
    detect_rest(t, w, a)  # the offline estimator's rest loop (one form with or without accel)
    v.classify(t, w, "imu")  # its validator's loop
    for cfg in configs:
        cfg = replace(cfg, initial_attitude_source=InitialAttitudeSource.PARAMETER,
                      heading_source=HeadingSource.PARAMETER)
        AttitudeStream(algorithm or DEFAULT_ALGORITHM, config=cfg).run(t, w, "imu", cov, a, mag)
        s = AttitudeStream(algorithm or DEFAULT_ALGORITHM, config=cfg)
        for k in range(3):  # push(): the step called from Python (the node's path)
            s.push(int(t[k]), w[k], "imu", cov[k], a[k], mag[k])
