"""The causal estimator's stage kernels driven sample by sample, as the chain's step drives them
(from the state their ``*_start`` makes, a full ring grown and the sample stepped again): the
streaming side of the stream == batch tests and of the closed forms that need an input the
stream does not give a stage (an attitude of the test's choosing)."""

from __future__ import annotations

import numpy as np

from gyro_attitude.core.attitude import chain
from gyro_attitude.core.attitude.alignment import (
    ALIGN_RING_DTYPE,
    aligner_result,
    aligner_start,
    aligner_update,
    alignment_result,
    failure_words,
)
from gyro_attitude.core.attitude.gyro_bias import B_BIAS, bias_report, bias_start, bias_step
from gyro_attitude.core.attitude.modes import GyroBiasMode
from gyro_attitude.core.attitude.rest import (
    F_ACCEL_STD,
    F_GYRO_STD,
    R_AT_REST,
    R_OLDEST,
    RING_FULL,
    grown_ring,
    rest_start,
    rest_update,
)
from gyro_attitude.core.attitude.settings import StreamConfig
from gyro_attitude.core.earth import earth_rate_enu
from gyro_attitude.core.jit import compiled


def _rows(a, n):
    return [(False, 0.0, 0.0, 0.0)] * n if a is None else [(True, *r) for r in a.tolist()]


def rest_rows(t, g, a=None):
    """Per sample (at rest, the window's oldest index, gyro std, accel std) of
    :func:`rest_update`, and the ring sizes it went through."""
    rf, ri = rest_start(StreamConfig())
    ring = np.zeros(64, chain.BIAS_RING_DTYPE).view(np.recarray)
    step, out, sizes = compiled(rest_update), [], set()
    for tk, gk, ak in zip(np.asarray(t).tolist(), np.asarray(g).tolist(), _rows(a, len(t)),
                          strict=True):
        while (code := step(rf, ri, ring.t, ring.x, ring.c, tk, *gk, *ak)) == RING_FULL:
            ring = grown_ring(ring, ri)
        assert code >= 0, code
        sizes.add(ring.shape[0])
        out.append((bool(ri[R_AT_REST]), int(ri[R_OLDEST]), rf[F_GYRO_STD], rf[F_ACCEL_STD]))
    return out, sizes


def bias_rows(t, g, a=None, q=None, config=None, latitude_rad=None):
    """The bias (N, 3) :func:`bias_step` gives each sample (mode auto unless ``config`` says
    otherwise) and the final report; ``q`` (N, 4) the attitude at which, with
    ``latitude_rad``, the Earth rate is taken out."""
    cfg = config or StreamConfig()
    rf, ri, bf, bi = bias_start(cfg)
    earth_n = np.zeros(3) if latitude_rad is None else np.asarray(earth_rate_enu(latitude_rad))
    min_rest_ns = int(round(cfg.min_rest_s * 1e9))
    ring = np.zeros(64, chain.BIAS_RING_DTYPE).view(np.recarray)
    step, out = compiled(bias_step), np.empty((len(t), 3))
    qs = [(latitude_rad is not None and q is not None, *qk) for qk in (
        np.asarray(q).tolist() if q is not None else [(0.0, 0.0, 0.0, 1.0)] * len(t))]
    for k, (tk, gk, ak) in enumerate(zip(np.asarray(t).tolist(), np.asarray(g).tolist(),
                                         _rows(a, len(t)), strict=True)):
        while cfg.gyro_bias is GyroBiasMode.AUTO and step(
                bf, bi, min_rest_ns, rf, ri, ring.t, ring.x, ring.c, ring.pv, ring.pe, earth_n,
                tk, *gk, *ak, *qs[k]) == RING_FULL:
            ring = grown_ring(ring, ri)
        out[k] = bf[B_BIAS:B_BIAS + 3]
    return out, bias_report(cfg.gyro_bias, bf, bi, min_rest_ns)


def aligned(t, g, a, config=None, latitude_rad=None):
    """The alignment :func:`aligner_update` and :func:`aligner_result` give over the first
    qualifying rest (one that lasts to the end of the data counts too); ValueError with the
    stream's words when it fails."""
    cfg = config or StreamConfig(initial_attitude_source="level")
    al = aligner_start(cfg, latitude_rad)[0]
    ring = np.zeros(64, ALIGN_RING_DTYPE).view(np.recarray)
    step = compiled(aligner_update)
    for tk, gk, ak in zip(np.asarray(t).tolist(), np.asarray(g).tolist(),
                          np.asarray(a).tolist(), strict=True):
        while (code := step(al, ring, tk, *gk, *ak, False, 0.0, 0.0, 0.0))[0] == RING_FULL:
            ring = grown_ring(ring, al.rest_i)
        if code[1]:
            break
    if not al.has_seg or al.t1 - al.t0 < al.min_rest_ns:
        raise ValueError("no rest long enough")
    failed = aligner_result(al)
    if failed:
        raise ValueError(failure_words(al, failed))
    return alignment_result(al)
