"""Free gyro: g-sensitive drift of a mass unbalance (§5-3) against m·l·f/H and the phase-1
drift-rate vector; gimbal stops as impacts with a coefficient of restitution (energy and
momentum bookkeeping written out here)."""

import math

import numpy as np
import pytest

from gyro_attitude.core.gyro.free_gyro import (
    FreeGyroParams,
    FreeGyroSimulator,
    spin_axis_from_free_gyro_angles,
)
from gyro_attitude.core.instruments.mass_unbalance import g_sensitive_drift_rate

G = 9.80665


def _still(t):
    return np.zeros((np.atleast_1d(t).shape[0], 3))


def _force(f):
    return lambda t: np.tile(np.asarray(f, dtype=float), (np.atleast_1d(t).shape[0], 1))


@pytest.mark.parametrize("model", ["precession", "full"])
def test_level_rotor_drifts_about_the_vertical_at_ml_g_over_h(model):
    """Base at rest in inertial space, f = g up (case z): the outer gimbal turns at m l g / H
    (closed form).  Full model: plus a nutation of amplitude ~ (m l g/H)/ω_nut (1e-7 rad)."""
    ml = 2e-5
    p = FreeGyroParams(1e-4, 6e-5, 2500.0, model=model, mass_unbalance=ml,
                       inner_gimbal_inertia=(2e-5,) * 3, outer_gimbal_inertia=(3e-5,) * 3,
                       max_step=2e-3)
    sim = FreeGyroSimulator(p, _still, specific_force_fn=_force((0.0, 0.0, G)))
    t = np.linspace(0.0, 2.0, 41)
    ang, _ = sim.run_until(t)
    rate = ml * G / p.spin_momentum
    np.testing.assert_allclose(ang[:, 0], rate * t, rtol=0, atol=1e-6 * rate * 2 + 2e-7)
    np.testing.assert_allclose(ang[:, 1], 0.0, rtol=0, atol=2e-7)


def test_tilted_rotor_follows_the_drift_rate_vector():
    """Any tilt and force direction: ṡ = ω_d × s with ω_d = (m l/H)(f − (f·s)s) of the phase-1
    function (precession model; central difference of the simulated axis, O(h²) ~ 1e-9)."""
    ml, f = 3e-5, np.array([2.0, -1.0, 9.5])
    p = FreeGyroParams(1e-4, 6e-5, 2500.0, mass_unbalance=ml, initial_angles=(0.4, -0.6),
                       max_step=1e-3)
    sim = FreeGyroSimulator(p, _still, specific_force_fn=_force(f))
    h = 1e-3
    ang, _ = sim.run_until([1.0 - h, 1.0, 1.0 + h])
    s = spin_axis_from_free_gyro_angles(ang)
    sdot = (s[2] - s[0]) / (2 * h)
    want = np.cross(g_sensitive_drift_rate(ml, p.spin_momentum, f, s[1]), s[1])
    np.testing.assert_allclose(sdot, want, rtol=1e-6, atol=0)
    with pytest.raises(ValueError, match="specific_force_fn"):
        FreeGyroSimulator(p, _still)


def _bounce_params(e, **kw):
    """Slow rotor (H = 5e-3 N·m·s) with the inner gimbal pushed at 4 rad/s between stops at
    0.45 and 0.55 rad (free, it would nutate between 0.42 and 0.58 rad)."""
    return FreeGyroParams(1e-4, 6e-5, 50.0, model="full", inner_gimbal_inertia=(2e-5,) * 3,
                          outer_gimbal_inertia=(3e-5,) * 3, initial_angles=(0.0, 0.5),
                          initial_rates=kw.pop("initial_rates", (0.0, 4.0)), max_step=2e-4,
                          inner_gimbal_stops=(0.45, 0.55), stop_restitution=e, **kw)


@pytest.mark.parametrize("e", [1.0, 0.6, 0.0])
def test_inner_gimbal_bounces_off_its_stops_with_the_restitution(e):
    """Base at rest: KE = ½ M_11 α̇² + ½ A_y β̇² + H²/(2J_s) (written out here).  Each impact
    reverses the rate times e, drops KE by ½ A_y (β̇⁻² − β̇⁺²) and keeps the angular momentum
    about the outer axis (the stop impulse is internal to the outer gimbal)."""
    p = _bounce_params(e)
    sim = FreeGyroSimulator(p, _still)
    jt, (igx, igy, igz), ioz = 6e-5, p.inner_gimbal_inertia, p.outer_gimbal_inertia[2]
    ay = jt + igy

    def ke(ang, rate):
        m11 = ioz + igx * math.sin(ang[1]) ** 2 + (jt + igz) * math.cos(ang[1]) ** 2
        return 0.5 * m11 * rate[0] ** 2 + 0.5 * ay * rate[1] ** 2

    e0 = ke(*sim.state())
    l0 = sim.angular_momentum()[2]
    ang, rate = sim.run_until(np.linspace(0.0, 1.0, 201))
    assert len(sim.stop_impacts) >= 1
    assert np.all(ang[:, 1] <= 0.55 + 1e-12) and np.all(ang[:, 1] >= 0.45 - 1e-12)
    lost = 0.0
    for _, axis, before, after in sim.stop_impacts:
        assert axis == 1 and before != 0.0
        assert after == pytest.approx(-e * before, rel=1e-14, abs=0)
        lost += 0.5 * ay * (before**2 - after**2)
    # the midpoint rule keeps this KE (not quadratic in the state: M_11 depends on β) to an
    # O(h²) oscillation, 6e-7 of e0 at h = 2e-4 s with or without stops (measured); impact
    # times are located to 1e-12 s
    assert ke(*sim.state()) == pytest.approx(e0 - lost, rel=0, abs=2e-6 * e0)
    # L_z is not a quadratic invariant either: same O(h²) error, measured ≤ 2e-9 relative
    assert sim.angular_momentum()[2] == pytest.approx(l0, rel=1e-8, abs=1e-12)
    if e < 1:
        assert lost > 0.3 * e0


def test_gimbal_resting_on_its_stop_loses_gyroscopic_rigidity():
    """A constant outer-axis torque M precesses the inner gimbal onto its stop (e = 0); held
    there (β̇ = 0), the outer axis feels M alone: α̈ = M / M_11(β_stop) (closed form, base at
    rest) — the gyro topples instead of precessing."""
    m = 1e-3
    p = _bounce_params(0.0, initial_rates=(0.0, 0.0), constant_torque=(m, 0.0))
    sim = FreeGyroSimulator(p, _still)
    t = np.linspace(0.0, 1.0, 201)
    ang, rate = sim.run_until(t)
    t_last = sim.stop_impacts[-1][0]
    assert all(after == 0.0 for *_, after in sim.stop_impacts)
    held = t > t_last + 1e-3
    assert held.sum() > 100
    np.testing.assert_allclose(ang[held, 1], 0.45, rtol=0, atol=1e-12)
    assert np.all(rate[held, 1] == 0.0)
    m11 = 3e-5 + 2e-5 * math.sin(0.45) ** 2 + (6e-5 + 2e-5) * math.cos(0.45) ** 2
    slope = np.polyfit(t[held], rate[held, 0], 1)[0]
    assert slope == pytest.approx(m / m11, rel=1e-9)


def test_bad_stops_raise():
    for kw, word in ((dict(inner_gimbal_stops=(1.0, -1.0)), "low < high"),
                     (dict(inner_gimbal_stops=(-1.0, 1.0)), "strictly between"),
                     (dict(stop_restitution=1.5), "stop_restitution")):
        with pytest.raises(ValueError, match=word):
            FreeGyroParams(1e-4, 6e-5, 50.0, model="full", initial_angles=(0.0, 1.2),
                           initial_rates=(0.0, 0.0), **{"inner_gimbal_stops": (-1.4, 1.4), **kw})
    with pytest.raises(ValueError, match="model='full'"):
        FreeGyroParams(1e-4, 6e-5, 50.0, inner_gimbal_stops=(-1.4, 1.4))
