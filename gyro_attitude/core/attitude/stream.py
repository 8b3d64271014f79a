"""The attitude-stream policy shared by the live node and offline replay: one home for what a bad,
gappy or jumping Imu stream gets.

:class:`AttitudeStream` takes samples one at a time (:meth:`AttitudeStream.push`, the node) or a
whole recording (:meth:`AttitudeStream.run`, replay) and applies the same rules either way:

* every sample first gets a verdict (:mod:`.validation`): non-finite rates, rates beyond
  ``max_rate_rad_s``, zero, duplicate and out-of-order stamps and a changed ``frame_id`` are
  skipped and counted by reason; the stream goes on with the next sample;
* a forward step longer than ``max_gap_ns`` is not integrated across: the attitude is held and
  the time base restarts at the sample after the gap (counted as ``gap``);
* a backward step longer than ``time_jump_ns`` resets the attitude to the initial one and the
  orientation variance to the initial variance (counted in ``time_jump_resets``);
* the orientation variance grows per axis with the gyro noise (angle random walk: each accepted
  interval adds ``σ_ω² dt²``, σ_ω² from the diagonal of ``angular_velocity_covariance``); a
  covariance that says "no estimate" (element 0 = −1, or all zeros) adds nothing, and one with a
  non-finite, negative or absurd (> 1e6 (rad/s)²) diagonal is treated as unknown and counted
  (``invalid_covariance``);
* every attitude handed out is finite and unit: should an update ever produce a non-finite
  quaternion, the stream restores the last good attitude, restarts its time base at the next
  sample and counts an ``integrator_error`` instead.

Real-IMU steps, applied to every ACCEPTED sample in this order (bad samples never reach them):
rest detection → gyro bias (:mod:`.gyro_bias`: ``none`` | ``parameter`` | ``auto``, zero-rate
updates at rests, Earth rate taken out when the latitude is known; with a given initial
attitude and a stream that rests from its start (within one rest window), the first estimate is applied back
to the start — the attitude is corrected by ``−Δb·Δt``, as the still body did not turn) →
alignment (:mod:`.alignment`, ``initial_attitude="level"``: no attitude while
``phase == "aligning"``; the attitude starts when the first rest of ``min_rest_s`` ends, from
the levelled attitude, with the samples since
the last rest sample integrated) → gravity aiding (:mod:`.gravity_aiding`, ``aiding="gravity"``)
→ integration of ``ω − bias``.  A gap or a time jump breaks the rest windows (a rest never spans
one); an accelerometer sample that is not finite or absurd is counted (``invalid_accel``),
breaks the windows and is not used for aiding; the gyro sample is still integrated.  The
orientation variance is the per-axis attitude/bias error covariance of :mod:`.covariance`
(gyro noise, bias uncertainty, alignment, aiding).

The two paths give the same attitudes sample for sample: :meth:`run` classifies the whole
recording with :func:`.validation.classify` and integrates each run of accepted samples in one
batch call (the batch and streaming integrators agree to ~1e-16) with ``ω − fixed bias`` and
the covariance as cumulative sums; it falls back to the per-sample path from the first segment
that would produce a non-finite attitude.  That fast path holds for ``gyro_bias`` ``none`` /
``parameter`` with a given initial attitude and no aiding.  Bias estimation at rests, alignment
and aiding are sequential filters (each sample's bias and correction depend on the attitude and
the rests before it), so :meth:`run` then runs the per-sample path itself (its cost against the
batch is printed by ``gyro-attitude bench --suite real``).
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
    integrate_batch,
)
from gyro_attitude.core.attitude import validation as v
from gyro_attitude.core.attitude.ahrs import AhrsFilter, AhrsParams
from gyro_attitude.core.attitude.alignment import (
    AlignmentResult,
    StaticAligner,
    check_gyrocompass_feasible,
    level_quaternion,
)
from gyro_attitude.core.attitude.covariance import AttitudeCovariance, propagate_batch
from gyro_attitude.core.attitude.gravity_aiding import GravityAiding
from gyro_attitude.core.attitude.gyro_bias import GyroBiasEstimator, GyroBiasReport
from gyro_attitude.core.attitude.modes import (
    Aiding,
    Frame,
    GyroBiasMode,
    HeadingSource,
    Phase,
    SettingError,
)
from gyro_attitude.core.attitude.rest import NOISE_FLOOR_RAD_S, detect_rest
from gyro_attitude.core.attitude.settings import StreamConfig
from gyro_attitude.core.earth import STANDARD_GRAVITY
from gyro_attitude.core.rotation import quat_from_rotvec, quat_multiply, quat_normalize


class PerSamplePathNeeded(ValueError):
    """:meth:`AttitudeStream.run` with an offline algorithm on a recording that a sequential
    filter acts on (levelling, aiding, auto bias with a rest)."""


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

ALIGNING, RUNNING, FAILED = Phase.ALIGNING, Phase.RUNNING, Phase.FAILED


def gyro_variances(covariance) -> tuple[np.ndarray | None, bool]:
    """(per-axis variances, invalid) of a row-major 3x3 ``angular_velocity_covariance``.

    ``None, False`` when it carries no estimate (element 0 = −1, REP-145) or is all zeros
    (unknown); ``None, True`` when its diagonal is non-finite, negative or beyond
    MAX_GYRO_VARIANCE (treated as unknown).
    """
    if covariance is None:
        return None, False
    c = np.asarray(covariance, dtype=np.float64).reshape(-1)
    if c.size != 9:
        return None, True
    if c[0] == -1.0:
        return None, False
    d = c[[0, 4, 8]]
    if not np.all(np.isfinite(d)) or np.any(d < 0) or np.any(d > MAX_GYRO_VARIANCE):
        return None, True
    if not np.any(c):
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
    no_estimate = c[:, 0] == -1.0
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

    @property
    def skipped(self) -> int:
        return int(self.action.shape[0] - self.index.shape[0])


class AttitudeStream:
    """Imu samples in, attitude out, under the one policy of the module docstring.

    ``algorithm`` a name from the registry (an offline one serves the batch path of :meth:`run`
    only: it needs samples after each interval, so :meth:`push` refuses it); ``q0`` the initial
    attitude (also the one a time jump resets to; with ``initial_attitude="level"`` the
    alignment replaces it); ``nav`` a :class:`NavFrame` for q_nb (Earth and transport rate
    removed) or None for q_ib; ``config`` the settings.  With ``nav`` (or
    ``config.latitude_rad``) the Earth rate is taken out of the bias estimate, using the current
    attitude as q_nb (for q_ib that takes the inertial frame as the nav frame at the start:
    right to ω_ie·t, a few °/h of Earth-rate direction).
    """

    def __init__(self, algorithm: str = DEFAULT_ALGORITHM, q0=(0.0, 0.0, 0.0, 1.0),
                 nav: NavFrame | None = None, config: StreamConfig | None = None):
        self.config = cfg = config if config is not None else StreamConfig()
        self.q_initial = _unit_quat(q0)
        self.nav = nav
        if nav is None and cfg.frame is Frame.ENU:
            nav = self.nav = cfg.nav_frame()
        self.algorithm = algorithm
        self.integrator = (StreamingIntegrator(algorithm=algorithm, q0=self.q_initial, nav=nav)
                           if get_algorithm(algorithm).causal else None)
        self.validator = v.ImuStreamValidator(cfg.check_config())
        self.intervals = v.IntervalStatistics(window=2000)
        self.counts_extra = {INVALID_COVARIANCE: 0, INVALID_ACCEL: 0, INTEGRATOR_ERROR: 0}
        self.details: dict[str, str] = {}
        self._resume_q: np.ndarray | None = None
        self._last_q: np.ndarray = self.q_initial
        lat = nav.latitude_rad if nav is not None else (
            cfg.latitude_rad if cfg.latitude_known else None)
        self.latitude_rad = None if lat is None else float(np.asarray(lat).reshape(-1)[0])
        if cfg.heading_source is HeadingSource.GYROCOMPASS:
            check_gyrocompass_feasible(cfg.gyro_bias_sigma_rad_s, self.latitude_rad,
                                       cfg.heading_error_limit_deg)
        fixed = cfg.gyro_bias_rad_s if cfg.gyro_bias is GyroBiasMode.PARAMETER else None
        self.bias_estimator = GyroBiasEstimator(
            cfg.gyro_bias, fixed, min_rest_s=cfg.min_rest_s, latitude_rad=self.latitude_rad,
            rest=cfg.rest_params())
        self._fixed_bias = self.bias_estimator.bias
        self.aiding = None
        self._mag = None  # the current sample's magnetic field (aiding magnetometer)
        if cfg.aiding is Aiding.GRAVITY:
            self.aiding = GravityAiding(cfg.aiding_kp, cfg.aiding_ki, cfg.aiding_accel_tol,
                                        cfg.aiding_rate_max,
                                        accel_lowpass_s=cfg.aiding_accel_lowpass_s)
        elif cfg.aiding in (Aiding.TILT, Aiding.MAGNETOMETER):
            self.aiding = AhrsFilter(AhrsParams.from_config(cfg))
        self.covariance = AttitudeCovariance(cfg.initial_attitude_variance, cfg.gyro_bias_sigma_rad_s,
                                             cfg.gyro_bias_rw)
        self._n2 = cfg.gyro_noise_density * cfg.gyro_noise_density
        self._var_known = bool(cfg.gyro_noise_density > 0 or cfg.gyro_bias_sigma_rad_s > 0
                               or cfg.levelling)
        self._accel_present: bool | None = None
        self._start_t: int | None = None
        self._first_rest_pending = cfg.gyro_bias is GyroBiasMode.AUTO and not cfg.levelling
        self.alignment: AlignmentResult | None = None
        self.alignment_error: str | None = None
        self.phase = RUNNING
        if cfg.levelling:
            self.phase = ALIGNING
            self._new_aligner()

    def _new_aligner(self) -> None:
        cfg = self.config
        gc = cfg.heading_source is HeadingSource.GYROCOMPASS
        self._aligner = StaticAligner(
            cfg.initial_heading_deg, gyrocompass=gc, latitude_rad=self.latitude_rad if gc else None,
            gyro_bias=(cfg.gyro_bias_rad_s if cfg.gyro_bias is GyroBiasMode.PARAMETER
                       else (0.0, 0.0, 0.0)),
            gyro_bias_sigma=cfg.gyro_bias_sigma_rad_s if gc else None,
            accel_bias_sigma=cfg.accel_bias_sigma,
            heading_error_limit_deg=cfg.heading_error_limit_deg, min_rest_s=cfg.min_rest_s,
            rest=cfg.rest_params())
        self._align_buffer: deque = deque()

    # ------------------------------------------------------------------ state and settings
    @property
    def counts(self) -> dict[str, int]:
        out = {**self.validator.counts, **self.counts_extra}
        if self.config.aiding is Aiding.MAGNETOMETER:
            out[MAG_MISSING] = self._mag_missing
            out[INVALID_MAG] = self.aiding.mag_invalid
            out[MAG_DISTURBED] = self.aiding.mag_disturbed
            for key, text in ((INVALID_MAG, "a magnetic field sample not finite, beyond 10 mT "
                                            "or below 0.1 µT"),
                              (MAG_DISTURBED, "a field whose norm or dip is off the reference")):
                if out[key]:
                    self.details.setdefault(key, text)
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
        return self._last_q.copy()

    @property
    def variance(self) -> np.ndarray | None:
        """Per-axis orientation variance [rad²]; None while nothing gives an estimate."""
        return self.covariance.tt.copy() if self._var_known else None

    @property
    def bias_report(self) -> GyroBiasReport:
        return self.bias_estimator.report()

    def set_config(self, config: StreamConfig) -> None:
        """New validation thresholds from the next sample on (state kept; the bias, alignment
        and aiding settings stay those of construction)."""
        self.config = replace(self.config, max_gap_s=config.max_gap_s,
                              time_jump_threshold_s=config.time_jump_threshold_s,
                              max_rate_rad_s=config.max_rate_rad_s)
        self.validator.config = config.check_config()

    def set_algorithm(self, algorithm: str) -> None:
        """Switch the algorithm, keeping the attitude and the time base (raises ValueError and
        changes nothing for an unknown or unsuitable algorithm)."""
        integrator = StreamingIntegrator(algorithm=algorithm, q0=self.integrator.quaternion,
                                         nav=self.nav, t0_ns=self.integrator.last_t_ns)
        self.integrator = integrator
        self.algorithm = algorithm

    def update_nav(self, nav: NavFrame) -> None:
        """Constant nav frame from the next sample on (see StreamingIntegrator.update_nav)."""
        self.integrator.update_nav(nav)
        self.nav = nav

    def restart(self, q0=None) -> None:
        """Forget the time base (and the locked frame): the next sample starts from ``q0``
        (which also becomes the initial attitude), or from the initial attitude."""
        if q0 is not None:
            self.q_initial = _unit_quat(q0)
            self._last_q = self.q_initial
        self._resume_q = None
        self.validator.reset()
        self.intervals.clear()
        self._break_windows()

    # ------------------------------------------------------------------ one sample
    def push(self, t_ns: int, omega, frame_id: str = "", angular_velocity_covariance=None,
             accel=None, mag=None) -> tuple[v.Verdict, np.ndarray | None]:
        """One sample: its verdict and the attitude at ``t_ns`` (None when it was skipped or
        while aligning).  ``accel`` the specific force (3,) m/s² or None; ``mag`` the magnetic
        field (3,) tesla time-aligned to ``t_ns`` or None (aiding magnetometer: counted
        ``mag_missing``, heading gyro-only; a field that is not finite, absurd or zero is
        counted ``invalid_mag``, one that disagrees with the reference ``mag_disturbed``)."""
        if self.integrator is None:
            raise ValueError(f"{self.algorithm} is an offline algorithm: it cannot stream "
                             "(use run() over the whole recording, or a causal algorithm)")
        verdict = self.validator.check(t_ns, omega, frame_id)
        if verdict.rejected:
            self.details.setdefault(verdict.reason, verdict.detail)
            return verdict, None
        t_ns = int(t_ns)
        var, invalid = gyro_variances(angular_velocity_covariance)
        if invalid:
            self._count(INVALID_COVARIANCE, "angular_velocity_covariance with a non-finite or "
                                            "negative diagonal: treated as unknown")
        if var is not None:
            self._var_known = True
        action = verdict.action
        if action == v.RESET_TIME_JUMP:
            self.details.setdefault("time_jump", verdict.detail)
        a = self._accel(accel)
        self._mag = self._mag_sample(mag)
        if self._start_t is None:
            self._start_t = t_ns
        if action != v.ACCEPT:
            self._break_windows()  # a rest never spans a gap, a jump or a restart
        w = np.asarray(omega, dtype=np.float64)
        bias = self._bias_update(t_ns, w, a)
        if self.phase != RUNNING:
            return verdict, self._align_step(t_ns, w, a, var, action, bias)
        return self._integrate(verdict, t_ns, w - bias, a, var)

    _mag_missing = 0

    def _mag_sample(self, mag):
        """The sample's field for the aiding (magnetometer mode), counting absent ones; the
        filter checks and counts the values."""
        if self.config.aiding is not Aiding.MAGNETOMETER:
            return None
        if mag is None or (isinstance(mag, np.ndarray) and mag.shape == (3,)
                           and np.isnan(mag).all()):
            self._mag_missing += 1
            self.details.setdefault(MAG_MISSING, f"no field sample at stamp {self.last_t_ns} "
                                                 "(none within mag_max_age_s)")
            return None
        return mag

    def _accel(self, accel):
        """The sample's specific force as 3 floats, or None (absent or unusable, counted)."""
        if accel is None:
            a = None
        else:
            try:
                x, y, z = (float(c) for c in accel)
            except (TypeError, ValueError):
                x = y = z = math.nan
            if math.isfinite(x) and math.isfinite(y) and math.isfinite(z) and \
                    max(abs(x), abs(y), abs(z)) <= ACCEL_ABSURD:
                a = (x, y, z)
            else:
                self._count(INVALID_ACCEL, f"accelerometer sample {accel!r} is not 3 finite "
                                           "numbers: not used for rests or aiding")
                self._break_windows()
                self._accel_present = None
                return None
        if self._accel_present is not None and (a is not None) != self._accel_present:
            self._break_windows()  # the rest detectors need the accelerometer for all or none
        self._accel_present = a is not None
        return a

    def _break_windows(self) -> None:
        self.bias_estimator.break_window()
        if self.phase == ALIGNING and self._aligner._seg is not None:
            self._new_aligner()  # alignment needs one unbroken rest
        elif self.phase == ALIGNING:
            self._aligner.detector.reset()
            self._align_buffer.clear()
        if self.aiding is not None:
            self.aiding.last_t_ns = None

    def _bias_update(self, t_ns: int, w: np.ndarray, a) -> np.ndarray:
        est = self.bias_estimator
        if est.mode is not GyroBiasMode.AUTO:
            return self._fixed_bias
        q_nb = None
        if self.latitude_rad is not None:
            if self.phase == RUNNING:
                q_nb = self._last_q
            elif a is not None:  # aligning: level from this sample with the given heading
                try:
                    q_nb = level_quaternion(a, math.radians(self.config.initial_heading_deg))[0]
                except ValueError:
                    q_nb = None
        previous = est.bias
        try:
            bias = est.update(t_ns, w, a, q_nb)
        except ValueError:  # a value the rest statistics refuse (e.g. > 1e6): no rest here
            est.break_window()
            return est.bias
        if est.updated:
            seg = est._seg
            t_prev = self.integrator.last_t_ns
            if self._first_rest_pending and self.phase == RUNNING and seg is not None \
                    and seg[0] - self._start_t <= est.detector._window_ns \
                    and t_prev is not None and est._pool.k == 0:
                # (a full window is needed before the first decision, so the first rest sample
                # is at best the second sample of the stream)
                # Still since the start: the samples so far were integrated with the previous
                # bias; the body did not turn, so the attitude error is the bias change times
                # the elapsed time, a body-frame rotation taken back here.
                elapsed = (t_prev - self._start_t) * 1e-9
                q_fix = quat_multiply(self.integrator.quaternion,
                                      quat_from_rotvec(-(bias - previous) * elapsed))
                self.integrator.reset(q_fix, t_prev)
                self._last_q = q_fix
                self.covariance.first_rest_update(est.standard_error, elapsed)
            else:
                self.covariance.zero_rate_update(est.standard_error)
            self._first_rest_pending = False
        return bias

    def _align_step(self, t_ns, w, a, var, action, bias):
        if self.phase == FAILED:
            return None
        if a is None:
            self.alignment_error = ("alignment needs the accelerometer: no usable "
                                    "linear_acceleration")
            return None
        self.alignment_error = None
        al = self._aligner
        try:
            done = al.update(t_ns, w, a)
        except ValueError:
            self._new_aligner()
            return None
        buf = self._align_buffer
        buf.append((t_ns, w, a, var, self._mag))
        seg = al._seg
        if seg is None:
            while len(buf) > 1:
                buf.popleft()
        else:  # keep the samples from the last rest sample on: integrated once aligned
            while buf[0][0] < seg[1]:
                buf.popleft()
        if not done:
            return None
        try:
            res = al.result()
        except ValueError as exc:
            self.phase = FAILED
            self.alignment_error = str(exc)
            return None
        self.alignment = res
        self.alignment_error = None
        self.phase = RUNNING
        heading_var = (self.config.initial_attitude_variance if res.heading_source == "given"
                       else res.heading_error_expected ** 2)
        lv = res.level_error_expected ** 2
        # q_nb = Rz(ψ) Ry(θ) Rx(φ): a roll error δφ is a rotation about Rz Ry(θ) e_x, whose
        # vertical component −sin θ·δφ turns the heading too when the body is pitched.
        s_p = math.sin(res.pitch)
        self.covariance.align([lv, lv, heading_var + s_p * s_p * lv])
        self.q_initial = res.q_nb
        self._last_q = res.q_nb
        self._resume_q = None
        entries = list(buf)
        buf.clear()
        integ = self.integrator
        integ.reset(res.q_nb, None)
        if self.aiding is not None:
            self.aiding.last_t_ns = None
        t0, w0, a0, var0, self._mag = entries[0]
        verdict0 = v.Verdict(v.START, "", "")
        _, q = self._integrate(verdict0, t0, w0 - bias, a0, var0, fresh=True)
        for tk, wk, ak, vk, self._mag in entries[1:]:
            _, q = self._integrate(v.Verdict(v.ACCEPT, "", ""), tk, wk - bias, ak, vk)
        return q

    def _integrate(self, verdict: v.Verdict, t_ns: int, rate: np.ndarray, a, var,
                   fresh: bool = False):
        integ = self.integrator
        action = verdict.action
        last_t = integ.last_t_ns
        aid = self.aiding
        try:
            if action == v.ACCEPT:
                if aid is not None:
                    rate = aid.update(t_ns, rate, a, self._last_q, self._mag)
                q = integ.update(t_ns, rate)
            else:
                if action == v.RESET_TIME_JUMP:
                    q0 = self.q_initial
                    self.covariance.reset_attitude()
                    self.intervals.clear()
                elif action == v.RESTART_AFTER_GAP:
                    self.details.setdefault(v.GAP, verdict.detail)
                    q0 = self._last_q
                elif fresh:
                    q0 = self.q_initial
                else:  # START
                    q0 = self.q_initial if self._resume_q is None else self._resume_q
                    self._resume_q = None
                integ.reset(q0, None)
                if aid is not None:
                    aid.last_t_ns = None
                    rate = aid.update(t_ns, rate, a, q0, self._mag)
                q = integ.update(t_ns, rate)
        except ValueError as exc:  # defensive: the validator should have caught it
            return self._integrator_error(verdict, f"integrator refused a sample: {exc}")
        x, y, z, w = q.tolist()
        if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z) and math.isfinite(w)):
            return self._integrator_error(verdict, "non-finite attitude: last good one restored")
        if action == v.ACCEPT:
            dt = t_ns - last_t
            self.intervals.add(dt)
            dt_s = dt * 1e-9
            # angle random walk: each interval adds an independent angle error of variance
            # σ_ω² dt² per axis (σ_ω² per sample), i.e. N² dt with the noise density N.
            qv = var * (dt_s * dt_s) if var is not None else self._n2 * dt_s * _ONES
            cov = self.covariance
            cov.propagate(dt_s, qv)
            if aid is not None and aid.aided_samples != self._aided_seen:
                cov.aid_tilt(aid.kp * dt_s, (self.alignment.level_error_expected
                                             if self.alignment is not None
                                             else self.config.accel_bias_sigma / STANDARD_GRAVITY) ** 2)
        if aid is not None:
            self._aided_seen = aid.aided_samples
        self._last_q = q
        return verdict, q

    _aided_seen = 0

    def _count(self, key: str, detail: str) -> None:
        self.counts_extra[key] += 1
        self.details.setdefault(key, detail)

    def _integrator_error(self, verdict: v.Verdict, detail: str):
        self._count(INTEGRATOR_ERROR, detail)
        self._resume_q = self._last_q
        self.integrator.reset(self._last_q, None)
        self.validator.last_t_ns = None  # next sample starts a fresh time base
        if self.aiding is not None:
            self.aiding.last_t_ns = None
        return v.Verdict(v.REJECT, INTEGRATOR_ERROR, detail), None

    # ------------------------------------------------------------------ a whole recording
    @property
    def batch_path(self) -> bool:
        """Whether :meth:`run` integrates in batch whatever the data (no sequential filter
        configured; with ``gyro_bias="auto"`` it also does on a recording with no rest)."""
        cfg = self.config
        return (cfg.gyro_bias is not GyroBiasMode.AUTO and not cfg.levelling
                and cfg.aiding is Aiding.NONE)

    def needs_per_sample_path(self, t_ns, omega, accel=None) -> bool:
        """Whether :meth:`run` on this recording has to run the per-sample path (a sequential
        filter that acts on it: levelling, aiding, or ``auto`` bias on data with a rest)."""
        cfg = self.config
        if cfg.levelling or cfg.aiding is not Aiding.NONE:
            return True
        if cfg.gyro_bias is not GyroBiasMode.AUTO:
            return False
        t = np.asarray(t_ns)
        w = np.asarray(omega, dtype=np.float64)
        cls = v.classify(t, w, "", cfg.check_config())
        return self._auto_bias_may_act(t.astype(np.int64, copy=False), w, accel, cls.action)

    def _auto_bias_may_act(self, t, w, accel, act) -> bool:
        """Whether the ``auto`` bias estimator could find a rest: the batch rest detector over
        each run of accepted samples (the streaming detector breaks its windows at gaps and
        jumps, and at unusable accelerometer samples, so it finds no rest where this finds
        none: then the bias stays at its initial value and the batch path is exact)."""
        codes = v.ACTION_CODES
        valid = np.flatnonzero(act != codes[v.REJECT])
        if valid.size == 0:
            return False
        a = None if accel is None else np.asarray(accel, dtype=np.float64)
        if a is not None and not _usable_accel(_rows(a, valid)).all():
            return True  # unusable accelerometer samples: let the per-sample path count them
        # A window at rest has |mean| <= a and spread <= s, so the mean of |ω|² over it is at most
        # a² + s²: when every sample's |ω|² exceeds that, no window can be at rest (a cheap,
        # exact pre-check that spares the windowed statistics on moving recordings).
        cfg = self.config
        wv = _rows(w, valid)
        if np.einsum("ij,ij->i", wv, wv).min() > (cfg.rest_gyro_mean_max ** 2
                                                  + cfg.rest_gyro_std_max ** 2):
            return False
        bounds = np.append(np.flatnonzero(act[valid] != codes[v.ACCEPT]), valid.size)
        params = {"gyro_std_min": NOISE_FLOOR_RAD_S, **self.config.rest_params()}
        for p0, p1 in zip(bounds[:-1].tolist(), bounds[1:].tolist(), strict=True):
            seg = valid[p0:p1]
            if seg.size < 2:
                continue
            rest = detect_rest(_rows(t, seg), _rows(w, seg),
                               None if a is None else _rows(a, seg), **params)
            if rest.at_rest.any():
                return True
        return False

    def run(self, t_ns, omega, frame_id: str | list[str] | None = "",
            angular_velocity_covariance=None, accel=None, mag=None) -> StreamResult:
        """All samples of a recording, in file order, on a fresh stream: what :meth:`push`
        would give sample by sample (the stream is left in the state after the last one;
        the integrator holds the last sample only, so the rate fit of a later push() rebuilds
        from two samples on, as after a restart).

        ``t_ns`` (N,) int stamps; ``omega`` (N, 3) rad/s; ``frame_id`` one for all or one per
        sample; ``angular_velocity_covariance`` (N, 9) or None; ``accel`` (N, 3) m/s² or None;
        ``mag`` (N, 3) tesla time-aligned to the stamps (rows of NaN: no field there; see
        :func:`.sample_alignment.latest_at`) or None.
        Raises ValueError when ``initial_attitude="level"`` cannot align on the recording.
        """
        if self.validator.last_t_ns is not None or self.validator.accepted:
            raise ValueError("run() needs a fresh AttitudeStream (it replays a whole recording)")
        t = np.asarray(t_ns)
        w = np.asarray(omega, dtype=np.float64)
        n = w.shape[0]
        cov = None
        if angular_velocity_covariance is not None:
            cov = np.asarray(angular_velocity_covariance, dtype=np.float64)
            if cov.shape != (n, 9):
                raise ValueError(f"angular_velocity_covariance must have shape ({n}, 9), got "
                                 f"{cov.shape}")
        acc = None
        if accel is not None:
            acc = np.asarray(accel, dtype=np.float64)
            if acc.shape != (n, 3):
                raise ValueError(f"accel must have shape ({n}, 3), got {acc.shape}")
        mg = None
        if mag is not None:
            mg = np.asarray(mag, dtype=np.float64)
            if mg.shape != (n, 3):
                raise ValueError(f"mag must have shape ({n}, 3), got {mg.shape}")
        cls = v.classify(t, w, frame_id, self.config.check_config())  # checks the input too
        t = t.astype(np.int64, copy=False)
        cfg = self.config
        if (cfg.levelling or cfg.aiding is not Aiding.NONE
                or (cfg.gyro_bias is GyroBiasMode.AUTO and self._auto_bias_may_act(t, w, acc, cls.action))):
            if self.integrator is None:
                raise PerSamplePathNeeded(
                    f"{self.algorithm} is an offline algorithm and runs in batch only, but this "
                    "recording needs the per-sample path (levelling, aiding, or auto gyro bias "
                    "with a rest in the data): use a causal algorithm, or gyro bias none or a "
                    "fixed value")
            return self._run_pushing(t, w, frame_id, cov, acc, mg)
        codes = v.ACTION_CODES
        act = cls.action
        valid = np.flatnonzero(act != codes[v.REJECT])
        if cov is not None:
            var_all, known_all, invalid_all = gyro_variances_array(cov)
        else:
            var_all = known_all = invalid_all = None
        w_corr = w - self._fixed_bias

        # Each run of accepted samples (from a START, a restart after a gap or a time-jump
        # reset up to the next one) is one batch integration.
        bounds = np.append(np.flatnonzero(act[valid] != codes[v.ACCEPT]), valid.size)
        q_out = None
        for p0, p1 in zip(bounds[:-1].tolist(), bounds[1:].tolist(), strict=True):
            seg = valid[p0:p1]
            # START and a time-jump reset begin at the initial attitude; a gap holds the last
            q0 = q_out[p0 - 1] if act[seg[0]] == codes[v.RESTART_AFTER_GAP] else self.q_initial
            q_seg = integrate_batch(_rows(t, seg), _rows(w_corr, seg), q0=q0,
                                    algorithm=self.algorithm, nav=_nav_rows(self.nav, seg, n))
            if not np.isfinite(q_seg).all():
                if self.integrator is None:  # the bounds on rates and nav frames prevent it
                    raise ValueError(f"{self.algorithm} produced a non-finite attitude and, an "
                                     "offline algorithm, cannot take the per-sample path that "
                                     "restores the last good one: use a causal algorithm")
                return self._run_pushing(t, w, frame_id, cov, acc, mg)
            if p0 == 0 and p1 == valid.size:
                q_out = q_seg  # one run: no copy
                continue
            if q_out is None:
                q_out = np.empty((valid.size, 4))
            q_out[p0:p1] = q_seg
        if q_out is None:
            q_out = np.empty((0, 4))

        # Orientation variance: the covariance recurrence over accepted intervals as cumulative
        # sums (covariance.propagate_batch), restarting at every time-jump reset, as push() does.
        counts = dict(cls.counts)
        counts[INVALID_COVARIANCE] = 0
        variance = variance_known = None
        known_v = np.zeros(valid.size, dtype=bool)
        if var_all is not None:
            counts[INVALID_COVARIANCE] = int(np.count_nonzero(_rows(invalid_all, valid)))
            known_v = _rows(known_all, valid)
            if counts[INVALID_COVARIANCE]:
                k = int(valid[np.flatnonzero(_rows(invalid_all, valid))[0]])
                cls.details.setdefault(INVALID_COVARIANCE, f"angular_velocity_covariance "
                                       f"{cov[k].tolist()} has a non-finite, negative or absurd "
                                       "diagonal: treated as unknown")
        if known_v.any() or self._var_known:
            acc_rows = act[valid] == codes[v.ACCEPT]
            tv = _rows(t, valid)
            dt = np.zeros(valid.size)
            dt[1:] = (tv[1:] - tv[:-1]) * 1e-9
            dt[~acc_rows] = 0.0
            qv = self._n2 * dt[:, None] * _ONES
            if var_all is not None:
                qv = np.where(known_v[:, None], _rows(var_all, valid) * (dt * dt)[:, None], qv)
            c = self.covariance
            reset_rows = act[valid] == codes[v.RESET_TIME_JUMP]
            variance, tb_end, bb_end = propagate_batch(dt, qv, reset_rows, c.initial_tt, c.bb,
                                                       c.k2)
            if valid.size:  # the state push() would hold after the last row
                c.tt, c.tb, c.bb = variance[-1].copy(), tb_end, bb_end
                # Σ q since the attitude was last set (the first-rest correction uses it)
                resets = np.flatnonzero(reset_rows)
                c.noise = qv[(resets[-1] + 1 if resets.size else 0):].sum(axis=0)
            # rows before anything gives an estimate have none (as push: None)
            variance_known = np.maximum.accumulate(known_v) | self._var_known
            variance[~variance_known] = 0.0
        counts[INVALID_ACCEL] = 0
        if acc is not None and valid.size:
            counts[INVALID_ACCEL] = int(valid.size - np.count_nonzero(
                _usable_accel(_rows(acc, valid))))
        counts[INTEGRATOR_ERROR] = 0
        self._adopt_batch_state(cls, t, w, valid, q_out, counts)
        if known_v.any():
            self._var_known = True
        return StreamResult(valid, q_out, variance, variance_known, act, counts,
                            cls.time_jump_resets, dict(cls.details), self.bias_report, None)

    def _adopt_batch_state(self, cls, t, w, valid, q_out, counts) -> None:
        """Leave the stream as push() would after the recording (counts, attitude)."""
        val = self.validator
        for r in v.REJECT_REASONS:
            val.counts[r] = cls.counts[r]
        val.accepted = cls.accepted
        val.time_jump_resets = cls.time_jump_resets
        for key in self.counts_extra:
            self.counts_extra[key] = counts.get(key, 0)
        if valid.size:
            val.last_t_ns = int(t[valid[-1]])
            val.frame_id = cls.frame_id
            self._start_t = int(t[valid[0]])
            self._last_q = q_out[-1].copy()
            if self.integrator is not None:
                # the last sample is the integrator's history: the next push() integrates
                # from it (as after a restart: the fit rebuilds from two samples on)
                self.integrator.reset(self._last_q, None)
                self.integrator.update(int(t[valid[-1]]), w[valid[-1]] - self._fixed_bias)

    def _run_pushing(self, t, w, frame_id, covariance, accel, mag=None) -> StreamResult:
        """Per-sample path over the whole recording (sequential filters, or the batch met a
        non-finite attitude)."""
        n = w.shape[0]
        frames = [frame_id] * n if frame_id is None or isinstance(frame_id, str) else frame_id
        index, qs, variances = [], [], []
        action = np.zeros(n, np.int8)
        codes = v.ACTION_CODES
        push = self.push
        for k in range(n):
            cov_k = None if covariance is None else covariance[k]
            acc_k = None if accel is None else accel[k]
            verdict, q = push(int(t[k]), w[k], frames[k] or "", cov_k, acc_k,
                              None if mag is None else mag[k])
            action[k] = codes[verdict.action]
            if q is None:
                continue
            index.append(k)
            qs.append(q)
            variances.append(self.covariance.tt.copy() if self._var_known else None)
        if self.phase != RUNNING:
            raise ValueError(self.alignment_error or (
                f"cannot align: no rest of at least {self.config.min_rest_s:g} s followed by "
                "motion in the recording (initial_attitude 'level' needs the IMU still at the "
                "start)"))
        q_arr = np.array(qs).reshape(-1, 4)
        var_rows = known = None
        if any(x is not None for x in variances):
            known = np.array([x is not None for x in variances])
            var_rows = np.array([x if x is not None else np.zeros(3) for x in variances])
        return StreamResult(np.array(index, dtype=np.int64), q_arr, var_rows, known, action,
                            self.counts, self.time_jump_resets, dict(self.details),
                            self.bias_report, self.alignment)


_ONES = np.ones(3)


def _rows(a: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """``a[rows]`` for sorted row indices; a view when they are consecutive (the usual
    case: a recording without bad samples), sparing a copy of the whole recording."""
    if rows.size and int(rows[-1]) - int(rows[0]) == rows.size - 1:
        return a[int(rows[0]):int(rows[-1]) + 1]
    return a[rows]


def _usable_accel(a: np.ndarray) -> np.ndarray:
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


def _nav_rows(nav: NavFrame | None, rows: np.ndarray, n: int) -> NavFrame | None:
    """``nav`` restricted to the input rows ``rows`` (time series of length n are sliced)."""
    if nav is None:
        return None
    changes = {}
    for f in fields(nav):
        a = np.asarray(getattr(nav, f.name))
        if a.ndim >= 1 and a.shape[0] == n and not (f.name == "velocity_enu" and a.ndim == 1):
            changes[f.name] = a[rows]
    return replace(nav, **changes) if changes else nav
