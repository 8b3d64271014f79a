"""The aided form of :meth:`AttitudeStream.run`: the data-only stages as arrays, one loop for the
feedback.

With aiding on, the correction of every sample depends on the attitude it corrects, so the chain
cannot run as arrays end to end.  But most of the chain never looks at the attitude: the verdicts
of the validator, the accelerometer's usability, saturation, the rest windows (which rows a rest
accumulates and from which sample), the alignment, the gyro variances and the magnetometer's
missing rows are the data's alone.  Those run as their array forms
(:func:`.stream_batch.data_stages`, :func:`.stream_batch.rest_plan`, the same functions as the
array form of the chain), and one loop over the accepted rows takes what truly is sequential,
through the per-sample step of :meth:`AttitudeStream.push` itself:

* the bias stage's accumulation (:meth:`.gyro_bias.GyroBiasEstimator.accumulate` at the rows the
  rest plan names; the value a rest averages needs the attitude at its sample when the Earth rate
  is taken out) and what a new estimate does to the stream (``_bias_published``: the first rest
  applied back to the start, zero-rate updates of the covariance);
* the start from the alignment (``_aligned``) and aiding → integration → covariance
  (``_integrate``, the one sequential step).

So push() and run() share one implementation of every sequential step; the results are the same
floats in the same operations (tested equal, ≤ 1e-12, in every mode).

Runs of accepted rows (the motion, and the rests once the first estimate can no longer be
applied back to the start) go through :func:`accept_rows`, compiled (:mod:`gyro_attitude.core.jit`):
the stages' own kernels on their state arrays (the rest value at the attitude then,
``accumulate`` / ``close_rest`` and the zero-rate update; ``gravity_step`` / ``ahrs_step``,
``cubic_advance``, the covariance's ``propagate`` / ``aid_tilt``) in the order of
:meth:`AttitudeStream._integrate`, with no interpreter per sample.  That needs the causal cubic
and a constant nav frame (or none); otherwise, and for every other row (a sample the validator
did not simply accept, the alignment, the first rest), the loop takes ``_integrate`` itself.
When the loop meets an integrator error (a non-finite attitude, which restarts the validator's
time base) it returns None and :meth:`AttitudeStream.run` pushes every sample instead.
"""

from __future__ import annotations

import bisect
import math

import numpy as np

from gyro_attitude.core.attitude import validation as v
from gyro_attitude.core.attitude.ahrs import (
    I_HAS_LAST,
    MAG_ABSENT,
    MAG_GIVEN,
    MAG_NOT_FLOATS,
    AhrsFilter,
)
from gyro_attitude.core.attitude.alignment import level_quaternions
from gyro_attitude.core.attitude.covariance import V_TT, zero_rate_update
from gyro_attitude.core.attitude.gravity_aiding import G_HAS_LAST, GravityAiding
from gyro_attitude.core.attitude.gyro_bias import (
    B_BIAS,
    B_SE,
    J_HAS_SEG,
    J_UPDATED,
    _c_bn_times,
    accumulate,
    close_rest,
)
from gyro_attitude.core.attitude.modes import Aiding, GyroBiasMode
from gyro_attitude.core.attitude.sample_step import advance_accepted
from gyro_attitude.core.attitude.stream import (
    _ACCEPTED,
    _STARTED,
    EXTRA_COUNTS,
    GYRO_NOISE_UNKNOWN,
    MAG_MISSING,
    RUNNING,
    RunForm,
    StreamResult,
    cannot_align,
    covariance_rows,
    rows,
    unknown_noise_note,
)
from gyro_attitude.core.attitude.stream_batch import data_stages, rest_plan
from gyro_attitude.core.earth import STANDARD_GRAVITY
from gyro_attitude.core.jit import compiled, kernel

__all__ = ["run_loop"]

_ACCEPT, _START = v.ACTION_CODES[v.ACCEPT], v.ACTION_CODES[v.START]
_VERDICT_OF_CODE = {code: action for action, code in v.ACTION_CODES.items()}


def run_loop(s, t, w, frame_id, cov, acc, mag) -> StreamResult | None:
    """The chain over a recording on the fresh stream ``s`` (see the module docstring); None
    when an integrator error needs the per-sample form."""
    cfg, st = s.config, s.state
    rec = data_stages(s, t, w, frame_id, acc,
                      mag if cfg.aiding is Aiding.MAGNETOMETER else None)
    valid, tv, wv, actv, counts, details = (rec.valid, rec.tv, rec.wv, rec.actv, rec.counts,
                                            rec.details)
    m = valid.size
    # the stages' details first: the loop's own setdefault() then keeps them, as push() does
    for key, text in details.items():
        st.details.setdefault(key, text)

    # per-row inputs of the rows Python steps, as the per-sample steps take them (converted
    # on demand: the compiled rows take the arrays)
    tl, wl, actl = _RowInts(tv), _RowTuples(wv), _RowInts(actv)
    al = _RowTuples(None, None)
    if rec.av is not None:
        al = _RowTuples(rec.av, rec.a_ok)
    # rows where push() breaks the windows, which restarts the aiding's time base: a gap, a
    # jump, a restart, an unusable accelerometer sample
    restart = rec.breaks.copy()
    if rec.a_ok is not None:
        restart |= ~rec.a_ok
    var_rows = _RowTuples(None, None)
    known_rows = np.zeros(m, dtype=bool)
    if cov is not None:
        var_v, known_v = covariance_rows(cov, valid, counts, details)
        if v.no_estimate(rows(cov, valid)).any():
            st.details.setdefault(GYRO_NOISE_UNKNOWN, unknown_noise_note(cfg))
        known_rows = np.asarray(known_v, dtype=bool)
        var_rows = _RowTuples(var_v, known_rows)
    # whether anything gives an orientation variance by each row
    variance_known = np.maximum.accumulate(known_rows) | st.variance_known if m \
        else np.zeros(0, dtype=bool)
    ml = _RowTuples(None, None)
    if cfg.aiding is Aiding.MAGNETOMETER:
        if mag is None:
            missing = np.ones(m, dtype=bool)
        else:
            mv = rows(mag, valid)
            missing = np.isnan(mv).all(axis=1)
            ml = _RowTuples(mv, ~missing)
        s._mag_missing = int(np.count_nonzero(missing))
        if s._mag_missing:
            k = int(valid[np.flatnonzero(missing)[0]])
            st.details.setdefault(MAG_MISSING, f"no field sample at stamp {int(t[k])} "
                                               "(none within mag_max_age_s)")

    # the rests: which row accumulates which sample (from the detector's array form)
    est = s.bias_estimator
    auto = est.mode is GyroBiasMode.AUTO
    ev_rows: list[int] = []
    ev_src: list[int] = []
    ev_first: list[bool] = []
    if auto and m:
        (idx, _), plan = rest_plan(est, rec)
        est.reset()
        for kk, j in plan:
            ev_rows += idx[kk].tolist()
            ev_src += idx[j].tolist()
            ev_first += [True] + [False] * (kk.size - 1)
    earth = auto and s.latitude_rad is not None
    # per row: the rest sample it accumulates (-1: none), whether that opens a rest, whether
    # its own value (rate less the Earth rate at the attitude then) is needed later
    ev_src_row = np.full(m, -1, dtype=np.int64)
    ev_first_row = np.zeros(m, dtype=bool)
    need_row = np.zeros(m, dtype=bool)
    if ev_rows:
        ev_at = np.array(ev_rows, dtype=np.int64)
        ev_src_row[ev_at] = ev_src
        ev_first_row[ev_at] = ev_first
        if earth:
            need_row[np.array(ev_src, dtype=np.int64)] = True
    vals = np.zeros((m, 3))
    vals_earth = np.zeros(m, dtype=bool)

    align = rec.align
    done = align[0] if align is not None else -1
    first_row = align[1] if align is not None else 0
    if earth and align is not None:
        # while aligning the bias stage takes the Earth rate out at the attitude levelled from
        # each sample's force (data only: the array form of level_quaternion, as run_arrays)
        lv = np.flatnonzero(need_row[:done + 1]).tolist()
        if lv:
            q_lv, usable = level_quaternions(np.where(rec.a_ok[lv, None], rec.av[lv], 0.0),
                                             math.radians(cfg.initial_heading_deg))
            usable &= rec.a_ok[lv]
            for k, qk, ok_k in zip(lv, q_lv.tolist(), usable.tolist(), strict=True):
                vals[k], vals_earth[k] = est.value(wl[k], qk if ok_k else None)
            need_row[lv] = False
    aid = s.aiding
    integrate = s._integrate
    bias_attitude = s._bias_attitude
    published = s._bias_published
    covariance = s.covariance
    has_q = np.zeros(m, dtype=bool)
    q_out = np.empty((m, 4))
    tt_out = np.empty((m, 3))
    bias = est.bias_floats
    fast = _Compiled.for_stream(s, rec, var_rows, ml, restart, (
        earth, need_row, ev_src_row, ev_first_row, vals, vals_earth)) if m else None
    # the rows the compiled loop must stop before (Python runs them): rows not accepted; and,
    # while the first bias estimate may still be applied back to the start, the rest rows
    stop_rows = np.append(np.flatnonzero(rec.actv != _ACCEPT) if m else [], m).astype(
        np.int64).tolist()
    stop_or_ev = np.append(np.flatnonzero((rec.actv != _ACCEPT) | (ev_src_row >= 0))
                           if m else [], m).astype(np.int64).tolist()
    ns = 0
    r = 0
    while r < m:
        t_r = tl[r]
        if st.start_t_ns is None:
            st.start_t_ns = t_r
        code = actl[r]
        if fast is not None and code == _ACCEPT and st.phase is RUNNING and not (
                st.first_rest_pending and ev_src_row[r] >= 0):
            # 2. and 4.-6. compiled, up to the next row where Python must act
            stops = stop_or_ev if st.first_rest_pending else stop_rows
            ns = bisect.bisect_right(stops, r)
            end = stops[ns]
            if not fast.run(r, end, bias, q_out, tt_out):
                return None
            bias = est.bias_floats
            has_q[r:end] = True
            r = end
            continue
        # 2. rest -> gyro bias: the value this sample gives a rest, then the accumulation the
        # rest plan puts at this row
        if need_row[r]:
            vals[r], vals_earth[r] = est.value(wl[r], bias_attitude(al[r]))
        j = int(ev_src_row[r])
        if j >= 0:
            if ev_first_row[r] and est.open_rest_start_ns is not None:
                est.close_rest()  # the previous rest ended (push() closed it when it did)
            g_j, earth_j = (tuple(vals[j].tolist()), bool(vals_earth[j])) if earth \
                else (wl[j], False)
            previous = bias
            est.accumulate(tl[j], g_j, earth_j)
            if est.updated:
                if st.first_rest_pending and fast is not None:
                    fast.settle()  # the first estimate may reset the integrator
                published(previous)
            bias = est.bias_floats
        # 3. alignment
        if st.phase is not RUNNING:
            if r == done:
                if fast is not None:
                    fast.settle()
                q = s._aligned(align[2], [(tl[k], wl[k], al[k], var_rows[k], ml[k])
                                          for k in range(first_row, done + 1)], bias)
                if q is None or st.phase is not RUNNING:
                    return None
                has_q[r] = True
                q_out[r] = q
                tt_out[r] = covariance.tt_floats()
            r += 1
            continue
        # 4.-6. aiding, integration, covariance
        if fast is not None:
            fast.settle()
        if restart[r] and aid is not None:
            aid.last_t_ns = None
        verdict = _ACCEPTED if code == _ACCEPT else (
            _STARTED if code == _START else v.Verdict(_VERDICT_OF_CODE[code], None, ""))
        x = wl[r]
        _, q = integrate(verdict, t_r, (x[0] - bias[0], x[1] - bias[1], x[2] - bias[2]), al[r],
                         var_rows[r], ml[r])
        if q is None:
            return None  # an integrator error: the per-sample form handles what follows
        has_q[r] = True
        q_out[r] = q
        tt_out[r] = covariance.tt_floats()
        r += 1

    # the state after the last row, as push() would leave it (the rest windows start again)
    if fast is not None:
        fast.settle()
    est.break_window()
    if m:
        st.accel_present = None if rec.a_ok is None else (bool(rec.a_ok[-1]) or None)
        if acc is None:
            st.accel_present = False
        st.variance_known = bool(variance_known[-1])
    for key in EXTRA_COUNTS:  # the data-only stages' counts beside what the loop counted
        st.counts[key] += counts[key]
    for key, text in details.items():
        st.details.setdefault(key, text)
    if st.phase is not RUNNING:
        raise ValueError(s.alignment_error or cannot_align(cfg))
    index = np.flatnonzero(has_q)
    q_arr = q_out[index]
    variance = known = None
    if m and np.asarray(variance_known, dtype=bool)[index].any():
        known = np.asarray(variance_known, dtype=bool)[index]
        variance = np.where(known[:, None], tt_out[index], 0.0)
    return StreamResult(valid[index], q_arr, variance, known,
                        rec.cls.action, s.counts, rec.cls.time_jump_resets, dict(st.details),
                        s.bias_report, s.alignment, RunForm.LOOP)


_UNSET = object()


def _plain(a, dtype) -> np.ndarray:
    """``a`` as a C-contiguous, writeable array of ``dtype`` (a copy only when it is not): the
    compiled loop's argument types stay the same whatever the input (a read-only array of a
    file's buffer would be another signature, compiled again)."""
    return np.require(a, dtype, ["C", "W"])


def compile_kernels(config=None, algorithm: str | None = None) -> None:
    """Compile (or load from numba's cache) what the causal chain runs compiled: a short
    synthetic recording (rest, turn, rest; accelerometer and field) through :meth:`run` and
    :meth:`push` of a stream with ``config`` (and ``algorithm``), or with every aiding mode.
    The start is the given attitude whatever ``config`` says (a levelling or gyrocompassing
    start might never align on it; its kernels are the same).  The node calls it at start-up
    and dev.sh after installing, so that no sample waits for the compiler."""
    from dataclasses import replace

    from gyro_attitude.core.attitude import DEFAULT_ALGORITHM
    from gyro_attitude.core.attitude.alignment import level_quaternion
    from gyro_attitude.core.attitude.modes import HeadingSource, InitialAttitudeSource
    from gyro_attitude.core.attitude.settings import StreamConfig
    from gyro_attitude.core.attitude.stream import AttitudeStream

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
    algorithm = algorithm or DEFAULT_ALGORITHM
    level_quaternion((0.0, 0.0, STANDARD_GRAVITY), 0.0)  # levelling's own call (alignment)
    for cfg in configs:
        cfg = replace(cfg, initial_attitude_source=InitialAttitudeSource.PARAMETER,
                      heading_source=HeadingSource.PARAMETER)
        AttitudeStream(algorithm, config=cfg).run(t, w, "imu", cov, a, mag)
        s = AttitudeStream(algorithm, config=cfg)
        for k in range(n):
            s.push(int(t[k]), w[k], "imu", cov[k], a[k], mag[k])


class _RowTuples:
    """``rows[r]``: row ``r`` of an (M, 3) array as 3 floats, None where ``ok`` is False (or
    for every row without an array), made when asked: only the rows Python steps need one."""

    __slots__ = ("a", "ok")

    def __init__(self, a, ok=None):
        self.a = a
        self.ok = None if a is None else (None if ok is None else np.asarray(ok, dtype=bool))

    def __getitem__(self, r):
        if self.a is None or (self.ok is not None and not self.ok[r]):
            return None
        return tuple(self.a[r].tolist())


class _RowInts:
    """``rows[r]``: element ``r`` of an integer array as a Python int."""

    __slots__ = ("a",)

    def __init__(self, a):
        self.a = a

    def __getitem__(self, r):
        return int(self.a[r])


class _Compiled:
    """The arguments of :func:`accept_rows` for one stream and recording: the per-row inputs
    as arrays and the stages' state arrays (stepped in place)."""

    @classmethod
    def for_stream(cls, s, rec, var_rows, ml, restart, plan):
        """The compiled form's arguments, or None when a stage has no kernel here (another
        algorithm than the causal cubic, a nav frame with time series).  ``var_rows`` and
        ``ml`` the loop's per-row gyro variances and fields, ``plan`` its rest plan (earth,
        need_row, ev_src_row, ev_first_row, vals, vals_earth)."""
        integ = s.integrator
        if integ.cubic is None or integ._nav_rates is not None:
            return None
        aid = s.aiding
        if aid is not None and not isinstance(aid, GravityAiding | AhrsFilter):
            return None
        return cls(s, rec, var_rows, ml, restart, plan)

    def __init__(self, s, rec, var_rows, ml, restart, plan):
        m = rec.valid.size
        self.s = s
        self.t = _plain(rec.tv, np.int64)
        self.w = _plain(rec.wv, np.float64)
        if rec.av is None:
            self.a, self.a_ok = np.zeros((m, 3)), np.zeros(m, dtype=bool)
        else:
            self.a = _plain(rec.av, np.float64)
            self.a_ok = _plain(rec.a_ok, bool)
        self.m = np.zeros((m, 3))
        self.m_state = np.full(m, MAG_ABSENT, dtype=np.int64)
        if ml.a is not None:  # the fields (aiding magnetometer): absent where not ml.ok
            finite = np.isfinite(ml.a).all(axis=1)
            self.m = _plain(np.where(finite[:, None], ml.a, 0.0), np.float64)
            self.m_state = _plain(np.where(ml.ok, np.where(finite, MAG_GIVEN, MAG_NOT_FLOATS),
                                           MAG_ABSENT), np.int64)
        self.var_ok = np.zeros(m, dtype=bool) if var_rows.ok is None else _plain(var_rows.ok,
                                                                                 bool)
        self.var = np.zeros((m, 3)) if var_rows.a is None else _plain(np.where(
            self.var_ok[:, None], var_rows.a, 0.0), np.float64)
        self.restart = _plain(restart, bool)
        self.dt = np.zeros(m, dtype=np.int64)
        aid = s.aiding
        self.kind = 0 if aid is None else (1 if isinstance(aid, GravityAiding) else 2)
        dummy_f, dummy_i = np.zeros(1), np.zeros(1, dtype=np.int64)
        g = (aid.params, aid.gf, aid.gi) if self.kind == 1 else (dummy_f, dummy_f, dummy_i)
        h = (aid.pa, aid.af, aid.ai) if self.kind == 2 else (dummy_f, dummy_f, dummy_i)
        integ = s.integrator
        cs, nav = integ.cubic, integ._nav_const
        # the arguments that stay (arrays stepped in place, settings)
        self._inputs = (
            self.a, self.a_ok, self.m, self.m_state, self.var, self.var_ok, self.restart,
            self.kind, *g, *h, cs.ci, cs.ts, cs.ws, cs.cf, nav is not None,
            *((0.0, 0.0, 0.0) if nav is None else (float(nav[0]), float(nav[1]),
                                                  float(nav[2]))),
            s.covariance.c, s.covariance.k2, s._n2, 0.0 if aid is None else aid.kp)
        self._floor_for, self._floor = _UNSET, 0.0
        self._stale: list[tuple[int, int]] = []
        earth, need_row, ev_src_row, ev_first_row, vals, vals_earth = plan
        est = s.bias_estimator
        earth_n = est._earth_n if earth else np.zeros(3)
        self._rests = (bool(earth), np.asarray(earth_n, dtype=np.float64), need_row,
                       ev_src_row, ev_first_row, vals, vals_earth, est.bf, est.bi,
                       est.min_rest_ns)

    def run(self, r0: int, r1: int, bias, q_out, tt_out) -> bool:
        """Rows r0..r1-1 (all accepted, nothing else happening there) through steps 4.-6.;
        False on an integrator error (the per-sample form takes over).  The integrator's and
        the interval statistics' Python side catch up in :meth:`settle`."""
        s = self.s
        st = s.state
        q = st.q
        if self._floor_for is not s.alignment:
            self._floor_for = s.alignment
            self._floor = (s.alignment.level_error_expected if s.alignment is not None
                           else s.config.accel_bias_sigma / STANDARD_GRAVITY) ** 2
        bad, seen, first_fb, n_fb, q0, q1, q2, q3 = compiled(accept_rows)(
            r0, r1, self.t, self.w, bias[0], bias[1], bias[2], *self._inputs, self._floor,
            st.aided_seen, q[0], q[1], q[2], q[3], q_out, tt_out, self.dt, *self._rests)
        self._stale.append((r0, r1))
        if bad >= 0:
            return False
        st.aided_seen = seen
        st.q = (q0, q1, q2, q3)
        if n_fb:
            st.count_fit_fallbacks(n_fb, int(self.t[first_fb]))
        return True

    def settle(self) -> None:
        """Bring the integrator's Python attributes and the interval statistics up to the
        rows run so far (before Python code reads them)."""
        if not self._stale:
            return
        s = self.s
        s.integrator.synced()
        window = s.intervals.window
        dts = np.concatenate([self.dt[a:b] for a, b in self._stale[-window:]])
        s.intervals.extend(dts[-window:])
        self._stale = []


@kernel
def accept_rows(r0, r1, t, w, b0, b1, b2, a, a_ok, m, m_state, var, var_ok, restart, kind,
                gp, gf, gi, pa, af, ai, ci, ts, ws, cf, has_nav, n0, n1, n2, c, k2, noise2, kp,
                floor_var, aided_seen, x, y, z, u, q_out, tt_out, dt_out, earth, earth_n,
                need_row, ev_src_row, ev_first_row, vals, vals_earth, bf, bi, min_rest_ns):
    """Step 2. at the rests the plan names (run_loop: ``need_row``, ``ev_src_row``,
    ``ev_first_row``; the values in ``vals``/``vals_earth``; the bias estimator's state
    ``bf``/``bi``; a new estimate is a zero-rate update of the covariance) and steps 4.-6. of
    :meth:`AttitudeStream._integrate` (an accepted sample: aiding ``kind`` 0 none, 1 gravity,
    2 AHRS; the causal cubic; the covariance) over rows ``r0..r1-1``, from the bias ``b`` and
    the attitude ``(x, y, z, u)``; attitudes and ``tt`` into ``q_out``/``tt_out``, interval
    lengths into ``dt_out``.  Returns (the row of an integrator error or -1, the aiding's
    sample count, the first row whose fit fell back, how many fell back, the last attitude)."""
    first_fb = -1
    n_fb = 0
    for r in range(r0, r1):
        tr = t[r]
        # 2. the value this sample gives a rest (its rate less the Earth rate seen at the
        # attitude now), then the accumulation the rest plan puts at this row
        if need_row[r]:
            e0, e1, e2 = _c_bn_times(x, y, z, u, 2.0 / (x * x + y * y + z * z + u * u), earth_n)
            vals[r, 0], vals[r, 1], vals[r, 2] = w[r, 0] - e0, w[r, 1] - e1, w[r, 2] - e2
            vals_earth[r] = True
        j = ev_src_row[r]
        if j >= 0:
            if ev_first_row[r] and bi[J_HAS_SEG] == 1:
                close_rest(bf, bi, min_rest_ns)
            if earth:
                accumulate(bf, bi, min_rest_ns, t[j], vals[j, 0], vals[j, 1], vals[j, 2],
                           vals_earth[j])
            else:
                accumulate(bf, bi, min_rest_ns, t[j], w[j, 0], w[j, 1], w[j, 2], False)
            if bi[J_UPDATED] == 1:
                zero_rate_update(c, bf[B_SE], bf[B_SE + 1], bf[B_SE + 2])
            b0, b1, b2 = bf[B_BIAS], bf[B_BIAS + 1], bf[B_BIAS + 2]
        if restart[r] and kind != 0:
            if kind == 1:
                gi[G_HAS_LAST] = 0
            else:
                ai[I_HAS_LAST] = 0
        ok, fb, aided_seen, dt, qx, qy, qz, qu = advance_accepted(
            kind, gp, gf, gi, pa, af, ai, ci, ts, ws, cf, has_nav, n0, n1, n2, c, k2, noise2, kp,
            floor_var, aided_seen, tr, w[r, 0] - b0, w[r, 1] - b1, w[r, 2] - b2, a_ok[r],
            a[r, 0], a[r, 1], a[r, 2], m_state[r], m[r, 0], m[r, 1], m[r, 2], var_ok[r],
            var[r, 0], var[r, 1], var[r, 2], x, y, z, u)
        if fb != 0:
            n_fb += fb
            if first_fb < 0:
                first_fb = r
        if not ok:
            return r, aided_seen, first_fb, n_fb, x, y, z, u
        x, y, z, u = qx, qy, qz, qu
        dt_out[r] = dt
        q_out[r, 0], q_out[r, 1], q_out[r, 2], q_out[r, 3] = x, y, z, u
        tt_out[r, 0], tt_out[r, 1], tt_out[r, 2] = c[V_TT], c[V_TT + 1], c[V_TT + 2]
    return -1, aided_seen, first_fb, n_fb, x, y, z, u
