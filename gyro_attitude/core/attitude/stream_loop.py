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
floats in the same operations (tested equal, ≤ 1e-12, in every mode).  When the loop meets an
integrator error (a non-finite attitude, which restarts the validator's time base) it returns
None and :meth:`AttitudeStream.run` pushes every sample instead.
"""

from __future__ import annotations

import math

import numpy as np

from gyro_attitude.core.attitude import validation as v
from gyro_attitude.core.attitude.alignment import level_quaternions
from gyro_attitude.core.attitude.modes import Aiding, GyroBiasMode
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

    # per-row inputs of the loop, as plain Python values (a list index is ~20× cheaper than
    # an array element)
    tl, wl, actl = tv.tolist(), [tuple(x) for x in wv.tolist()], actv.tolist()
    al = [None] * m
    if rec.av is not None:
        ok = rec.a_ok.tolist()
        al = [tuple(x) if ok_k else None for x, ok_k in zip(rec.av.tolist(), ok, strict=True)]
    # rows where push() breaks the windows, which restarts the aiding's time base: a gap, a
    # jump, a restart, an unusable accelerometer sample
    restart = rec.breaks.copy()
    if rec.a_ok is not None:
        restart |= ~rec.a_ok
    restart = restart.tolist()
    var_rows = [None] * m
    known_rows = np.zeros(m, dtype=bool)
    if cov is not None:
        var_v, known_v = covariance_rows(cov, valid, counts, details)
        if v.no_estimate(rows(cov, valid)).any():
            st.details.setdefault(GYRO_NOISE_UNKNOWN, unknown_noise_note(cfg))
        known_rows = np.asarray(known_v, dtype=bool)
        var_rows = [tuple(x) if k else None for x, k in zip(np.asarray(var_v).tolist(),
                                                             known_rows.tolist(), strict=True)]
    # whether anything gives an orientation variance by each row
    variance_known = (np.maximum.accumulate(known_rows) | st.variance_known).tolist() if m \
        else []
    ml = [None] * m
    if cfg.aiding is Aiding.MAGNETOMETER:
        if mag is None:
            missing = np.ones(m, dtype=bool)
        else:
            mv = rows(mag, valid)
            missing = np.isnan(mv).all(axis=1)
            ml = [None if miss else x for x, miss in zip(mv.tolist(), missing.tolist(),
                                                          strict=True)]
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
    need = set(ev_src) if earth else set()
    values: dict[int, tuple] = {}
    n_ev = len(ev_rows)

    align = rec.align
    done = align[0] if align is not None else -1
    first_row = align[1] if align is not None else 0
    if earth and align is not None:
        # while aligning the bias stage takes the Earth rate out at the attitude levelled from
        # each sample's force (data only: the array form of level_quaternion, as run_arrays)
        lv = sorted(k for k in need if k <= done)
        if lv:
            q_lv, usable = level_quaternions(np.where(rec.a_ok[lv, None], rec.av[lv], 0.0),
                                             math.radians(cfg.initial_heading_deg))
            usable &= rec.a_ok[lv]
            for k, qk, ok_k in zip(lv, q_lv.tolist(), usable.tolist(), strict=True):
                values[k] = est.value(wl[k], qk if ok_k else None)
                need.discard(k)
    aid = s.aiding
    integrate = s._integrate
    bias_attitude = s._bias_attitude
    published = s._bias_published
    covariance = s.covariance
    index: list[int] = []
    qs: list[tuple] = []
    var_out: list = []
    p = 0
    next_ev = ev_rows[0] if n_ev else -1
    bias = est.bias_floats
    for r in range(m):
        t_r = tl[r]
        if st.start_t_ns is None:
            st.start_t_ns = t_r
        # 2. rest -> gyro bias: the value this sample gives a rest, then the accumulation the
        # rest plan puts at this row
        if r in need:
            values[r] = est.value(wl[r], bias_attitude(al[r]))
        if r == next_ev:
            if ev_first[p] and est.open_rest_start_ns is not None:
                est.close_rest()  # the previous rest ended (push() closed it when it did)
            j = ev_src[p]
            g_j, earth_j = values.pop(j) if earth else (wl[j], False)
            previous = bias
            est.accumulate(tl[j], g_j, earth_j)
            if est.updated:
                published(previous)
            bias = est.bias_floats
            p += 1
            next_ev = ev_rows[p] if p < n_ev else -1
        # 3. alignment
        if st.phase is not RUNNING:
            if r == done:
                q = s._aligned(align[2], [(tl[k], wl[k], al[k], var_rows[k], ml[k])
                                          for k in range(first_row, done + 1)], bias)
                if q is None or st.phase is not RUNNING:
                    return None
                index.append(r)
                qs.append(q)
                var_out.append(covariance.tt_floats() if variance_known[r] else None)
            continue
        # 4.-6. aiding, integration, covariance
        if restart[r] and aid is not None:
            aid.last_t_ns = None
        code = actl[r]
        verdict = _ACCEPTED if code == _ACCEPT else (
            _STARTED if code == _START else v.Verdict(_VERDICT_OF_CODE[code], None, ""))
        x = wl[r]
        _, q = integrate(verdict, t_r, (x[0] - bias[0], x[1] - bias[1], x[2] - bias[2]), al[r],
                         var_rows[r], ml[r])
        if q is None:
            return None  # an integrator error: the per-sample form handles what follows
        index.append(r)
        qs.append(q)
        var_out.append(covariance.tt_floats() if variance_known[r] else None)

    # the state after the last row, as push() would leave it (the rest windows start again)
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
    q_arr = np.array(qs, dtype=np.float64).reshape(-1, 4)
    variance = known = None
    if any(x is not None for x in var_out):
        known = np.array([x is not None for x in var_out])
        variance = np.array([x if x is not None else (0.0, 0.0, 0.0) for x in var_out])
    return StreamResult(valid[np.array(index, dtype=np.int64)], q_arr, variance, known,
                        rec.cls.action, s.counts, rec.cls.time_jump_resets, dict(st.details),
                        s.bias_report, s.alignment, RunForm.LOOP)
