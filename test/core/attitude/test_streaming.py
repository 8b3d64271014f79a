"""StreamingIntegrator against the batch interface (one step, stepped per call or in the
batch's loop: the same bits), resets, start times, bad input, update_nav."""

from __future__ import annotations

import numpy as np
import pytest
from attitude_truth import (
    CAUSAL_QUAT_RATE_ALGS,
    INCR_ALGS,
    NAV_H,
    NAV_LAT,
    NAV_VELS,
    Q0,
    angle_between,
    smooth_increments,
    smooth_rate,
)
from scipy.spatial.transform import Rotation

from gyro_attitude.core.attitude import (
    ALGORITHMS,
    DEFAULT_ALGORITHM,
    NavFrame,
    StreamingIntegrator,
    causal_algorithms,
    increments_from_rates,
    integrate_batch,
    integrate_increments_batch,
)

_LAT, _H, _VELS = NAV_LAT, NAV_H, NAV_VELS


def _stream(algorithm, t_ns, w, q0, nav=None, quadrature="trapezoid"):
    s = StreamingIntegrator(algorithm, q0, nav=nav, quadrature=quadrature)
    return np.array([s.update(int(t), x) for t, x in zip(t_ns, w, strict=True)])


@pytest.mark.parametrize("algorithm", list(causal_algorithms()))
def test_batch_equals_streaming(algorithm):
    """Every causal algorithm: the stream's attitudes are the batch's, bit for bit (one step)."""
    rng = np.random.default_rng(3)
    n = 400
    t_ns = np.cumsum(rng.integers(800_000, 1_200_000, n)).astype(np.int64)
    w = smooth_rate(t_ns * 1e-9, scale=2.0)
    q0 = Q0 if algorithm != "euler_zxz_rk4" else Rotation.from_euler("ZXZ", [0.3, 1.2, -0.4]
                                                                     ).as_quat()
    q_batch = integrate_batch(t_ns, w, q0, algorithm)
    assert np.array_equal(q_batch, _stream(algorithm, t_ns, w, q0))
    if not ALGORITHMS[algorithm].sequential:
        lat = np.linspace(0.5, 0.52, n)
        vel = np.column_stack((np.linspace(0, 250, n), np.full(n, 30.0), np.zeros(n)))
        nav = NavFrame(lat, height_m=np.linspace(0, 1000, n), velocity_enu=vel)
        q_batch = integrate_batch(t_ns, w, q0, algorithm, nav=nav)
        assert np.array_equal(q_batch, _stream(algorithm, t_ns, w, q0, nav))
    if ALGORITHMS[algorithm].consumes == "increment":
        q_batch = integrate_batch(t_ns, w, q0, algorithm, quadrature="cubic")
        q_stream = _stream(algorithm, t_ns, w, q0, quadrature="cubic")
        assert np.array_equal(q_batch, q_stream)
        d = increments_from_rates(t_ns, w)
        s = StreamingIntegrator(algorithm, q0, t0_ns=int(t_ns[0]))
        q_stream = np.array([q0] + [s.update_increment(int(t), x) for t, x in zip(t_ns[1:], d,
                                                                                   strict=True)])
        q_batch = integrate_increments_batch(t_ns, d, q0, algorithm)
        assert np.array_equal(q_batch, q_stream)


def test_streaming_reset_and_state():
    s = StreamingIntegrator(DEFAULT_ALGORITHM, t0_ns=None)
    assert s.last_t_ns is None and s.samples == 0
    s.update(0, (0.0, 0.0, 1.0))
    q = s.update(1_000_000_000, (0.0, 0.0, 1.0))
    assert angle_between(q, Rotation.from_rotvec([0, 0, 1.0]).as_quat())[0] < 1e-14
    s.reset(Q0, t_ns=5)
    assert s.samples == 1 and s.last_t_ns == 5
    np.testing.assert_array_equal(s.quaternion, Q0)
    q = s.update(5 + 500_000_000, (2.0, 0.0, 0.0))
    truth = (Rotation.from_quat(Q0) * Rotation.from_rotvec([1.0, 0, 0])).as_quat()
    assert angle_between(q, truth)[0] < 1e-14


@pytest.mark.parametrize("algorithm", CAUSAL_QUAT_RATE_ALGS + ["coning2"])
def test_streaming_with_start_time_holds_first_rate_back(algorithm):
    """t0_ns without a rate: the first rate is held back to t0 (as the node starts)."""
    t_ns = np.array([0, 4_000_000, 9_000_000, 15_000_000, 20_000_000], dtype=np.int64)
    w = smooth_rate(t_ns * 1e-9, scale=2.0)
    s = StreamingIntegrator(algorithm, Q0, t0_ns=0)
    q_stream = np.array([Q0] + [s.update(int(t), x) for t, x in zip(t_ns[1:], w[1:],
                                                                      strict=True)])
    w_held = w.copy()
    w_held[0] = w[1]
    q_batch = integrate_batch(t_ns, w_held, Q0, algorithm)
    assert angle_between(q_batch, q_stream).max() < 1e-14


def _random_steps(n, seed=11):
    rng = np.random.default_rng(seed)
    return np.cumsum(rng.integers(700_000, 1_300_000, n)).astype(np.int64)


def _nav_cases(n):
    lat = np.linspace(0.5, 0.52, n)
    vel = np.column_stack((np.linspace(0, 250, n), np.full(n, 30.0), np.zeros(n)))
    return [None, NavFrame(0.7, velocity_enu=(40.0, -10.0, 0.0)),
            NavFrame(lat, height_m=np.linspace(0, 1000, n), velocity_enu=vel)]


@pytest.mark.parametrize("algorithm", INCR_ALGS)
@pytest.mark.parametrize("n", [1, 2, 3, 4, 5, 6, 9, 23])
def test_coning_streaming_first_samples_and_partial_blocks_equal_batch(algorithm, n):
    """Short runs end inside an N-block (and before/at the first-interval redo)."""
    t_ns = _random_steps(n)
    w = smooth_rate(t_ns * 1e-9, scale=3.0)
    for quadrature in ("trapezoid", "cubic"):
        for nav in _nav_cases(n):
            q_batch = integrate_batch(t_ns, w, Q0, algorithm, nav=nav, quadrature=quadrature)
            q_stream = _stream(algorithm, t_ns, w, Q0, nav, quadrature)
            assert np.array_equal(q_batch, q_stream), (quadrature, nav)
    if n > 1:
        d = smooth_increments(t_ns[:-1] * 1e-9, t_ns[1:] * 1e-9, scale=3.0)
        for nav in _nav_cases(n):
            s = StreamingIntegrator(algorithm, Q0, nav=nav, t0_ns=int(t_ns[0]))
            q_stream = np.array([Q0] + [s.update_increment(int(t), x)
                                        for t, x in zip(t_ns[1:], d, strict=True)])
            q_batch = integrate_increments_batch(t_ns, d, Q0, algorithm, nav=nav)
            assert np.array_equal(q_batch, q_stream), nav


def test_every_causal_algorithm_streams_and_offline_ones_are_refused():
    """Every causal algorithm has a streaming step (the batch == streaming tests then cover
    it); an offline algorithm needs future samples: one clear ValueError, no stream."""
    for name, alg in ALGORITHMS.items():
        if alg.causal:
            s = StreamingIntegrator(name, Q0)
            s.update(0, (0.1, 0.2, 0.3))
            assert np.all(np.isfinite(s.update(1_000_000, (0.1, 0.2, 0.3))))
        else:
            with pytest.raises(ValueError, match=f"{name} is an offline algorithm"):
                StreamingIntegrator(name, Q0)


@pytest.mark.parametrize("algorithm", INCR_ALGS)
def test_coning_streaming_reset_mid_block(algorithm):
    """reset() inside an open N-block drops the block: the stream restarts like a batch."""
    t_ns = _random_steps(40, seed=2)
    w = smooth_rate(t_ns * 1e-9, scale=2.0)
    for quadrature in ("trapezoid", "cubic"):
        s = StreamingIntegrator(algorithm, Q0, quadrature=quadrature)
        for t, x in zip(t_ns[:7], w[:7], strict=True):
            s.update(int(t), x)
        # reset without a time: the next sample is the new origin
        s.reset(Q0)
        q_stream = np.array([s.update(int(t), x) for t, x in zip(t_ns[7:], w[7:], strict=True)])
        q_batch = integrate_batch(t_ns[7:], w[7:], Q0, algorithm, quadrature=quadrature)
        assert angle_between(q_batch, q_stream).max() < 1e-13
        # reset with a time: the first rate is held back to it (as for t0_ns)
        s.reset(Q0, t_ns=int(t_ns[-1]) + 1_000_000)
        t2 = int(t_ns[-1]) + 1_000_000 + np.cumsum(np.full(9, 900_000))
        w2 = smooth_rate(t2 * 1e-9, scale=2.0)
        q_stream = np.array([s.update(int(t), x) for t, x in zip(t2, w2, strict=True)])
        t_all = np.concatenate(([int(t_ns[-1]) + 1_000_000], t2))
        q_batch = integrate_batch(t_all, np.vstack((w2[:1], w2)), Q0, algorithm,
                                  quadrature=quadrature)
        assert angle_between(q_batch[1:], q_stream).max() < 1e-13


def test_update_increment_bad_input():
    s = StreamingIntegrator("coning2")
    with pytest.raises(ValueError, match="start time"):
        s.update_increment(10, (0.0, 0.0, 0.0))
    s.reset(Q0, t_ns=0)
    with pytest.raises(ValueError, match="non-finite"):
        s.update_increment(10, (0.0, np.nan, 0.0))
    with pytest.raises(ValueError, match="shape"):
        s.update_increment(10, (0.0, 0.0))
    with pytest.raises(ValueError, match="not positive"):
        s.update_increment(0, (0.0, 0.0, 0.0))
    assert s.samples == 1 and s.last_t_ns == 0
    with pytest.raises(ValueError, match="consumes rate samples"):
        StreamingIntegrator("rotvec_cubic", t0_ns=0).update_increment(10, (0.0, 0.0, 0.0))


def test_streaming_nav_series_checked_and_bounded():
    nav = NavFrame(np.array([0.5, 0.51, 0.52]))
    s = StreamingIntegrator("coning2", nav=nav)
    for k in range(3):
        s.update(k * 1_000_000, (0.1, 0.0, 0.0))
    with pytest.raises(ValueError, match="sample 3 is beyond"):
        s.update(3_000_000, (0.1, 0.0, 0.0))
    with pytest.raises(ValueError, match="latitude"):
        StreamingIntegrator("coning2", nav=NavFrame(np.array([0.5, 2.0])))


def _piecewise_velocity(n, switches):
    """(n, 3) ENU velocity: _VELS[j] from sample switches[j-1] on (switches ascending)."""
    vel = np.empty((n, 3))
    edges = [0, *switches, n]
    for j in range(len(edges) - 1):
        vel[edges[j]:edges[j + 1]] = _VELS[j]
    return vel


def _stream_switching(algorithm, t_ns, w, switches):
    s = StreamingIntegrator(algorithm, Q0, nav=NavFrame(_LAT, height_m=_H,
                                                        velocity_enu=_VELS[0]))
    out = []
    for k, (t, x) in enumerate(zip(t_ns, w, strict=True)):
        if k in switches:
            s.update_nav(NavFrame(_LAT, height_m=_H, velocity_enu=_VELS[switches.index(k) + 1]))
        out.append(s.update(int(t), x))
    return np.array(out)


@pytest.mark.parametrize("algorithm", [DEFAULT_ALGORITHM, "exp_map", "quat_rk4", "coning1_prev",
                                       "coning2", "coning3"])
def test_update_nav_mid_stream_equals_batch_with_piecewise_constant_series(algorithm):
    """update_nav before sample s == a NavFrame series holding the new values from s on."""
    n, switches = 300, [101, 218]
    t_ns = _random_steps(n, seed=5)
    w = smooth_rate(t_ns * 1e-9, scale=2.0)
    nav = NavFrame(_LAT, height_m=_H, velocity_enu=_piecewise_velocity(n, switches))
    q_batch = integrate_batch(t_ns, w, Q0, algorithm, nav=nav)
    q_stream = _stream_switching(algorithm, t_ns, w, switches)
    assert angle_between(q_batch, q_stream).max() < 1e-12
    # and the switch matters: the stale velocity differs by ~5e-6 rad at the end
    q_stale = integrate_batch(t_ns, w, Q0, algorithm,
                              nav=NavFrame(_LAT, height_m=_H, velocity_enu=_VELS[0]))
    assert angle_between(q_stale[-1], q_stream[-1])[0] > 1e-6


def test_update_nav_refuses_bad_values_and_keeps_its_frame():
    nav0 = NavFrame(_LAT, height_m=_H, velocity_enu=_VELS[0])
    s = StreamingIntegrator(DEFAULT_ALGORITHM, Q0, nav=nav0)
    for bad in (NavFrame(2.0), NavFrame(_LAT, velocity_enu=(np.nan, 0.0, 0.0)),
                NavFrame(np.array([0.5, 0.6])), (0.5, 0.0, 0.0)):
        with pytest.raises(ValueError):
            s.update_nav(bad)
        assert s.nav is nav0
    np.testing.assert_array_equal(s._nav_rates, nav0.rate_enu())
    with pytest.raises(ValueError, match="NavFrame"):
        StreamingIntegrator(DEFAULT_ALGORITHM, Q0).update_nav(nav0)
