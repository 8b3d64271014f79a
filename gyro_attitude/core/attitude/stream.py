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
  non-finite or negative diagonal is treated as unknown and counted (``invalid_covariance``);
* every attitude handed out is finite and unit: should an update ever produce a non-finite
  quaternion, the stream restores the last good attitude, restarts its time base at the next
  sample and counts an ``integrator_error`` instead.

The two paths give the same attitudes sample for sample: :meth:`run` classifies the whole
recording with :func:`.validation.classify` and integrates each run of accepted samples in one
batch call (the batch and streaming integrators agree to ~1e-16); it falls back to the per-sample
path from the first segment that would produce a non-finite attitude.
"""

from __future__ import annotations

import math
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
from gyro_attitude.core.rotation import quat_normalize

INVALID_COVARIANCE = "invalid_covariance"
INTEGRATOR_ERROR = "integrator_error"


def gyro_variances(covariance) -> tuple[np.ndarray | None, bool]:
    """(per-axis variances, invalid) of a row-major 3x3 ``angular_velocity_covariance``.

    ``None, False`` when it carries no estimate (element 0 = −1, REP-145) or is all zeros
    (unknown); ``None, True`` when its diagonal is non-finite or negative (treated as unknown).
    """
    if covariance is None:
        return None, False
    c = np.asarray(covariance, dtype=np.float64).reshape(-1)
    if c.size != 9:
        return None, True
    if c[0] == -1.0:
        return None, False
    d = c[[0, 4, 8]]
    if not np.all(np.isfinite(d)) or np.any(d < 0):
        return None, True
    if not np.any(c):
        return None, False
    return d, False


def gyro_variances_array(covariance: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Array form of :func:`gyro_variances` for (N, 9): (variances (N, 3), known, invalid)."""
    c = np.asarray(covariance, dtype=np.float64)
    d = c[:, [0, 4, 8]]
    no_estimate = c[:, 0] == -1.0
    with np.errstate(invalid="ignore"):
        invalid = ~no_estimate & (~np.isfinite(d).all(axis=1) | (d < 0).any(axis=1))
        zeros = ~np.any(c != 0, axis=1)
    known = ~no_estimate & ~invalid & ~zeros
    return np.where(known[:, None], d, 0.0), known, invalid


@dataclass(frozen=True)
class StreamConfig:
    """Thresholds of the policy (see the module docstring); times in ns."""

    max_gap_ns: int = 100_000_000
    time_jump_ns: int = 1_000_000_000
    max_rate_rad_s: float = v.DEFAULT_MAX_RATE_RAD_S
    initial_variance: float = 0.0

    def __post_init__(self):
        self.check_config()  # raises ValueError naming the field
        iv = self.initial_variance
        if isinstance(iv, bool) or not isinstance(iv, int | float | np.integer | np.floating) \
                or not (math.isfinite(iv) and iv >= 0):
            raise ValueError(f"initial_variance must be a finite number >= 0, got {iv!r}")

    def check_config(self) -> v.ImuCheckConfig:
        return v.ImuCheckConfig(self.max_gap_ns, self.time_jump_ns, self.max_rate_rad_s)


@dataclass
class StreamResult:
    """Attitudes of :meth:`AttitudeStream.run` over N input samples.

    ``index`` (M,) input positions that got an attitude (the others were skipped); ``q`` (M, 4)
    scalar-last, finite and unit; ``variance`` (M, 3) per-axis orientation variance [rad²] and
    ``variance_known`` (M,) whether a gyro covariance had been seen by that row (None, None when
    no input carried one); ``action`` (N,) verdict codes
    (:data:`.validation.ACTION_CODES`); ``counts`` per reason (rejections, ``gap``,
    ``invalid_covariance``, ``integrator_error``); ``time_jump_resets``; ``details`` the first
    log line per reason.
    """

    index: np.ndarray
    q: np.ndarray
    variance: np.ndarray | None
    variance_known: np.ndarray | None
    action: np.ndarray
    counts: dict[str, int]
    time_jump_resets: int
    details: dict[str, str] = field(default_factory=dict)

    @property
    def skipped(self) -> int:
        return int(self.action.shape[0] - self.index.shape[0])


class AttitudeStream:
    """Imu samples in, attitude out, under the one policy of the module docstring.

    ``algorithm`` a name from the registry (an offline one serves :meth:`run` only: it needs
    samples after each interval, so :meth:`push` refuses it); ``q0`` the initial attitude (also the one a time
    jump resets to); ``nav`` a :class:`NavFrame` for q_nb (Earth and transport rate removed) or
    None for q_ib; ``config`` the thresholds.
    """

    def __init__(self, algorithm: str = DEFAULT_ALGORITHM, q0=(0.0, 0.0, 0.0, 1.0),
                 nav: NavFrame | None = None, config: StreamConfig | None = None):
        self.config = config if config is not None else StreamConfig()
        self.q_initial = _unit_quat(q0)
        self.nav = nav
        self.algorithm = algorithm
        self.integrator = (StreamingIntegrator(algorithm=algorithm, q0=self.q_initial, nav=nav)
                           if get_algorithm(algorithm).causal else None)
        self.validator = v.ImuStreamValidator(self.config.check_config())
        self.intervals = v.IntervalStatistics(window=2000)
        self.counts_extra = {INVALID_COVARIANCE: 0, INTEGRATOR_ERROR: 0}
        self.details: dict[str, str] = {}
        self._resume_q: np.ndarray | None = None
        self._last_q: np.ndarray = self.q_initial
        self._angle_var = np.full(3, float(self.config.initial_variance))
        self._var_known = False

    # ------------------------------------------------------------------ state and settings
    @property
    def counts(self) -> dict[str, int]:
        return {**self.validator.counts, **self.counts_extra}

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
        """Per-axis orientation variance [rad²]; None while no gyro covariance was seen."""
        return self._angle_var.copy() if self._var_known else None

    def set_config(self, config: StreamConfig) -> None:
        """New thresholds from the next sample on (state kept)."""
        self.config = config
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

    # ------------------------------------------------------------------ one sample
    def push(self, t_ns: int, omega, frame_id: str = "",
             angular_velocity_covariance=None) -> tuple[v.Verdict, np.ndarray | None]:
        """One sample: its verdict and the attitude at ``t_ns`` (None when it was skipped)."""
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
        integ = self.integrator
        action = verdict.action
        last_t = integ.last_t_ns
        try:
            if action == v.ACCEPT:
                q = integ.update(t_ns, omega)
            else:
                if action == v.RESET_TIME_JUMP:
                    self.details.setdefault("time_jump", verdict.detail)
                    q0 = self.q_initial
                    self._angle_var[:] = self.config.initial_variance
                    self.intervals.clear()
                elif action == v.RESTART_AFTER_GAP:
                    self.details.setdefault(v.GAP, verdict.detail)
                    q0 = self._last_q
                else:  # START
                    q0 = self.q_initial if self._resume_q is None else self._resume_q
                    self._resume_q = None
                integ.reset(q0, None)
                q = integ.update(t_ns, omega)
        except ValueError as exc:  # defensive: the validator should have caught it
            return self._integrator_error(verdict, f"integrator refused a sample: {exc}")
        x, y, z, w = q.tolist()
        if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z) and math.isfinite(w)):
            return self._integrator_error(verdict, "non-finite attitude: last good one restored")
        if action == v.ACCEPT:
            dt = t_ns - last_t
            self.intervals.add(dt)
            if var is not None:
                # angle random walk: each interval adds an independent angle error of variance
                # σ_ω² dt² per axis, so the variance grows linearly in time (σ_ω² dt · T).
                dt_s = dt * 1e-9
                self._angle_var += var * (dt_s * dt_s)
        if var is not None:
            self._var_known = True
        self._last_q = q
        return verdict, q

    def _count(self, key: str, detail: str) -> None:
        self.counts_extra[key] += 1
        self.details.setdefault(key, detail)

    def _integrator_error(self, verdict: v.Verdict, detail: str):
        self._count(INTEGRATOR_ERROR, detail)
        self._resume_q = self._last_q
        self.integrator.reset(self._last_q, None)
        self.validator.last_t_ns = None  # next sample starts a fresh time base
        return v.Verdict(v.REJECT, INTEGRATOR_ERROR, detail), None

    # ------------------------------------------------------------------ a whole recording
    def run(self, t_ns, omega, frame_id: str | list[str] | None = "",
            angular_velocity_covariance=None) -> StreamResult:
        """All samples of a recording, in file order, on a fresh stream: what :meth:`push`
        would give sample by sample (the stream is left in the state after the last one).

        ``t_ns`` (N,) int stamps; ``omega`` (N, 3) rad/s; ``frame_id`` one for all or one per
        sample; ``angular_velocity_covariance`` (N, 9) or None.
        """
        if self.validator.last_t_ns is not None or self.validator.accepted:
            raise ValueError("run() needs a fresh AttitudeStream (it replays a whole recording)")
        t = np.asarray(t_ns)
        w = np.asarray(omega, dtype=np.float64)
        cls = v.classify(t, w, frame_id, self.config.check_config())
        n = w.shape[0]
        t = t.astype(np.int64, copy=False)
        codes = v.ACTION_CODES
        act = cls.action
        valid = np.flatnonzero(act != codes[v.REJECT])
        if angular_velocity_covariance is not None:
            cov = np.asarray(angular_velocity_covariance, dtype=np.float64)
            if cov.shape != (n, 9):
                raise ValueError(f"angular_velocity_covariance must have shape ({n}, 9), got "
                                 f"{cov.shape}")
            var_all, known_all, invalid_all = gyro_variances_array(cov)
        else:
            var_all = known_all = invalid_all = None

        # Each run of accepted samples (from a START, a restart after a gap or a time-jump
        # reset up to the next one) is one batch integration.
        bounds = np.append(np.flatnonzero(act[valid] != codes[v.ACCEPT]), valid.size)
        q_out = np.empty((valid.size, 4))
        for p0, p1 in zip(bounds[:-1].tolist(), bounds[1:].tolist(), strict=True):
            seg = valid[p0:p1]
            # START and a time-jump reset begin at the initial attitude; a gap holds the last
            q0 = q_out[p0 - 1] if act[seg[0]] == codes[v.RESTART_AFTER_GAP] else self.q_initial
            q_seg = integrate_batch(t[seg], w[seg], q0=q0, algorithm=self.algorithm,
                                    nav=_nav_rows(self.nav, seg, n))
            if not np.isfinite(q_seg).all():
                return self._run_pushing(t, w, frame_id, angular_velocity_covariance)
            q_out[p0:p1] = q_seg

        # Orientation variance: cumulative σ_ω² dt² over accepted intervals, restarting from the
        # initial variance at every time-jump reset, exactly as push() accumulates it.
        counts = dict(cls.counts)
        variance = variance_known = None
        if var_all is not None:
            counts[INVALID_COVARIANCE] = int(np.count_nonzero(invalid_all[valid]))
            known_v = known_all[valid]
            if known_v.any():
                dt = np.zeros(valid.size)
                acc = act[valid] == codes[v.ACCEPT]
                tv = t[valid]
                dt[1:] = (tv[1:] - tv[:-1]) * 1e-9
                grow = np.where((acc & known_v)[:, None], var_all[valid] * (dt * dt)[:, None],
                                0.0)
                variance = np.empty((valid.size, 3))
                resets = np.flatnonzero(act[valid] == codes[v.RESET_TIME_JUMP])
                bounds = np.concatenate(([0], resets, [valid.size]))
                init = float(self.config.initial_variance)
                for b0, b1 in zip(bounds[:-1], bounds[1:], strict=True):
                    if b1 > b0:
                        g = grow[b0:b1].copy()
                        g[0] += init
                        variance[b0:b1] = np.cumsum(g, axis=0)
                # rows before the first known covariance have no estimate (as push: None)
                variance_known = np.maximum.accumulate(known_v)
                variance[~variance_known] = 0.0
            if counts[INVALID_COVARIANCE]:
                k = int(valid[np.flatnonzero(invalid_all[valid])[0]])
                cls.details.setdefault(INVALID_COVARIANCE, f"angular_velocity_covariance "
                                       f"{cov[k].tolist()} has a non-finite or negative "
                                       "diagonal: treated as unknown")
        else:
            counts[INVALID_COVARIANCE] = 0
        counts[INTEGRATOR_ERROR] = 0
        self._adopt_batch_state(cls, t, w, valid, q_out, counts)
        return StreamResult(valid, q_out, variance, variance_known, act, counts,
                            cls.time_jump_resets, dict(cls.details))

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
            self._last_q = q_out[-1].copy()
            if self.integrator is not None:
                self.integrator.reset(self._last_q, int(t[valid[-1]]))

    def _run_pushing(self, t, w, frame_id, covariance) -> StreamResult:
        """Per-sample path over the whole recording (the batch met a non-finite attitude)."""
        n = w.shape[0]
        frames = [frame_id] * n if frame_id is None or isinstance(frame_id, str) else frame_id
        index, qs, variances = [], [], []
        action = np.zeros(n, np.int8)
        for k in range(n):
            cov_k = None if covariance is None else covariance[k]
            verdict, q = self.push(int(t[k]), w[k], frames[k] or "", cov_k)
            if q is None:
                continue
            action[k] = v.ACTION_CODES[verdict.action]
            index.append(k)
            qs.append(q)
            variances.append(self._angle_var.copy() if self._var_known else None)
        q_arr = np.array(qs).reshape(-1, 4)
        var_rows = known = None
        if any(x is not None for x in variances):
            known = np.array([x is not None for x in variances])
            var_rows = np.array([x if x is not None else np.zeros(3) for x in variances])
        return StreamResult(np.array(index, dtype=np.int64), q_arr, var_rows, known, action,
                            self.counts, self.time_jump_resets, dict(self.details))


def _unit_quat(q) -> np.ndarray:
    a = np.asarray(q, dtype=np.float64)
    if a.shape != (4,) or not np.all(np.isfinite(a)) or not np.linalg.norm(a) > 1e-9:
        raise ValueError(f"initial attitude must be 4 finite numbers, not all zero; got {q!r}")
    return quat_normalize(a)


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
