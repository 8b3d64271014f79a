"""The array form of the attitude stream's chain over a whole recording (:meth:`AttitudeStream.run`).

Each stage runs its own array form and leaves its own state as its per-sample step would:

1. validate: :meth:`.validation.ImuStreamValidator.run` (the verdicts of ``classify``); unusable
   accelerometer rows counted;
2. rest → gyro bias: :meth:`.gyro_bias.GyroBiasEstimator.run` over the accepted rows, windows
   broken where the per-sample step breaks them — before every gap, jump, restart and unusable
   accelerometer row (the usable row right after an unusable one is not fed: the streaming
   detector refuses it, an accelerometer appearing mid-window);
3. alignment: :meth:`.alignment.StaticAligner.run` (levelling): the first rest that ends;
4. integrate: one batch call per run of accepted rows between two events (a restart, a gap, a
   jump, the alignment, the first bias estimate applied back to the start), with each row's
   ``ω − bias``;
5. covariance: :meth:`.covariance.AttitudeCovariance.run` (restarted cumulative sums).

:func:`run_arrays` returns None when an integration produced a non-finite attitude; the caller
then runs the per-sample form, which restores the last good attitude and counts it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gyro_attitude.core.attitude import integrate_batch
from gyro_attitude.core.attitude import validation as v
from gyro_attitude.core.attitude.alignment import level_quaternions
from gyro_attitude.core.attitude.modes import GyroBiasMode
from gyro_attitude.core.attitude.stream import (
    EXTRA_COUNTS,
    GYRO_NOISE_UNKNOWN,
    INVALID_ACCEL,
    RATE_FIT_FALLBACK,
    RUNNING,
    SATURATED,
    SATURATION_MIN_RAD_S,
    RunForm,
    StreamResult,
    cannot_align,
    covariance_rows,
    invalid_accel_note,
    nav_rows,
    rate_fit_note,
    rows,
    saturation_note,
    unknown_noise_note,
    usable_accel,
)
from gyro_attitude.core.rotation import quat_from_rotvec, quat_multiply

__all__ = ["Recording", "count_saturated", "data_stages", "rest_plan", "run_arrays"]

_EARTH_PASSES = 8  # fixed-point passes allowed for the Earth rate at the current attitude

_ACCEPT = v.ACTION_CODES[v.ACCEPT]
_REJECT = v.ACTION_CODES[v.REJECT]
_RESTART = v.ACTION_CODES[v.RESTART_AFTER_GAP]
_RESET = v.ACTION_CODES[v.RESET_TIME_JUMP]


@dataclass
class Recording:
    """The data-only stages of the chain over a recording (:func:`data_stages`), which every
    form of :meth:`AttitudeStream.run` shares: the verdicts ``cls``, the accepted rows
    ``valid`` (M,) with their stamps ``tv``, rates ``wv``, verdict codes ``actv``, specific
    force ``av`` and whether it is usable ``a_ok`` (None without accelerometer), the rows that
    break the rest windows ``breaks``, the counts and details of those stages, and the
    alignment ``align = (done row, first integrated row, AlignmentResult)`` when levelling."""

    cls: v.Classification
    valid: np.ndarray
    tv: np.ndarray
    wv: np.ndarray
    actv: np.ndarray
    av: np.ndarray | None
    a_ok: np.ndarray | None
    breaks: np.ndarray
    counts: dict
    details: dict
    align: tuple | None


def data_stages(s, t, w, frame_id, acc, mag=None, empty=np.empty) -> Recording:
    """Validation, the accelerometer's usability, saturation and alignment over a recording on
    the fresh stream ``s`` (their array forms, leaving each stage as its per-sample step
    would); ``mag`` (N, 3) the field for a heading from it at the alignment, or None;
    ``empty(shape, dtype)`` allocates the accepted rows' index and copies."""
    cfg, st = s.config, s.state
    cls = s.validator.run(t, w, frame_id)  # 1. validate
    act = cls.action
    valid = v.accepted_rows(act, empty)
    m = valid.size
    details = dict(cls.details)
    counts = dict.fromkeys(EXTRA_COUNTS, 0)
    tv, wv, actv = rows(t, valid, empty), rows(w, valid, empty), rows(act, valid)
    av = a_ok = None
    if acc is not None and m:
        av = rows(acc, valid)
        a_ok = usable_accel(av)
        bad = np.flatnonzero(~a_ok)
        if bad.size:
            counts[INVALID_ACCEL] = int(bad.size)
            details.setdefault(INVALID_ACCEL, invalid_accel_note(av[bad[0]]))
    breaks = actv != _ACCEPT  # a rest never spans a gap, a jump or a restart
    count_saturated(wv, st, counts, details)
    # 3. alignment (it reads the raw rates and the accelerometer only)
    align = None
    if cfg.levelling:
        if av is None:
            raise ValueError("alignment needs the accelerometer: no usable linear_acceleration")
        idx = np.flatnonzero(a_ok)
        cut = breaks.copy()
        cut[1:] |= ~a_ok[:-1]
        got = s.aligner.run(tv[idx], wv[idx], av[idx], cut[idx],
                            None if mag is None else rows(mag, valid)[idx])
        if got is None:
            raise ValueError(cannot_align(cfg))
        align = (int(idx[got[0]]), int(idx[got[1]]), got[2])
    return Recording(cls, valid, tv, wv, actv, av, a_ok, breaks, counts, details, align)


def run_arrays(s, t, w, frame_id, cov, acc, empty=np.empty) -> StreamResult | None:
    """The chain's array form over a recording on the fresh stream ``s`` (see the module
    docstring); None when an integration met a non-finite attitude.  ``empty(shape, dtype)``
    allocates the arrays of the recording's length: the accepted rows, the bias, the
    bias-corrected rates and the attitudes."""
    cfg, st = s.config, s.state
    rec = data_stages(s, t, w, frame_id, acc, empty=empty)
    cls, valid, tv, wv, actv = rec.cls, rec.valid, rec.tv, rec.wv, rec.actv
    av, a_ok, counts, details, align = rec.av, rec.a_ok, rec.counts, rec.details, rec.align
    act = cls.action
    m = valid.size
    start = 0  # first row integrated
    out_from = 0  # first row with an attitude
    q_start = st.q_initial
    if align is not None:
        start, out_from = align[1], align[0]
        q_start = align[2].q_nb

    # 2. and 4.: rest -> gyro bias, then integration.  With the Earth rate taken out of the
    # rest averages at the current attitude, the bias depends on the attitude it corrects:
    # iterated to the fixed point (each pass changes the attitude by ~ω_ie·T times the last
    # change: a few passes reach rounding), or the per-sample form when it does not settle.
    est = s.bias_estimator
    earth = est.mode is GyroBiasMode.AUTO and s.latitude_rad is not None
    # the attitude each row's bias step sees (only where the Earth rate is taken out)
    q_nb = np.tile(st.q_initial, (m, 1)) if earth else None
    known = np.ones(m, dtype=bool) if earth else None
    if earth and align is not None:  # while aligning: levelled from each sample's force
        q_lv, ok = level_quaternions(np.where(a_ok[:, None], av, 0.0)[:align[0] + 1],
                                     math.radians(cfg.initial_heading_deg))
        q_nb[:align[0] + 1] = q_lv
        known[:align[0] + 1] = ok & a_ok[:align[0] + 1]
    fed, plan = rest_plan(est, rec, empty)
    q_prev = None
    for _ in range(_EARTH_PASSES if earth else 1):
        values = est.values_without_earth(wv, q_nb, known) if earth else wv
        bias, track, updates = _bias_track(est, tv, wv, values, fed, known if earth else False,
                                           plan, empty)
        if align is not None:
            if not bias.flags.writeable:
                bias = bias.copy()
            bias[align[1]:align[0]] = bias[align[0]]  # buffered samples: the bias at the end
        fallbacks = []
        got = _integrate(s, t.shape[0], valid, tv, bias,
                         np.subtract(wv, bias, out=empty(wv.shape, np.float64)), actv, track,
                         updates, start, q_start, fallbacks, empty)
        if got is None:
            return None
        q, first_rest = got
        if not earth or (q_prev is not None and np.max(np.abs(q - q_prev)) <= 1e-15):
            break
        q_prev = q
        # the attitude each row's bias step sees: the one handed out at the row before
        q_nb[out_from + 1:] = q[out_from - start:-1]
    else:
        return None
    del fed, plan, values  # the rest plan's rows (per rest row): not needed from here on
    counts[RATE_FIT_FALLBACK] = sum(int(f[1].size) for f in fallbacks)
    if fallbacks:
        r0, kk = fallbacks[0]
        details.setdefault(RATE_FIT_FALLBACK, rate_fit_note(int(tv[r0 + int(kk[0])])))
    if updates.size:
        st.first_rest_pending = False
    if align is not None:
        done = align[0]
        if updates.size and updates[0] <= done:
            # the zero-rate updates while aligning set the bias variance the attitude starts
            # with (the last one counts: each sets it anew)
            k = int(np.searchsorted(updates, done, side="right")) - 1
            s.covariance.zero_rate_update(track.standard_error[k])
        s._start_aligned(align[2])
        updates_after = updates[updates > done]
    else:
        updates_after = updates

    # 5. covariance over the integrated rows
    var_v = known_v = None
    if cov is not None:
        var_v, known_v = covariance_rows(cov, valid, counts, details)
        if v.no_estimate(rows(cov, valid)).any():
            details.setdefault(GYRO_NOISE_UNKNOWN, unknown_noise_note(cfg))
    variance = variance_known = None
    known_any = known_v is not None and bool(known_v[out_from:].any())
    if known_any or st.variance_known:
        tt = _covariance_chunked(s, tv, actv, start, var_v, known_v, track, updates,
                                 updates_after, first_rest, empty)
        variance = tt[out_from - start:]
        kv = np.zeros(m - out_from, dtype=bool) if known_v is None else known_v[out_from:]
        variance_known = np.maximum.accumulate(kv) | st.variance_known
        variance[~variance_known] = 0.0
        if known_any:
            st.variance_known = True

    # the chain's state after the last row, as push() would leave it
    q_out = q[out_from - start:]
    # the input rate and jitter push() counts: the interval before each plainly accepted row
    # it integrated (not a start, a restart after a gap or a jump, nor the first row after
    # the alignment: the integration starts there), since the last time jump (which clears
    # them)
    codes = v.ACTION_CODES
    jumps = np.flatnonzero(actv[start:] == codes[v.RESET_TIME_JUMP])
    first = start + (int(jumps[-1]) if jumps.size else 0) + 1
    plain = _last_rows(actv, codes[v.ACCEPT], first, s.intervals.window)
    s.intervals.extend(tv[plain] - tv[plain - 1])
    if m:
        st.start_t_ns = int(tv[0])
        st.accel_present = None if a_ok is None else (bool(a_ok[-1]) or None)
        if acc is None:
            st.accel_present = False
        if q_out.shape[0]:
            st.q = tuple(q_out[-1].tolist())
            if s.integrator is not None:
                # the last sample is the integrator's history: the next push() integrates from
                # it (as after a restart: the fit rebuilds from two samples on)
                s.integrator.reset(q_out[-1], None)
                s.integrator.update(int(tv[-1]), wv[-1] - bias[-1])  # the last row's rate
    for key in EXTRA_COUNTS:
        st.counts[key] = counts[key]
    for key, text in details.items():
        st.details.setdefault(key, text)
    if st.phase is not RUNNING:  # no sample at all while levelling
        raise ValueError(s.alignment_error or cannot_align(cfg))
    return StreamResult(valid[out_from:], q_out, variance, variance_known, act,
                        s.counts, cls.time_jump_resets, dict(st.details), s.bias_report,
                        s.alignment, RunForm.ARRAYS)


def _last_rows(actv: np.ndarray, code: int, first: int, count: int) -> np.ndarray:
    """The last ``count`` rows from ``first`` on whose verdict is ``code``, in order, found from
    the end a chunk at a time (the interval statistics keep only that many)."""
    parts: list[np.ndarray] = []
    found = 0
    hi = actv.shape[0]
    while hi > first and found < count:
        lo = max(first, hi - COVARIANCE_CHUNK)
        got = lo + np.flatnonzero(actv[lo:hi] == code)
        parts.insert(0, got)
        found += got.size
        hi = lo
    return np.concatenate(parts)[-count:] if parts else np.zeros(0, np.int64)


#: rows per covariance chunk: its per-row inputs (dt, noise, zero-rate rows, standard errors)
#: and the cumulative sums' temporaries are built a chunk at a time (the covariance carries
#: its state from one chunk to the next, as from one sample to the next: the same bits)
COVARIANCE_CHUNK = 1 << 16


def _covariance_chunked(s, tv, actv, start, var_v, known_v, track, updates, updates_after,
                        first_rest, empty=np.empty) -> np.ndarray:
    """Step 5 over rows ``start`` … of the accepted rows, chunk by chunk: ``tt`` (rows, 3)."""
    m = tv.shape[0]
    tt = empty((m - start, 3), np.float64)
    upd_rows = updates_after - start
    upd_k = None if track is None else np.searchsorted(updates, updates_after)
    for c0 in range(0, m - start, COVARIANCE_CHUNK):
        c1 = min(c0 + COVARIANCE_CHUNK, m - start)
        r0, r1 = start + c0, start + c1
        dt = np.zeros(c1 - c0)
        lo = max(r0, start + 1)
        dt[lo - r0:] = (tv[lo:r1] - tv[lo - 1:r1 - 1]) * 1e-9
        dt[actv[r0:r1] != _ACCEPT] = 0.0
        qv = s._n2 * dt[:, None] * np.ones(3)
        if var_v is not None:
            qv = np.where(known_v[r0:r1, None], var_v[r0:r1] * (dt * dt)[:, None], qv)
        zero_rate = np.zeros(c1 - c0, dtype=bool)
        se = np.zeros((c1 - c0, 3))
        if upd_k is not None and upd_rows.size:
            i0, i1 = np.searchsorted(upd_rows, (c0, c1))
            zero_rate[upd_rows[i0:i1] - c0] = True
            se[upd_rows[i0:i1] - c0] = track.standard_error[upd_k[i0:i1]]
        fr = None
        if first_rest is not None and c0 <= first_rest[0] - start < c1:
            zero_rate[first_rest[0] - start - c0] = False
            fr = (first_rest[0] - start - c0, first_rest[1], first_rest[2])
        tt[c0:c1] = s.covariance.run(dt, qv, actv[r0:r1] == _RESET, zero_rate, se, fr)
    return tt


def count_saturated(wv, st, counts, details) -> None:
    """Array form of ``AttitudeStream._saturation_step`` over the accepted rows (the same
    running maximum and repeats, exactly), leaving the state as it would; chunk by chunk, the
    running maximum and the last row carried (as from one sample to the next)."""
    counts[SATURATED] = 0
    for c0 in range(0, wv.shape[0], COVARIANCE_CHUNK):
        _count_saturated(wv[c0:c0 + COVARIANCE_CHUNK], st, counts, details)


def _count_saturated(wv, st, counts, details) -> None:
    if wv.shape[0] == 0:
        return
    a = np.abs(wv)
    run_max = np.maximum.accumulate(np.vstack([st.sat[None, :3], a]), axis=0)[1:]
    prev = np.vstack([st.sat[None, 3:], wv[:-1]])
    with np.errstate(invalid="ignore"):
        pinned = (a == run_max) & (wv == prev) & (a >= SATURATION_MIN_RAD_S)
    rows_pinned = np.flatnonzero(pinned.any(axis=1))
    counts[SATURATED] += int(rows_pinned.size)
    if rows_pinned.size:
        k = int(rows_pinned[0])
        axis = int(np.flatnonzero(pinned[k])[-1])
        details.setdefault(SATURATED, saturation_note(axis, float(wv[k, axis])))
    st.sat[:3] = run_max[-1]
    st.sat[3:] = wv[-1]


def rest_plan(est, rec: Recording, empty=np.empty):
    """The rows the bias stage's detector takes (:func:`_bias_inputs`) and the rests it finds
    there (:meth:`.gyro_bias.GyroBiasEstimator.rests`, on the rates: found once), or None
    without an ``auto`` bias."""
    fed = _bias_inputs(est, rec.tv, rec.av, rec.a_ok, rec.breaks)
    plan = None
    if est.mode is GyroBiasMode.AUTO and rec.tv.shape[0]:
        idx, cut = fed
        # (views where every accepted row is fed and every accelerometer row usable: no copy
        # of the recording)
        a_fed = None if rec.av is None else (rows(rec.av, idx) if rec.a_ok.all() else
                                             np.where(rec.a_ok[idx, None], rec.av[idx], 0.0))
        plan = est.rests(rows(rec.tv, idx), rows(rec.wv, idx), a_fed, cut, empty)
    return fed, plan


def _bias_inputs(est, tv, av, a_ok, breaks):
    """Which accepted rows the bias stage's detector takes and where its windows break:
    (fed rows (F,), breaks (F,)) — every gap, jump, restart and unusable accelerometer row
    breaks them, and the usable row after an unusable one is refused (the accelerometer
    reappearing mid-window)."""
    m = tv.shape[0]
    fed = np.ones(m, dtype=bool)
    cut = breaks.copy()
    if a_ok is not None and not a_ok.all():
        cut |= ~a_ok
        after = np.zeros(m, dtype=bool)
        after[1:] = ~a_ok[:-1] & a_ok[1:]
        fed &= ~after
        nxt = np.flatnonzero(after) + 1
        cut[nxt[nxt < m]] = True
    idx = np.flatnonzero(fed)
    return idx, cut[idx]


def _bias_track(est, tv, wv, values, fed, earth, plan, empty=np.empty):
    """Step 2 on the accepted rows: (bias (M, 3), the BiasTrack or None, update rows (U,))."""
    m = tv.shape[0]
    if est.mode is not GyroBiasMode.AUTO or m == 0:
        return np.broadcast_to(np.asarray(est.bias, dtype=np.float64), (m, 3)), None, \
            np.zeros(0, np.int64)
    est.reset()
    idx, _ = fed
    earth_fed = rows(earth, idx) if isinstance(earth, np.ndarray) else earth
    track = est.run(rows(tv, idx), rows(wv, idx), earth_removed=earth_fed,
                    values=rows(values, idx), plan=plan, empty=empty)
    if idx.size == m:  # every row fed: the track's bias is the rows' bias
        return track.bias, track, idx[track.updates]
    bias = empty((m, 3), np.float64)
    bias[:] = est.bias
    pos = np.searchsorted(idx, np.arange(m), side="right") - 1
    bias[pos >= 0] = track.bias[pos[pos >= 0]]
    return bias, track, idx[track.updates]


def _integrate(s, n, valid, tv, bias, rate, actv, track, updates, start, q_start, fallbacks,
               empty=np.empty):
    """Step 4: (attitudes of the rows from ``start`` on, the first-rest correction or None),
    or None on a non-finite attitude.  ``fallbacks`` collects (first row of the run, its
    intervals whose rate fit fell back)."""
    st = s.state
    m = tv.shape[0]
    first_rest = None
    if st.first_rest_pending and track is not None and track.updates.size:
        u0 = int(updates[0])
        if int(track.rest_start_ns[0]) - int(tv[0]) <= s.bias_estimator.window_ns and u0 > 0:
            first_rest = (u0, track.standard_error[0],
                          (int(tv[u0 - 1]) - int(tv[0])) * 1e-9, track.previous[0])
    ev = np.flatnonzero(actv[start:] != _ACCEPT) + start
    bounds = sorted({start, *ev.tolist(), *([first_rest[0]] if first_rest else []), m})
    q = empty((m - start, 4), np.float64)
    nav_all = nav_rows(s.nav, valid, n)
    for r0, r1 in zip(bounds[:-1], bounds[1:], strict=True):
        a0 = actv[r0]
        if r0 == start:
            q0 = q_start
        elif first_rest is not None and r0 == first_rest[0]:
            _, _, elapsed, previous = first_rest
            q0 = quat_multiply(q[r0 - 1 - start],
                               quat_from_rotvec(-(bias[r0] - previous) * elapsed))
        elif a0 == _RESTART:
            q0 = q[r0 - 1 - start]
        else:  # a time-jump reset: back to the initial (or levelled) attitude
            q0 = q_start
        if first_rest is not None and r0 == first_rest[0]:
            # the integrator restarted at the previous sample, its rate held back to it
            # (``rate`` is this call's own array: its row r0-1 is set for the run and restored,
            # sparing a copy of the run)
            held = rate[r0 - 1].copy()
            rate[r0 - 1] = rate[r0]
            fb = []
            # written in place from row r0-1 on (that row, the previous run's last attitude,
            # restored after): no run-sized second array
            into = placed = r0 - 1 >= start
            held_q = q[r0 - 1 - start].copy() if into else None
            try:
                q_run = integrate_batch(tv[r0 - 1:r1], rate[r0 - 1:r1], q0=q0,
                                        algorithm=s.algorithm,
                                        nav=None if nav_all is None else nav_rows(
                                            nav_all, np.arange(r0 - 1, r1), m),
                                        fallbacks=fb,
                                        out=q[r0 - 1 - start:r1 - start] if into else None)[1:]
            finally:
                rate[r0 - 1] = held
                if into:
                    q[r0 - 1 - start] = held_q
            fallbacks.extend((r0 - 1, f) for f in fb)
        else:
            sel = slice(r0, r1)
            fb = []
            placed = True
            q_run = integrate_batch(tv[sel], rate[sel], q0=q0, algorithm=s.algorithm,
                                    nav=None if nav_all is None else nav_rows(
                                        nav_all, np.arange(r0, r1), m), fallbacks=fb,
                                    out=q[r0 - start:r1 - start])
            fallbacks.extend((r0, f) for f in fb)
        if not np.isfinite(q_run).all():
            return None
        if not placed:
            q[r0 - start:r1 - start] = q_run
    return q, first_rest

