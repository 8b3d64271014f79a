"""The rate fits in time (core/attitude/interpolation.py) against scipy's barycentric
interpolator, on equally spaced and jittered stamps; the offline chunked composition's worker
threads against its single-thread path."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.interpolate import BarycentricInterpolator

from gyro_attitude.core.attitude import compose, increments_from_rates, integrate_batch
from gyro_attitude.core.attitude.interpolation import (
    GAUSS2,
    causal_fit_points,
    fitted_rates,
    sliding_fit_rates,
)

T0 = 1_700_000_000_000_000_000  # long-recording stamps: relative times must stay exact


def _stamps(n, jitter_ns, seed=0, step_ns=1_000_000):
    rng = np.random.default_rng(seed)
    steps = step_ns + rng.integers(-jitter_ns, jitter_ns + 1, n - 1)
    return T0 + np.concatenate(([0], np.cumsum(steps))).astype(np.int64)


def _oracle(t_ns, omega, k, start, n_nodes, fractions):
    """scipy's barycentric interpolation through samples start..start+n_nodes-1 of each
    interval, at t_{k-1} + f h_k (times in s relative to t_{k-1}, from exact ints)."""
    out = np.empty((len(k), len(fractions), 3))
    for r, (kk, s0) in enumerate(zip(k, start, strict=True)):
        x = (t_ns[s0:s0 + n_nodes] - t_ns[kk - 1]) * 1e-9
        h = (t_ns[kk] - t_ns[kk - 1]) * 1e-9
        out[r] = BarycentricInterpolator(x, omega[s0:s0 + n_nodes])(np.asarray(fractions) * h)
    return out


@pytest.mark.parametrize("jitter", [0, 1, 300_000])
@pytest.mark.parametrize(("offset", "n_nodes", "fractions"),
                         [(3, 4, GAUSS2), (3, 4, (0.5,)), (3, 6, (0.1127, 0.5, 0.8873)),
                          (2, 3, GAUSS2), (1, 2, (0.25,))])
def test_sliding_fit_matches_scipy(jitter, offset, n_nodes, fractions):
    n = 400
    t = _stamps(n, jitter)
    rng = np.random.default_rng(1)
    w = rng.normal(size=(n, 3))
    k0, k1 = offset, n - n_nodes + offset + 1  # every interval whose window is inside
    got = sliding_fit_rates(t, w, k0, k1, offset, n_nodes, fractions)
    k = np.arange(k0, k1)
    want = _oracle(t, w, k, k - offset, n_nodes, fractions)
    assert got.shape == (len(fractions), k.size, 3)
    # Lagrange weights of order 1 on O(1) data: agreement to a few ulps
    np.testing.assert_allclose(got.transpose(1, 0, 2), want, rtol=0, atol=1e-12)


@pytest.mark.parametrize("jitter", [0, 300_000])
@pytest.mark.parametrize(("n_nodes", "k"), [(2, 1), (3, 2), (3, 1), (4, 3)])
def test_plain_float_fit_matches_scipy(jitter, n_nodes, k):
    # the per-sample fit over a history of n_nodes samples (interval k: the newest, or
    # interval 1 redone with the quadratic through 0, 1, 2) against the same oracle, at
    # the Gauss points and beyond the nodes
    t = _stamps(40, jitter)
    w = np.random.default_rng(2).normal(size=(40, 3))
    for s0 in range(0, 40 - n_nodes):
        ts, ws = t[s0:s0 + n_nodes].tolist(), [tuple(r) for r in w[s0:s0 + n_nodes].tolist()]
        for fa, fb in (GAUSS2, (-0.5, 1.7)):
            got = causal_fit_points(ts, ws, k, n_nodes, fa, fb)
            want = _oracle(t, w, [s0 + k], [s0], n_nodes, (fa, fb))[0]
            np.testing.assert_allclose(got[:2], want, rtol=0, atol=1e-11)
            assert got[2] == (ts[k] - ts[k - 1]) * 1e-9


def test_sliding_fit_reproduces_a_cubic_exactly_on_jittered_stamps():
    """A cubic in time is its own causal cubic fit (the order-4 property of rotvec_cubic)."""
    t = _stamps(200, 250_000, seed=3)
    s = (t - t[0]) * 1e-9
    coeffs = np.array([[0.3, -1.0, 2.0], [1.5, 0.2, -0.7], [-2.0, 0.4, 0.9], [0.8, -0.3, 0.1]])
    w = sum(c[None, :] * s[:, None] ** p for p, c in enumerate(coeffs))
    k = np.arange(3, t.size)
    got = sliding_fit_rates(t, w, 3, t.size, 3, 4, GAUSS2)
    for f, frac in enumerate(GAUSS2):
        se = s[k - 1] + frac * (s[k] - s[k - 1])
        want = sum(c[None, :] * se[:, None] ** p for p, c in enumerate(coeffs))
        np.testing.assert_allclose(got[f], want, rtol=0, atol=1e-12)


@pytest.mark.parametrize("jitter", [0, 200_000])
def test_cubic_increments_over_a_record_take_each_intervals_causal_window(jitter):
    """increments_from_rates("cubic"), the compiled loop over the causal fit's step: the Gauss
    integral of scipy's polynomial through samples k-3..k, at the start through 0..2 for
    intervals 1 and 2 (interval 1 as the streams redo it)."""
    n = 300
    t = _stamps(n, jitter, seed=5)
    w = np.random.default_rng(6).normal(size=(n, 3))
    k = np.arange(1, n)
    start = np.maximum(k - 3, 0)
    nodes = np.where(k < 3, 3, 4)
    want = np.concatenate([_oracle(t, w, [kk], [s0], m, GAUSS2)
                           for kk, s0, m in zip(k, start, nodes, strict=True)])
    h = (np.diff(t) * 1e-9)[:, None]
    got = increments_from_rates(t, w, "cubic")
    np.testing.assert_allclose(got, 0.5 * h * (want[:, 0] + want[:, 1]), rtol=0, atol=1e-15)
    two = increments_from_rates(t[:2], w[:2], "cubic")  # two samples: the linear fit
    np.testing.assert_allclose(two[0], 0.5 * h[0] * (w[0] + w[1]), rtol=0, atol=1e-18)


def test_fitted_rates_sends_the_ends_to_the_gathered_fit():
    """Rows whose window leaves the record go to ``gathered``; the others are fitted."""
    n = 20
    t = _stamps(n, 0)
    w = np.random.default_rng(7).normal(size=(n, 3))
    asked = []

    def gathered(kk):
        asked.append(kk.tolist())
        return np.zeros((kk.size, 1, 3))

    out = fitted_rates(t, w, np.arange(1, n), (0.5,), 3, 6, gathered)
    assert asked == [[1, 2], [18, 19]]  # k < 3 and k > n - 3
    np.testing.assert_array_equal(out[[0, 1, 17, 18]], 0.0)
    want = _oracle(t, w, np.arange(3, 18), np.arange(0, 15), 6, (0.5,))
    np.testing.assert_allclose(out[2:17], want, rtol=0, atol=1e-12)
    asked.clear()
    fitted_rates(t, w, np.array([5, 9, 4]), (0.5,), 3, 6, gathered)  # not a run
    assert asked == [[5, 9, 4]]


@pytest.mark.parametrize("algorithm", ["magnus6_quintic"])
def test_threaded_composition_equals_single_thread(monkeypatch, algorithm):
    """Three chunks: worker threads prepare them, the attitude is carried in order; the
    result is the same arithmetic as the single-thread path (bit for bit)."""
    n = 2 * compose.CHUNK + 1000
    t = _stamps(n, 100_000, seed=8)
    w = np.random.default_rng(9).normal(size=(n, 3)) * 2.0
    kw = {}
    monkeypatch.setattr(compose, "_prepare_threads", 2)
    threaded = integrate_batch(t, w, algorithm=algorithm, **kw)
    previous = compose.set_prepare_threads(0)
    assert previous == 2

    def no_threads(*_a, **_k):
        raise AssertionError("a thread pool was started with 0 prepare threads")

    monkeypatch.setattr(compose, "ThreadPoolExecutor", no_threads)
    single = integrate_batch(t, w, algorithm=algorithm, **kw)
    np.testing.assert_array_equal(threaded, single)
    assert np.allclose(np.linalg.norm(threaded, axis=1), 1.0, rtol=0, atol=1e-15)


@pytest.mark.parametrize("bad", [-1, 65, 1.5, True, "2", None])
def test_prepare_threads_rejects_what_is_not_a_thread_count(bad):
    before = compose._prepare_threads
    with pytest.raises(ValueError, match="prepare threads"):
        compose.set_prepare_threads(bad)
    assert compose._prepare_threads == before
