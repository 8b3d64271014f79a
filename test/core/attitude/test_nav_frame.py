"""Navigation-frame (q_nb) integration against closed forms, with ω_ie + ω_en written out
from docs/equations.md (not taken from earth.nav_rate_enu)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from attitude_truth import (
    NAV_H,
    NAV_LAT,
    NAV_VELS,
    Q0,
    angle_between,
    nav_rate_written_out,
)
from scipy.spatial.transform import Rotation

from gyro_attitude.core.attitude import (
    DEFAULT_ALGORITHM,
    NavFrame,
    StreamingIntegrator,
    integrate_batch,
)

_LAT, _H, _VELS = NAV_LAT, NAV_H, NAV_VELS


def test_earth_rate_only_one_hour_at_rest():
    lat = math.radians(47.0)
    q_nb = Rotation.from_euler("ZYX", [0.8, 0.1, -0.05]).as_quat()
    n = 360_000  # 1 h at 100 Hz
    t_ns = np.arange(n + 1, dtype=np.int64) * 10_000_000
    w_ib_b = Rotation.from_quat(q_nb).inv().apply(nav_rate_written_out(lat, 0.0, (0.0, 0.0, 0.0)))
    q = integrate_batch(t_ns, np.broadcast_to(w_ib_b, (n + 1, 3)), q_nb,
                        nav=NavFrame(lat))
    assert angle_between(q, q_nb).max() < 1e-10
    assert np.abs(np.linalg.norm(q, axis=1) - 1).max() < 1e-12
    # Without the nav frame the same samples show the Earth turning (sanity of the case).
    q_i = integrate_batch(t_ns, np.broadcast_to(w_ib_b, (n + 1, 3)), q_nb)
    assert angle_between(q_i[-1], q_nb)[0] == pytest.approx(7.292115e-5 * 3600, rel=1e-6)


def test_moving_base_and_turning_body_time_series():
    """Vehicle flying north-east (latitude series) while the body yaws at constant rate."""
    n, h = 20_000, 0.01
    t_ns = np.arange(n + 1, dtype=np.int64) * 10_000_000
    t = t_ns * 1e-9
    v = np.array([200.0, 150.0, 0.0])
    lat = 0.6 + 150.0 * t / 6.37e6
    rate_n = nav_rate_written_out(lat, 0.0, np.broadcast_to(v, (n + 1, 3)))
    w_nb_b = np.array([0.0, 0.0, 0.2])
    q_true = (Rotation.from_quat(Q0) * Rotation.from_rotvec(np.outer(t, w_nb_b)))
    w_ib_b = q_true.inv().apply(rate_n) + w_nb_b
    nav = NavFrame(lat, height_m=0.0, velocity_enu=np.broadcast_to(v, (n + 1, 3)))
    q = integrate_batch(t_ns, w_ib_b, Q0, DEFAULT_ALGORITHM, nav=nav)
    assert angle_between(q, q_true.as_quat()).max() < 1e-9
    assert h > 0


def _piecewise_velocity(n, switches):
    """(n, 3) ENU velocity: _VELS[j] from sample switches[j-1] on (switches ascending)."""
    vel = np.empty((n, 3))
    edges = [0, *switches, n]
    for j in range(len(edges) - 1):
        vel[edges[j]:edges[j + 1]] = _VELS[j]
    return vel


@pytest.mark.parametrize("algorithm", ["exp_map", "coning1"])
def test_update_nav_body_at_rest_in_n_stays_put(algorithm):
    """Closed form: a body at rest in a nav frame whose velocity steps measures
    ω_ib^b = C_bn ω_in^n(t); with the rate switched at the same samples the exponential map
    of the trapezoid increment cancels ζ exactly, so q_nb stays q0.  A stale velocity drifts
    by |Δω_en|·T."""
    n, switches = 400, [150, 290]
    t_ns = np.arange(n, dtype=np.int64) * 5_000_000  # 200 Hz, 2 s
    vel = _piecewise_velocity(n, switches)
    rate_n = nav_rate_written_out(np.full(n, _LAT), np.full(n, _H), vel)
    w = Rotation.from_quat(Q0).inv().apply(rate_n)  # C_bn ω_in^n
    q = _stream_switching(algorithm, t_ns, w, switches)
    assert angle_between(q, np.broadcast_to(Q0, q.shape)).max() < 1e-13
    s = StreamingIntegrator(algorithm, Q0, nav=NavFrame(_LAT, height_m=_H,
                                                        velocity_enu=_VELS[0]))
    q_stale = [s.update(int(t), x) for t, x in zip(t_ns, w, strict=True)][-1]
    # trapezoid of the rate error over the two later segments (closed form)
    err = rate_n - rate_n[0]
    dt = 5e-3
    expected = np.linalg.norm(0.5 * (err[1:] + err[:-1]).sum(axis=0) * dt)
    assert angle_between(q_stale, Q0)[0] == pytest.approx(expected, rel=1e-6)
    assert expected > 5e-6


def _stream_switching(algorithm, t_ns, w, switches):
    s = StreamingIntegrator(algorithm, Q0, nav=NavFrame(_LAT, height_m=_H,
                                                        velocity_enu=_VELS[0]))
    out = []
    for k, (t, x) in enumerate(zip(t_ns, w, strict=True)):
        if k in switches:
            s.update_nav(NavFrame(_LAT, height_m=_H, velocity_enu=_VELS[switches.index(k) + 1]))
        out.append(s.update(int(t), x))
    return np.array(out)
