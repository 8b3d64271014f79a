"""The causal chain's array form works on long recordings in bounded chunks (covariance, rest
statistics, the sums of a rest, saturation counts): any chunk size gives the same numbers bit for
bit, because each chunk carries its state into the next as one sample carries it into the next."""

import numpy as np
import pytest


def _peak(fn):
    import tracemalloc

    tracemalloc.start()
    try:
        got = fn()
        return got, tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


@pytest.mark.parametrize("algorithm", ["magnus6_quintic", "rotvec_cubic", "coning4"])
def test_integration_into_a_given_array_is_the_same_bits_and_allocates_no_second_one(algorithm):
    """integrate_batch(out=) writes the attitudes into the caller's array (the causal array form
    assembles its runs so): the bits of a fresh result, ``out`` itself returned, and for the
    rate algorithms without an (N, 4) array of its own (the peak is N x 32 bytes below the
    fresh result's, or -- the compiled loop, whose fresh peak is its result alone -- below
    one such array)."""
    from gyro_attitude.core.attitude import integrate_batch
    from gyro_attitude.core.attitude.registry import get_algorithm

    n = 20_000
    t = 10**9 + np.arange(n, dtype=np.int64) * 1_000_000
    s = (t - t[0]) * 1e-9
    w = np.stack([0.3 * np.sin(2 * s), 0.2 * np.cos(0.7 * s), 0.1 + 0 * s], axis=1)
    q0 = (0.1, -0.2, 0.3, 0.9)
    fresh, peak_fresh = _peak(lambda: integrate_batch(t, w, q0=q0, algorithm=algorithm))
    out = np.full((n + 2, 4), np.nan)
    got, peak_into = _peak(lambda: integrate_batch(t, w, q0=q0, algorithm=algorithm,
                                                   out=out[1:-1]))
    assert np.shares_memory(got, out)
    assert got.tobytes() == fresh.tobytes()
    assert np.isnan(out[[0, -1]]).all()  # nothing outside the rows given
    if get_algorithm(algorithm).integrates_into:
        assert peak_fresh - peak_into > 0.9 * 32 * n or peak_into < 0.9 * 32 * n, \
            (peak_fresh, peak_into)
    with pytest.raises(ValueError, match="out must be"):
        integrate_batch(t, w, algorithm=algorithm, out=np.empty((n, 3)))


def _untraced_empty(shape, dtype=np.float64):
    """Arrays in an anonymous mapping, which tracemalloc does not see: a stand-in for a
    file-backed allocator (io/spool.py) handed to the core."""
    import math
    import mmap

    shape = (shape,) if isinstance(shape, int) else tuple(shape)
    count = math.prod(shape)
    buf = mmap.mmap(-1, max(count * np.dtype(dtype).itemsize, 1))
    return np.frombuffer(buf, dtype=dtype, count=count).reshape(shape)


def test_the_offline_estimator_keeps_what_grows_with_the_recording_in_the_callers_allocator(
        monkeypatch):
    """estimate_offline(empty=) takes every array of the recording's length from the caller's
    allocator (replay gives it file-backed ones): the same bits as without, and the memory
    it allocates itself grows by no more than a few bytes a sample (the validator's verdict
    codes and the accelerometer flags), where one (N, 4) output of its own would be 32.
    The blocks are taken as long ones (a short block keeps its forward low-pass, up to
    _KEEP_FORWARD samples: bounded, but it would grow between these two lengths)."""
    from gyro_attitude.benchmarks.offline_memory import rest_tumble_rest
    from gyro_attitude.core.attitude import offline
    from gyro_attitude.core.attitude.offline import estimate_offline
    from gyro_attitude.core.attitude.settings import StreamConfig

    monkeypatch.setattr(offline, "_KEEP_FORWARD", 0)
    cfg = StreamConfig(aiding="gravity")
    peaks = {}
    for n in (150_000, 450_000):  # both above every working chunk (65,536 rows)
        t, w, a = rest_tumble_rest(n)
        ref = estimate_offline(t, w, a, config=cfg, chunk_samples=4096)
        got, peaks[n] = _peak(lambda t=t, w=w, a=a: estimate_offline(
            t, w, a, config=cfg, chunk_samples=4096, empty=_untraced_empty))
        assert np.array_equal(ref.q, got.q) and np.array_equal(ref.index, got.index)
        assert np.array_equal(ref.variance, got.variance) and ref.counts == got.counts
    per_sample = (peaks[450_000] - peaks[150_000]) / 300_000
    assert per_sample < 4.0, f"{per_sample:.1f} bytes a sample outside the allocator"


