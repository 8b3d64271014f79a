"""The attitude estimator shared by the live node and offline replay: a chain of stages.

Every Imu sample passes the stages in one order (the numbered steps of :meth:`AttitudeStream.push`):

1. **validate** (:mod:`.validation`): non-finite rates, rates beyond ``max_rate_rad_s``, zero,
   duplicate and out-of-order stamps and a changed ``frame_id`` are skipped and counted by
   reason; a forward step longer than ``max_gap_s`` is a gap (not integrated across: the attitude
   is held, the time base restarts); a backward jump longer than ``time_jump_threshold_s`` resets
   the attitude to the initial one.  An accelerometer sample that is not finite or absurd is
   counted (``invalid_accel``) and not used; a gap, a jump or such a sample breaks the rest
   windows (a rest never spans one).
2. **rest → gyro bias** (:mod:`.rest`, :mod:`.gyro_bias`): ``none`` | ``parameter`` | ``auto``
   (zero-rate updates at rests, Earth rate taken out when the latitude is known); with a given
   initial attitude and a stream that rests from its start (within one rest window), the first
   estimate is applied back to the start — the attitude is corrected by ``−Δb·Δt``, as the still
   body did not turn.
3. **alignment** (:mod:`.alignment`, ``initial_attitude_source: level``): no attitude while
   :attr:`StreamState.phase` is ``aligning``; when the first rest of ``min_rest_s`` ends, the
   attitude starts from the levelled one with the samples since the last rest sample integrated.
4. **aiding** (:mod:`.gravity_aiding`, ``aiding: gravity``): a rate correction toward the
   accelerometer's vertical.
5. **integrate** ``ω − bias (+ correction)`` (:mod:`.streaming`); every attitude handed out is
   finite and unit (a non-finite update restores the last good attitude, restarts the time base
   and counts an ``integrator_error``).
6. **covariance** (:mod:`.covariance`): the per-axis attitude/bias error covariance (gyro noise
   ``σ_ω² dt²`` from the diagonal of ``angular_velocity_covariance`` or ``N² dt``, bias
   uncertainty, zero-rate updates, alignment, aiding); a covariance that says "no estimate"
   (REP-145: :func:`gyro_variances`) adds nothing, an invalid one is counted.

Each stage keeps its own state (the validator, the bias estimator, the aligner, the aiding
filter, the integrator, the covariance); what the chain itself carries between samples is one
visible :class:`StreamState`.  :meth:`AttitudeStream.push` takes one sample through the chain
(the node); :meth:`AttitudeStream.run` is push() over a whole recording (replay).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field, fields, replace

import numpy as np

from gyro_attitude.core.attitude import (
    DEFAULT_ALGORITHM,
    NavFrame,
    StreamingIntegrator,
    get_algorithm,
)
from gyro_attitude.core.attitude import validation as v
from gyro_attitude.core.attitude.ahrs import (
    MAG_ABSENT,
    MAG_GIVEN,
    MAG_NOT_FLOATS,
    AhrsFilter,
    AhrsParams,
    _as_floats,
)
from gyro_attitude.core.attitude.alignment import (
    AlignmentResult,
    StaticAligner,
    check_gyrocompass_feasible,
    level_quaternion,
)
from gyro_attitude.core.attitude.covariance import AttitudeCovariance
from gyro_attitude.core.attitude.gravity_aiding import GravityAiding
from gyro_attitude.core.attitude.gyro_bias import GyroBiasEstimator, GyroBiasReport
from gyro_attitude.core.attitude.modes import (
    Aiding,
    Frame,
    GyroBiasMode,
    HeadingSource,
    InitialAttitudeSource,
    Phase,
    SettingError,
)
from gyro_attitude.core.attitude.sample_step import (
    AFTER_BIAS,
    BIAS_REFUSED,
    DONE,
    NOT_FINITE,
    NOT_PLAIN,
    push_sample,
    saturation_step,
)
from gyro_attitude.core.attitude.settings import StreamConfig
from gyro_attitude.core.earth import STANDARD_GRAVITY
from gyro_attitude.core.jit import compiled, direct
from gyro_attitude.core.rotation import (
    quat_from_rotvec,
    quat_multiply,
    quat_normalize,
    quat_rotate,
)

__all__ = ["AttitudeStream", "StreamConfig", "StreamResult", "StreamState", "bias_summary",
           "compile_kernels", "gyro_variances"]


INVALID_COVARIANCE = "invalid_covariance"
# (rad/s)²: a gyro variance beyond this (σ = 1000 rad/s) is no estimate of a real gyro's noise,
# and summed over an attitude it would overflow the orientation variance
MAX_GYRO_VARIANCE = 1.0e6
INTEGRATOR_ERROR = "integrator_error"
INVALID_ACCEL = "invalid_accel"
# aiding magnetometer: Imu samples with no field within mag_max_age_s, fields that are not a
# reading (non-finite, absurd, zero), fields that disagree with the reference (disturbances)
MAG_MISSING = "mag_missing"
INVALID_MAG = "invalid_mag"
MAG_DISTURBED = "mag_disturbed"
# m/s²: a specific force beyond this (1e5 g) is no accelerometer reading
ACCEL_ABSURD = 1e6
# accepted samples pinned at a repeated extreme: a clipped (saturated) gyro
SATURATED = "saturated"
# rad/s: a value repeated at the largest magnitude seen is a clip only this high (every gyro's
# range is above 2 rad/s; a quantized gyro at rest repeats its small values)
SATURATION_MIN_RAD_S = 1.0
# intervals whose rate fit could not be trusted (the samples alias the motion, or the fit leaves
# their range): integrated toward the exponential map (interpolation.untrusted_fits)
RATE_FIT_FALLBACK = "rate_fit_fallback"
EXTRA_COUNTS = (INVALID_COVARIANCE, INVALID_ACCEL, INTEGRATOR_ERROR, SATURATED, RATE_FIT_FALLBACK)
GYRO_NOISE_UNKNOWN = "gyro_noise_unknown"  # a detail (said once), not a count


def field_absent(mag) -> bool:
    """Whether a sample has no magnetic field: none given, or a row of NaN."""
    return mag is None or (isinstance(mag, np.ndarray) and mag.shape == (3,)
                           and bool(np.isnan(mag).all()))


def _values(x) -> str:
    """A sample's values as a list of floats in a log line (its repr when they are not
    numbers): the same text from push() and from run()."""
    try:
        return str(np.asarray(x, dtype=np.float64).reshape(-1).tolist())
    except (TypeError, ValueError):
        return repr(x)


def invalid_accel_note(accel) -> str:
    return (f"accelerometer sample {_values(accel)} is not 3 finite numbers: not used for "
            "rests or aiding")


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

ALIGNING, RUNNING, FAILED = Phase.ALIGNING, Phase.RUNNING, Phase.FAILED
_ACCEPTED, _STARTED = v.Verdict(v.ACCEPT, "", ""), v.Verdict(v.START, "", "")


def gyro_variances(covariance) -> tuple[tuple[float, float, float] | None, bool]:
    """(per-axis variances, invalid) of a row-major 3x3 ``angular_velocity_covariance``.

    ``None, False`` when it carries no estimate (REP-145, :func:`.validation.no_estimate`) or is
    all zeros (unknown); ``None, True`` when its diagonal is non-finite, negative or beyond
    MAX_GYRO_VARIANCE (treated as unknown).  Plain floats: it runs once per live sample.
    """
    if covariance is None:
        return None, False
    return row_variances(np.asarray(covariance, dtype=np.float64).reshape(-1).tolist())


def row_variances(c: list) -> tuple[tuple[float, float, float] | None, bool]:
    """:func:`gyro_variances` of a covariance already made a list of floats."""
    if len(c) != 9:
        return None, True
    if v.no_estimate(c):
        return None, False
    d = c[0], c[4], c[8]
    # a chained comparison is False for NaN, so this refuses non-finite values too
    if not all(0.0 <= x <= MAX_GYRO_VARIANCE for x in d):
        return None, True
    if not any(c):
        return None, False
    return d, False


def gyro_variances_array(covariance: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Array form of :func:`gyro_variances` for (N, 9): (variances (N, 3), known, invalid)."""
    c = np.asarray(covariance, dtype=np.float64)
    if c.ndim == 2 and c.shape[0] > 1 and c.strides[0] == 0:
        # one row repeated (a broadcast view: every message carried the same covariance)
        var, known, invalid = gyro_variances_array(c[:1])
        n = c.shape[0]
        return (np.broadcast_to(var, (n, 3)), np.broadcast_to(known, (n,)),
                np.broadcast_to(invalid, (n,)))
    d = c[:, [0, 4, 8]]
    no_estimate = v.no_estimate(c)
    with np.errstate(invalid="ignore"):
        invalid = ~no_estimate & (~np.isfinite(d).all(axis=1) | (d < 0).any(axis=1)
                                  | (d > MAX_GYRO_VARIANCE).any(axis=1))
        zeros = ~np.any(c != 0, axis=1)
    known = ~no_estimate & ~invalid & ~zeros
    return np.where(known[:, None], d, 0.0), known, invalid


def bias_summary(report: GyroBiasReport) -> str:
    """One line on the gyro bias for a summary or a log (rad/s and °/s)."""
    if report.mode != GyroBiasMode.AUTO or report.rests_used == 0:
        return f"gyro bias {report.mode}: {np.round(report.bias, 6).tolist()} rad/s ({report.note})"
    return (f"gyro bias auto: {np.round(report.bias, 6).tolist()} rad/s "
            f"(± {np.round(report.standard_error, 7).tolist()}, {report.rests_used} rest(s), "
            f"{report.rest_samples} samples); {report.note}")


@dataclass
class StreamResult:
    """Attitudes of :meth:`AttitudeStream.run` over N input samples.

    ``index`` (M,) input positions that got an attitude (the others were skipped, or came
    while aligning); ``q`` (M, 4) scalar-last, finite and unit; ``variance`` (M, 3) per-axis
    orientation variance [rad²] and ``variance_known`` (M,) whether it is an estimate by that
    row (None, None when nothing gives one); ``action`` (N,) verdict codes
    (:data:`.validation.ACTION_CODES`); ``counts`` per reason (rejections, ``gap``,
    ``invalid_covariance``, ``invalid_accel``, ``integrator_error``); ``time_jump_resets``;
    ``details`` the first log line per reason; ``bias`` the final :class:`GyroBiasReport`;
    ``alignment`` the :class:`AlignmentResult` (``level``) or None.
    """

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
    notes: list[str] = field(default_factory=list)  # what the estimator did, in words

    @property
    def skipped(self) -> int:
        return int(self.action.shape[0] - self.index.shape[0])


@dataclass
class StreamState:
    """What the chain carries between samples (each stage keeps its own state besides).

    ``q`` the last attitude handed out, 4 floats (the initial one before any: the per-sample
    stages take plain floats); ``q_initial`` the attitude
    a time-jump reset goes back to; ``resume_q`` the attitude to go on from after an integrator
    error; ``phase``; ``start_t_ns`` the first accepted stamp; ``accel_present`` whether the
    last usable sample had an accelerometer (None after an unusable one); ``first_rest_pending``
    whether the first bias estimate may still be applied back to the start;
    ``variance_known`` whether anything gives an orientation variance yet; ``counts`` and
    ``details`` of the stages' own events (:data:`EXTRA_COUNTS`); ``aided_seen`` the aiding
    filter's sample count at the last covariance update.
    """

    q: tuple[float, float, float, float]
    q_initial: np.ndarray
    phase: Phase = RUNNING
    resume_q: tuple | None = None
    start_t_ns: int | None = None
    accel_present: bool | None = None
    first_rest_pending: bool = False
    variance_known: bool = False
    counts: dict[str, int] = field(default_factory=lambda: dict.fromkeys(EXTRA_COUNTS, 0))
    details: dict[str, str] = field(default_factory=dict)
    aided_seen: int = 0
    # the saturation check's state: per axis the largest |ω| accepted so far (0:3) and the
    # last accepted ω (3:6)
    sat: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 0.0] + [math.nan] * 3))

    def count(self, key: str, detail: str) -> None:
        self.counts[key] += 1
        self.details.setdefault(key, detail)

    def count_fit_fallbacks(self, n: int, t_ns: int) -> None:
        """``n`` intervals whose rate fit fell back, the first of them ending at ``t_ns``."""
        self.counts[RATE_FIT_FALLBACK] += n
        self.details.setdefault(RATE_FIT_FALLBACK, rate_fit_note(t_ns))


class AttitudeStream:
    """Imu samples in, attitude out, through the chain of the module docstring.

    ``algorithm`` a name from the registry (an offline one serves the array form of :meth:`run`
    only: it needs samples after each interval, so :meth:`push` refuses it); ``q0`` the initial
    attitude (also the one a time jump resets to; levelling replaces it); ``nav`` a
    :class:`NavFrame` for q_nb (Earth and transport rate removed; default: the one of
    ``config`` with frame enu) or None for q_ib; ``config`` the settings.  The latitude is
    known with a nav frame or for gyrocompassing; then the Earth rate is taken out of the bias
    estimate at the current attitude.
    """

    def __init__(self, algorithm: str = DEFAULT_ALGORITHM, q0=(0.0, 0.0, 0.0, 1.0),
                 nav: NavFrame | None = None, config: StreamConfig | None = None):
        self._init_args = (algorithm, q0, nav, config)
        self.config = cfg = config if config is not None else StreamConfig()
        q_initial = _unit_quat(q0)
        if nav is None and cfg.frame is Frame.ENU:
            nav = cfg.nav_frame()
        self.nav = nav
        self.algorithm = algorithm
        lat = nav.latitude_rad if nav is not None else (
            cfg.latitude_rad if cfg.latitude_known else None)
        self.latitude_rad = None if lat is None else float(np.asarray(lat).reshape(-1)[0])
        if cfg.heading_source is HeadingSource.GYROCOMPASS:
            check_gyrocompass_feasible(cfg.gyro_bias_sigma_rad_s, self.latitude_rad,
                                       cfg.heading_error_limit_deg)
        # -- the stages, in chain order
        self.validator = v.ImuStreamValidator(cfg.check_config())
        self.intervals = v.IntervalStatistics(window=2000)
        fixed = cfg.gyro_bias_rad_s if cfg.gyro_bias is GyroBiasMode.PARAMETER else None
        self.bias_estimator = GyroBiasEstimator(
            cfg.gyro_bias, fixed, min_rest_s=cfg.min_rest_s, latitude_rad=self.latitude_rad,
            rest=cfg.rest_params())
        self.aligner: StaticAligner | None = self._new_aligner() if cfg.levelling else None
        self._align_buffer: deque = deque()
        self.aiding = None
        self._mag = None  # the current sample's magnetic field (aiding magnetometer)
        self._mag_missing = 0
        if cfg.aiding is Aiding.GRAVITY:
            self.aiding = GravityAiding(cfg.aiding_kp, cfg.aiding_ki, cfg.aiding_accel_tol,
                                        cfg.aiding_rate_max,
                                        accel_lowpass_s=cfg.aiding_accel_lowpass_s)
        elif cfg.aiding in (Aiding.TILT, Aiding.MAGNETOMETER):
            self.aiding = AhrsFilter(AhrsParams.from_config(cfg))
        if not get_algorithm(algorithm).causal:
            raise ValueError(f"{algorithm} is an offline algorithm (it needs the samples after "
                             "each interval): the causal estimator takes a causal one (or use "
                             "the offline estimator)")
        self.integrator = StreamingIntegrator(algorithm=algorithm, q0=q_initial, nav=nav)
        self.covariance = AttitudeCovariance(cfg.initial_attitude_variance,
                                             cfg.gyro_bias_sigma_rad_s, cfg.gyro_bias_rw)
        self._n2 = cfg.gyro_noise_density * cfg.gyro_noise_density
        # -- the chain's own state
        self.state = StreamState(
            q=tuple(q_initial.tolist()), q_initial=q_initial, phase=ALIGNING if cfg.levelling else RUNNING,
            first_rest_pending=cfg.gyro_bias is GyroBiasMode.AUTO and not cfg.levelling,
            variance_known=bool(cfg.gyro_noise_density > 0 or cfg.gyro_bias_sigma_rad_s > 0
                                or cfg.levelling))
        self.alignment: AlignmentResult | None = None
        self.alignment_error: str | None = None
        # push()'s compiled form for the samples nothing special happens to (None where a stage
        # has no kernel: another integrator, a nav frame with time series, another aiding)
        self._fast = _PushKernel.for_stream(self)

    def _new_aligner(self) -> StaticAligner:
        cfg = self.config
        gc = cfg.heading_source is HeadingSource.GYROCOMPASS
        return StaticAligner(
            cfg.initial_heading_deg, gyrocompass=gc, latitude_rad=self.latitude_rad if gc else None,
            gyro_bias=(cfg.gyro_bias_rad_s if cfg.gyro_bias is GyroBiasMode.PARAMETER
                       else (0.0, 0.0, 0.0)),
            gyro_bias_sigma=cfg.gyro_bias_sigma_rad_s if gc else None,
            accel_bias_sigma=cfg.accel_bias_sigma,
            heading_error_limit_deg=cfg.heading_error_limit_deg, min_rest_s=cfg.min_rest_s,
            rest=cfg.rest_params(), mag_heading=cfg.aiding is Aiding.MAGNETOMETER,
            declination_deg=cfg.magnetic_declination_deg, hard_iron_t=cfg.mag_hard_iron_t)

    # ------------------------------------------------------------------ queries
    @property
    def phase(self) -> Phase:
        return self.state.phase

    @property
    def q_initial(self) -> np.ndarray:
        return self.state.q_initial

    @property
    def details(self) -> dict[str, str]:
        return self.state.details

    @property
    def counts(self) -> dict[str, int]:
        out = {**self.validator.counts, **self.state.counts,
               v.MISSING_SAMPLES: self.validator.missing_samples}
        if self.config.aiding is Aiding.MAGNETOMETER:
            out[MAG_MISSING] = self._mag_missing
            out[INVALID_MAG] = self.aiding.mag_invalid
            out[MAG_DISTURBED] = self.aiding.mag_disturbed
            for key, text in ((INVALID_MAG, "a magnetic field sample not finite, beyond 10 mT "
                                            "or below 0.1 µT"),
                              (MAG_DISTURBED, "a field whose norm or dip is off the reference")):
                if out[key]:
                    self.state.details.setdefault(key, text)
        return out

    @property
    def rejected_total(self) -> int:
        return self.validator.rejected_total

    @property
    def accepted(self) -> int:
        return self.validator.accepted

    @property
    def time_jump_resets(self) -> int:
        return self.validator.time_jump_resets

    @property
    def last_t_ns(self) -> int | None:
        return self.validator.last_t_ns

    @property
    def quaternion(self) -> np.ndarray:
        return np.array(self.state.q, dtype=np.float64)

    @property
    def variance(self) -> np.ndarray | None:
        """Per-axis orientation variance [rad²]; None while nothing gives an estimate."""
        return self.covariance.tt.copy() if self.state.variance_known else None

    @property
    def bias_report(self) -> GyroBiasReport:
        return self.bias_estimator.report()

    # ------------------------------------------------------------------ settings
    def set_config(self, config: StreamConfig) -> None:
        """New validation thresholds from the next sample on (state kept; the bias, alignment
        and aiding settings stay those of construction)."""
        self.config = replace(self.config, max_gap_s=config.max_gap_s,
                              time_jump_threshold_s=config.time_jump_threshold_s,
                              max_rate_rad_s=config.max_rate_rad_s,
                              max_missing_samples=config.max_missing_samples)
        self.validator.config = self.config.check_config()
        self._fast = _PushKernel.for_stream(self)

    def set_algorithm(self, algorithm: str) -> None:
        """Switch the algorithm, keeping the attitude and the time base (raises ValueError and
        changes nothing for an unknown or unsuitable algorithm)."""
        integrator = StreamingIntegrator(algorithm=algorithm, q0=self.integrator.quaternion,
                                         nav=self.nav, t0_ns=self.integrator.last_t_ns)
        self.integrator = integrator
        self.algorithm = algorithm
        self._fast = _PushKernel.for_stream(self)

    def update_nav(self, nav: NavFrame) -> None:
        """Constant nav frame from the next sample on (see StreamingIntegrator.update_nav)."""
        self.integrator.update_nav(nav)
        self.nav = nav
        self._fast = _PushKernel.for_stream(self)

    def restart(self, q0=None) -> None:
        """Forget the time base (and the locked frame): the next sample starts from ``q0``
        (which also becomes the initial attitude), or from the initial attitude."""
        st = self.state
        if q0 is not None:
            st.q_initial = _unit_quat(q0)
            st.q = tuple(st.q_initial.tolist())
        st.resume_q = None
        self.validator.reset()
        self.intervals.clear()
        self._break_windows()

    # ------------------------------------------------------------------ one sample
    def push(self, t_ns: int, omega, frame_id: str = "", angular_velocity_covariance=None,
             accel=None, mag=None) -> tuple[v.Verdict, np.ndarray | None]:
        """One sample through the chain: its verdict and the attitude at ``t_ns`` (None when it
        was skipped or while aligning).  ``accel`` the specific force (3,) m/s² or None; ``mag``
        the magnetic field (3,) tesla time-aligned to ``t_ns`` or None (aiding magnetometer:
        counted ``mag_missing``, heading gyro-only; a field that is not finite, absurd or zero
        is counted ``invalid_mag``, one that disagrees with the reference ``mag_disturbed``)."""
        fast = self._fast
        if fast is not None:
            if out := fast.push(t_ns, omega, frame_id, angular_velocity_covariance, accel, mag):
                return out
            fast.args = None  # the Python steps below may change what it holds
        st = self.state
        # 1. validate
        verdict = self.validator.check(t_ns, omega, frame_id)
        if verdict.rejected:
            st.details.setdefault(verdict.reason, verdict.detail)
            return verdict, None
        t_ns = int(t_ns)
        var = None
        if angular_velocity_covariance is not None:
            var = self._gyro_variance(angular_velocity_covariance)
        if verdict.reason is not None:  # a time jump, a gap, missing samples
            st.details.setdefault(verdict.reason, verdict.detail)
        a = self._accel(accel)
        mag = self._mag_sample(mag, t_ns)
        if st.start_t_ns is None:
            st.start_t_ns = t_ns
        if verdict.action != v.ACCEPT:
            self._break_windows()  # a rest never spans a gap, a jump or a restart
        # the validator took 3 finite numbers: plain floats from here on
        w = tuple(omega.tolist() if isinstance(omega, np.ndarray) else (float(c) for c in omega))
        self._saturation_step(w)
        # 2. rest -> gyro bias
        bias = self._bias_step(t_ns, w, a)
        # 3. alignment
        if st.phase is not RUNNING:
            q = self._align_step(t_ns, w, a, var, bias, mag)
        else:  # 4.-6. aiding, integration, covariance
            verdict, q = self._integrate(verdict, t_ns, (w[0] - bias[0], w[1] - bias[1],
                                                         w[2] - bias[2]), a, var, mag)
        return verdict, None if q is None else np.array(q)

    def _gyro_variance(self, covariance):
        """The sample's per-axis gyro variances as 3 floats, or None (unknown; an invalid
        covariance counted, "no estimate" said once)."""
        var, invalid = gyro_variances(covariance)
        if invalid:
            self.state.count(INVALID_COVARIANCE, invalid_covariance_note(covariance))
            return None
        self._variance_seen(var, covariance)
        return var

    def _variance_seen(self, var, covariance) -> None:
        """A sample's gyro variances ``var`` (None: unknown) from a valid ``covariance``: the
        orientation variance is known from now on, or "no estimate" is said once."""
        st = self.state
        if var is not None:
            st.variance_known = True
        elif covariance is not None and GYRO_NOISE_UNKNOWN not in st.details and \
                v.no_estimate(np.asarray(covariance, dtype=np.float64).reshape(-1)):
            st.details[GYRO_NOISE_UNKNOWN] = unknown_noise_note(self.config)

    def _mag_sample(self, mag, t_ns):
        """The sample's field for the aiding (magnetometer mode), counting absent ones (a row
        of NaN is no sample); the filter checks and counts the values."""
        if self.config.aiding is not Aiding.MAGNETOMETER:
            return None
        if field_absent(mag):
            self._field_missing(t_ns)
            return None
        return mag

    def _field_missing(self, t_ns: int) -> None:
        self._mag_missing += 1
        self.state.details.setdefault(MAG_MISSING, f"no field sample at stamp {t_ns} "
                                                   "(none within mag_max_age_s)")

    def _saturation_step(self, w: tuple) -> None:
        """Count an accepted sample pinned at a repeated extreme (:func:`saturation_step`)."""
        axis = compiled(saturation_step)(self.state.sat, w[0], w[1], w[2], SATURATION_MIN_RAD_S)
        if axis >= 0:
            self.state.count(SATURATED, saturation_note(axis, w[axis]))

    def _accel(self, accel):
        """The sample's specific force as 3 floats, or None (absent or unusable, counted)."""
        st = self.state
        if accel is None:
            a = None
        else:
            try:
                x, y, z = (float(c) for c in (
                    accel.tolist() if isinstance(accel, np.ndarray) and accel.ndim == 1 else accel))
            except (TypeError, ValueError):
                x = y = z = math.nan
            if v.within(x, y, z, ACCEL_ABSURD):  # the compiled step's bound
                a = (x, y, z)
            else:
                st.count(INVALID_ACCEL, invalid_accel_note(accel))
                self._break_windows()
                st.accel_present = None
                return None
        if st.accel_present is not None and (a is not None) != st.accel_present:
            self._break_windows()  # the rest detectors need the accelerometer for all or none
        st.accel_present = a is not None
        return a

    def _break_windows(self) -> None:
        self.bias_estimator.break_window()
        if self.state.phase is ALIGNING:
            self.aligner.break_window()  # alignment needs one unbroken rest
            self._align_buffer.clear()
        if self.aiding is not None:
            self.aiding.last_t_ns = None

    def _bias_step(self, t_ns: int, w: tuple, a) -> tuple:
        """Step 2: the bias (3 floats) to subtract from this sample."""
        est = self.bias_estimator
        if est.mode is not GyroBiasMode.AUTO:
            return est.step(t_ns, w, a)
        previous = est.bias_floats
        try:
            bias = est.step(t_ns, w, a, self._bias_attitude(a))
        except ValueError:  # a value the rest statistics refuse (e.g. > 1e6): no rest here
            est.break_window()
            return est.bias_floats
        if est.updated:
            self._bias_published(previous)
        return bias

    def _bias_attitude(self, a):
        """The attitude the bias stage takes the Earth rate out at (None: it is absorbed): the
        current one, or while aligning levelled from this sample with the given heading."""
        if self.latitude_rad is None:
            return None
        if self.state.phase is RUNNING:
            return self.state.q
        if a is None:
            return None
        try:
            return level_quaternion(a, math.radians(self.config.initial_heading_deg))[0]
        except ValueError:
            return None

    def _bias_published(self, previous: tuple) -> None:
        """The bias stage published a new estimate (a zero-rate update at a rest); with the
        stream still since its start, the first one is applied back to the start."""
        est, st = self.bias_estimator, self.state
        t_prev = self.integrator.last_t_ns
        rest_start = est.open_rest_start_ns
        if st.first_rest_pending and st.phase is RUNNING and rest_start is not None \
                and rest_start - st.start_t_ns <= est.window_ns and t_prev is not None \
                and est.rests_completed == 0:
            # (a full window is needed before the first decision, so the first rest sample
            # is at best the second sample of the stream)
            # Still since the start: the samples so far were integrated with the previous
            # bias; the body did not turn, so the attitude error is the bias change times
            # the elapsed time, a body-frame rotation taken back here.
            bias = est.bias_floats
            elapsed = (t_prev - st.start_t_ns) * 1e-9
            q_fix = quat_multiply(self.integrator.quaternion, quat_from_rotvec(
                -(np.array(bias) - np.array(previous)) * elapsed))
            self.integrator.reset(q_fix, t_prev)
            st.q = tuple(q_fix.tolist())
            self.covariance.first_rest_update(est.standard_error_floats, elapsed)
        else:
            self.covariance.zero_rate_update(est.standard_error_floats)
        st.first_rest_pending = False

    def _align_step(self, t_ns, w, a, var, bias, mag):
        st = self.state
        if st.phase is FAILED:
            return None
        if a is None:
            self.alignment_error = ("alignment needs the accelerometer: no usable "
                                    "linear_acceleration")
            return None
        self.alignment_error = None
        al = self.aligner
        try:
            # the validator took t, w and a (finite, |w| ≤ max_rate ≤ 1e6, |a| ≤ 1e6)
            done = al.update_checked(t_ns, w, a, mag)
        except ValueError:
            self.aligner = self._new_aligner()
            return None
        buf = self._align_buffer
        buf.append((t_ns, w, a, var, mag))
        if not al.rest_open:
            while len(buf) > 1:
                buf.popleft()
        else:  # keep the samples from the last rest sample on: integrated once aligned
            last = al.last_rest_ns
            while buf[0][0] < last:
                buf.popleft()
        if not done:
            return None
        try:
            res = al.result()
        except ValueError as exc:
            st.phase = FAILED
            self.alignment_error = str(exc)
            return None
        entries = list(buf)
        buf.clear()
        return self._aligned(res, entries, bias)

    def _aligned(self, res: AlignmentResult, entries, bias):
        """The alignment is done: start from it and integrate the samples since the last rest
        sample (``entries`` of (t, w, a, var, mag)) with the bias in force now; the attitude
        at the last one."""
        self._start_aligned(res)
        b0, b1, b2 = bias
        q = None
        verdict = _STARTED
        fresh = True
        for tk, wk, ak, vk, mk in entries:
            _, q = self._integrate(verdict, tk, (wk[0] - b0, wk[1] - b1, wk[2] - b2), ak, vk,
                                   mk, fresh)
            verdict, fresh = _ACCEPTED, False
        return q

    def _start_aligned(self, res: AlignmentResult) -> None:
        """The alignment is done: the attitude, its covariance and the integrator start."""
        st = self.state
        self.alignment = res
        self.alignment_error = None
        st.phase = RUNNING
        st.q_initial = res.q_nb
        st.q = tuple(res.q_nb.tolist())
        st.resume_q = None
        self.covariance.align(alignment_variance(res, self.config.initial_attitude_variance))
        if self.integrator is not None:
            self.integrator.reset(res.q_nb, None)
        if self.aiding is not None:
            self.aiding.last_t_ns = None
            if res.heading_source == "magnetometer":
                # the heading is the mean field's over the rest: the filter goes on from it
                m_n = quat_rotate(res.q_nb, res.mean_magnetic_field)
                self.aiding.heading_from_field((res.rest_end_ns - res.rest_start_ns) * 1e-9,
                                               float(np.linalg.norm(m_n)),
                                               math.atan2(-float(m_n[2]),
                                                          math.hypot(m_n[0], m_n[1])))

    def _integrate(self, verdict: v.Verdict, t_ns: int, rate: tuple, a, var, mag=None,
                   fresh: bool = False):
        """Steps 4.-6. of one sample: aiding, integration, covariance; ``(verdict, attitude as
        4 floats)``, or ``(rejection, None)`` on an integrator error.  The one sequential step
        of the chain: :meth:`push` and the loop of :meth:`run` (:mod:`.stream_loop`) both
        take it."""
        st = self.state
        integ = self.integrator
        action = verdict.action
        last_t = integ.last_t_ns
        aid = self.aiding
        try:
            if action == v.ACCEPT:
                if aid is not None:
                    rate = aid.step(t_ns, rate, a, st.q, mag)
                fell_back = integ.fit_fallbacks
                q = integ.advance(t_ns, rate)
                if integ.fit_fallbacks != fell_back:
                    st.count_fit_fallbacks(integ.fit_fallbacks - fell_back, t_ns)
            else:
                if action == v.RESET_TIME_JUMP:
                    q0 = st.q_initial
                    self.covariance.reset_attitude()
                    self.intervals.clear()
                elif action == v.RESTART_AFTER_GAP:
                    st.details.setdefault(v.GAP, verdict.detail)
                    q0 = st.q
                elif fresh:
                    q0 = st.q_initial
                else:  # START
                    q0 = st.q_initial if st.resume_q is None else st.resume_q
                    st.resume_q = None
                integ.reset(q0, None)
                if aid is not None:
                    aid.last_t_ns = None
                    rate = aid.step(t_ns, rate, a, tuple(float(c) for c in q0), mag)
                q = integ.advance(t_ns, rate)
        except ValueError as exc:  # defensive: the validator should have caught it
            return self._integrator_error(verdict, f"integrator refused a sample: {exc}")
        x, y, z, w = q
        if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z) and math.isfinite(w)):
            return self._integrator_error(verdict, "non-finite attitude: last good one restored")
        if action == v.ACCEPT:
            dt = t_ns - last_t
            self.intervals.add(dt)
            dt_s = dt * 1e-9
            # angle random walk: each interval adds an independent angle error of variance
            # σ_ω² dt² per axis (σ_ω² per sample), i.e. N² dt with the noise density N.
            if var is not None:
                d2 = dt_s * dt_s
                qv = (var[0] * d2, var[1] * d2, var[2] * d2)
            else:
                n = self._n2 * dt_s
                qv = (n, n, n)
            cov = self.covariance
            cov.propagate(dt_s, qv)
            if aid is not None and aid.aided_samples != st.aided_seen:
                cov.aid_tilt(aid.kp * dt_s, (self.alignment.level_error_expected
                                             if self.alignment is not None
                                             else self.config.accel_bias_sigma
                                             / STANDARD_GRAVITY) ** 2)
        if aid is not None:
            st.aided_seen = aid.aided_samples
        st.q = q
        return verdict, q

    def _integrator_error(self, verdict: v.Verdict, detail: str):
        st = self.state
        st.count(INTEGRATOR_ERROR, detail)
        st.resume_q = st.q
        self.integrator.reset(st.q, None)
        self.validator.last_t_ns = None  # next sample starts a fresh time base
        if self.aiding is not None:
            self.aiding.last_t_ns = None
        return v.Verdict(v.REJECT, INTEGRATOR_ERROR, detail), None

    # ------------------------------------------------------------------ a whole recording
    def run(self, t_ns, omega, frame_id: str | list[str] | None = "",
            angular_velocity_covariance=None, accel=None, mag=None,
            empty=np.empty) -> StreamResult:
        """All samples of a recording, in file order, on a fresh stream: :meth:`push` sample by
        sample (the one chain), the attitudes gathered into arrays.

        ``t_ns`` (N,) int stamps; ``omega`` (N, 3) rad/s; ``frame_id`` one for all or one per
        sample; ``angular_velocity_covariance`` (N, 9) or None; ``accel`` (N, 3) m/s² or None;
        ``mag`` (N, 3) tesla or None.  ``empty(shape, dtype)`` allocates the arrays of the
        recording's length (default ``np.empty``; replay gives file-backed ones).
        Raises ValueError when levelling cannot align on the recording.
        """
        if self.validator.last_t_ns is not None or self.validator.accepted:
            raise ValueError("run() needs a fresh AttitudeStream (it replays a whole recording)")
        t = np.asarray(t_ns)
        w = np.asarray(omega, dtype=np.float64)
        n = w.shape[0]
        if t.ndim != 1 or not (np.issubdtype(t.dtype, np.integer) or t.size == 0) or \
                w.shape != (t.shape[0], 3):
            raise ValueError(f"t_ns must be a 1-D integer array of nanoseconds and omega must "
                             f"have shape (N, 3); got {t.dtype} {t.shape} and shape {w.shape}")
        cov, acc = recording_arrays(n, angular_velocity_covariance, accel)
        mg = None
        if mag is not None:
            mg = np.asarray(mag, dtype=np.float64)
            if mg.shape != (n, 3):
                raise ValueError(f"mag must have shape ({n}, 3), got {mg.shape}")
        v._frame_codes(frame_id, n)  # one string for all, or one per sample: ValueError else
        frames = [frame_id] * n if frame_id is None or isinstance(frame_id, str) else frame_id
        # a nav time series has one row per input sample: each row's rate goes to the
        # integrator before its sample (a skipped sample's row is never used)
        nav_rates = None
        if self.nav is not None and self.nav.series_length() is not None:
            if self.nav.series_length() != n:
                raise ValueError(f"nav time series must have one row per sample ({n}), got "
                                 f"{self.nav.series_length()}")
            nav_rates = self.nav.rate_enu(n)
        index, qs = empty(n, np.int64), empty((n, 4), np.float64)
        var, known = empty((n, 3), np.float64), empty(n, np.bool_)
        action = empty(n, np.int8)
        codes = v.ACTION_CODES
        push, st, m = self.push, self.state, 0
        for k, tk in enumerate(t.tolist()):
            if nav_rates is not None:
                self.integrator.set_nav_rate(nav_rates[k])
            verdict, q = push(tk, w[k], frames[k] or "", None if cov is None else cov[k],
                              None if acc is None else acc[k], None if mg is None else mg[k])
            action[k] = codes[verdict.action]
            if q is None:
                continue
            index[m], qs[m] = k, q
            known[m] = st.variance_known
            var[m] = self.covariance.tt if st.variance_known else 0.0
            m += 1
        if st.phase is not RUNNING:
            raise ValueError(self.alignment_error or cannot_align(self.config))
        any_known = bool(known[:m].any())
        return StreamResult(index[:m], qs[:m], var[:m] if any_known else None,
                            known[:m] if any_known else None, action, self.counts,
                            self.time_jump_resets, dict(st.details), self.bias_report,
                            self.alignment)


def alignment_variance(res: AlignmentResult, given_heading_variance: float) -> list[float]:
    """Per-axis variance of a levelled attitude: levelling on the tilt axes, the heading's
    (given or gyrocompassed) on the vertical one."""
    heading_var = (given_heading_variance if res.heading_source == "given"
                   else res.heading_error_expected ** 2)
    lv = res.level_error_expected ** 2
    # q_nb = Rz(ψ) Ry(θ) Rx(φ): a roll error δφ is a rotation about Rz Ry(θ) e_x, whose
    # vertical component −sin θ·δφ turns the heading too when the body is pitched.
    s_p = math.sin(res.pitch)
    return [lv, lv, heading_var + s_p * s_p * lv]


def saturation_note(axis: int, value: float) -> str:
    return (f"gyro pinned at {value:g} rad/s on axis {'xyz'[axis]} (a repeated extreme: the "
            "gyro saturated; the attitude is unreliable there)")


def rate_fit_note(t_ns: int) -> str:
    return (f"rate fit not trusted at stamp {t_ns}: the samples alias the motion (the rate "
            "turns by nearly half a turn between samples) or the fit leaves their range; the "
            "step moved toward the exponential map (the attitude is unreliable there: sample "
            "faster)")


def cannot_align(cfg: StreamConfig) -> str:
    return (f"cannot align: no rest of at least {cfg.min_rest_s:g} s followed by motion in the "
            "recording (initial_attitude_source 'level' needs the IMU still at the start)")


_ONES = np.ones(3)


def recording_arrays(n: int, angular_velocity_covariance, accel):
    """``(covariance (n, 9) or None, accel (n, 3) or None)`` as float arrays of a whole
    recording of n samples, or ValueError naming the wrong shape."""
    cov = acc = None
    if angular_velocity_covariance is not None:
        cov = np.asarray(angular_velocity_covariance, dtype=np.float64)
        if cov.shape != (n, 9):
            raise ValueError(f"angular_velocity_covariance must have shape ({n}, 9), got "
                             f"{cov.shape}")
    if accel is not None:
        acc = np.asarray(accel, dtype=np.float64)
        if acc.shape != (n, 3):
            raise ValueError(f"accel must have shape ({n}, 3), got {acc.shape}")
    return cov, acc


def covariance_rows(cov: np.ndarray, valid: np.ndarray, counts: dict, details: dict):
    """Per-axis gyro variances (M, 3) and whether each is known (M,) for the accepted rows
    ``valid`` of ``cov`` (N, 9); the invalid ones are counted in ``counts`` and the first is
    described in ``details`` (treated as unknown)."""
    var_all, known_all, invalid_all = gyro_variances_array(cov)
    inv = rows(invalid_all, valid)
    counts[INVALID_COVARIANCE] = int(np.count_nonzero(inv))
    if counts[INVALID_COVARIANCE]:
        k = int(valid[np.flatnonzero(inv)[0]])
        details.setdefault(INVALID_COVARIANCE, invalid_covariance_note(cov[k]))
    return rows(var_all, valid), rows(known_all, valid)


def rows(a: np.ndarray, index: np.ndarray, empty=None) -> np.ndarray:
    """``a[index]`` for sorted row indices; a view when they are consecutive (the usual
    case: a recording without bad samples), sparing a copy of the whole recording.  A copy
    goes into ``empty(shape, dtype)`` when given."""
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


class _PushKernel:
    """:meth:`AttitudeStream.push` compiled (:func:`.sample_step.push_sample`) for the samples
    nothing special happens to; its arguments (the stages' state arrays and settings) are
    gathered once and again after the Python steps ran (``args = None``)."""

    @classmethod
    def for_stream(cls, s: AttitudeStream) -> _PushKernel | None:
        integ = s.integrator
        if integ is None or integ.cubic is None or integ._nav_rates is not None or not (
                s.aiding is None or isinstance(s.aiding, GravityAiding | AhrsFilter)):
            return None
        return cls(s)

    def __init__(self, s: AttitudeStream):
        self.s = s
        self.args = None
        self._mag_mode = s.config.aiding is Aiding.MAGNETOMETER
        self._heading = math.radians(s.config.initial_heading_deg)  # the aligning Earth rate
        self._cov_row, self._cov_judged = None, (None, False)

    def _build(self) -> tuple:
        s = self.s
        self._kernel, self._direct = compiled(push_sample), False
        cfg = s.validator.config
        est, det = s.bias_estimator, s.bias_estimator.detector
        aid = s.aiding
        kind = 0 if aid is None else (1 if isinstance(aid, GravityAiding) else 2)
        dummy_f, dummy_i = np.zeros(1), np.zeros(1, dtype=np.int64)
        g = (aid.params, aid.gf, aid.gi) if kind == 1 else (dummy_f, dummy_f, dummy_i)
        h = (aid.pa, aid.af, aid.ai) if kind == 2 else (dummy_f, dummy_f, dummy_i)
        cs, nav = s.integrator.cubic, s.integrator._nav_const
        floor = (s.alignment.level_error_expected if s.alignment is not None
                 else s.config.accel_bias_sigma / STANDARD_GRAVITY) ** 2
        # every scalar of one Python type, always (the kernel is called without numba's
        # dispatch once it has its one set of argument types: jit.direct)
        return (int(cfg.max_gap_ns), float(cfg.max_rate_rad_s), float(ACCEL_ABSURD),
                float(SATURATION_MIN_RAD_S), s.state.sat, est.mode == GyroBiasMode.AUTO), (
            est.bf, est.bi, int(est.min_rest_ns), det.rf, det.ri, det.wt, det.wx, det.wc,
            est.pv, est.pe, est.earth_n,
            s.latitude_rad is not None and est.mode == GyroBiasMode.AUTO, s.intervals.ring,
            s.intervals.fill, kind, *g, *h, cs.ci, cs.ts, cs.ws, cs.cf, nav is not None,
            *((0.0, 0.0, 0.0) if nav is None else (float(nav[0]), float(nav[1]), float(nav[2]))),
            s.covariance.c, float(s.covariance.k2), float(s._n2),
            0.0 if aid is None else float(aid.kp), float(floor))

    #: the validator's verdict of a plain accept
    _ACCEPT = v.Verdict(v.ACCEPT)

    def push(self, t_ns, omega, frame_id, covariance, accel, mag):
        """``(verdict, attitude)`` of :meth:`AttitudeStream.push` for this sample, or None when
        the Python steps must take it (nothing changed then)."""
        s = self.s
        st = s.state
        val = s.validator
        stamps = val._stamps
        if st.phase is FAILED or type(t_ns) is not int or frame_id != val.frame_id \
                or stamps.period is None:
            return None
        try:
            w0, w1, w2 = omega.tolist() if type(omega) is np.ndarray else omega
            w0, w1, w2 = float(w0), float(w1), float(w2)
            if accel is None:
                has_a, a0, a1, a2 = False, 0.0, 0.0, 0.0
            else:
                a0, a1, a2 = accel.tolist() if type(accel) is np.ndarray else accel
                has_a, a0, a1, a2 = True, float(a0), float(a1), float(a2)
        except (TypeError, ValueError):
            return None
        var, invalid = None, False
        if covariance is not None:
            covariance = covariance.tolist() if type(covariance) is np.ndarray and \
                covariance.dtype == np.float64 and covariance.ndim == 1 else np.asarray(
                    covariance, dtype=np.float64).reshape(-1).tolist()
            # a driver sends the same covariance with every message: judged once
            if covariance == self._cov_row:
                var, invalid = self._cov_judged
            else:
                var, invalid = row_variances(covariance)
                self._cov_row, self._cov_judged = covariance, (var, invalid)
        if invalid:
            return None
        m_state, m0, m1, m2, missing = MAG_ABSENT, 0.0, 0.0, 0.0, False
        if self._mag_mode:
            m = _as_floats(mag)
            if m is not None:
                m_state, (m0, m1, m2) = MAG_GIVEN, m
            elif field_absent(mag):
                missing = True
            else:
                m_state = MAG_NOT_FLOATS
        var_ok = var is not None
        s0, s1, s2 = var if var_ok else (0.0, 0.0, 0.0)
        if self.args is None:
            self.args = self._build()
        head, tail = self.args
        present = -1 if st.accel_present is None else int(st.accel_present)
        previous = s.bias_estimator.bias_floats if st.first_rest_pending else None
        x, y, z, u = st.q
        code, pinned, n_fb, seen, x, y, z, u = self._kernel(
            t_ns, w0, w1, w2, has_a, a0, a1, a2, present, m_state, m0, m1, m2, var_ok, s0,
            s1, s2, stamps.last, stamps.period, *head, st.first_rest_pending,
            st.phase is ALIGNING, self._heading, *tail, st.aided_seen, x, y, z, u)
        if code == NOT_PLAIN:
            return None
        # what the Python steps before the bias stage do besides (validator, variances,
        # accelerometer, field, saturation)
        stamps.last = t_ns
        val._skipped = 0
        val.accepted += 1
        if var_ok or covariance is not None and covariance[0] == v.NO_ESTIMATE:
            s._variance_seen(var, covariance)
        st.accel_present = has_a
        if missing:
            s._field_missing(t_ns)
        if pinned >= 0:
            st.count(SATURATED, saturation_note(pinned, (w0, w1, w2)[pinned]))
        if n_fb:
            st.count_fit_fallbacks(n_fb, t_ns)
        if code == DONE:
            if not self._direct:
                self._kernel, self._direct = direct(self._kernel), True
            q = (x, y, z, u)
            s.integrator.took(t_ns, q)
            st.aided_seen = seen
            st.q = q
            return self._ACCEPT, np.array(q)
        if code == NOT_FINITE:
            self.args = None
            s.integrator.synced()
            return s._integrator_error(self._ACCEPT, "non-finite attitude: last good one restored")
        est = s.bias_estimator
        if code == BIAS_REFUSED:
            self.args = None
            est.break_window()
        elif code == AFTER_BIAS:  # a new estimate while the first may still go back to the start
            self.args = None
            s._bias_published(previous)
        bias = est.bias_floats
        a = (a0, a1, a2) if has_a else None
        mag_in = None if m_state == MAG_ABSENT else mag
        if st.phase is ALIGNING:  # ALIGN, or the bias stage's Python step while aligning
            q = s._align_step(t_ns, (w0, w1, w2), a, var, bias, mag_in)
            if st.phase is not ALIGNING:  # aligned (or failed): the stages started afresh
                self.args = None
            return self._ACCEPT, None if q is None else np.array(q)
        self.args = None
        verdict, q = s._integrate(self._ACCEPT, t_ns, (w0 - bias[0], w1 - bias[1], w2 - bias[2]), a,
                                  var, mag_in)
        return verdict, None if q is None else np.array(q)


def compile_kernels(config: StreamConfig | None = None, algorithm: str | None = None) -> None:
    """Compile (or load from numba's cache) what the chain runs compiled: a short synthetic
    recording (rest, turn, rest; accelerometer and field) pushed through a stream with
    ``config`` (and ``algorithm``), or with every aiding mode.  The start is the given attitude
    whatever ``config`` says (a levelling or gyrocompassing start might never align on it; its
    kernels are the same).  The node calls it at start-up and dev.sh after installing, so that
    no sample waits for the compiler."""
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
    for cfg in configs:
        cfg = replace(cfg, initial_attitude_source=InitialAttitudeSource.PARAMETER,
                      heading_source=HeadingSource.PARAMETER)
        AttitudeStream(algorithm or DEFAULT_ALGORITHM, config=cfg).run(t, w, "imu", cov, a, mag)
