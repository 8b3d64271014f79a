"""Gimbal lock: the full free-gyro model goes through β = ±90° with its energy and angular
momentum conserved (about the outer axis); the precession model refuses there, saying why;
the gimbal_lock_flip scene."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gyro_attitude.core.gyro.free_gyro import (
    FreeGyroParams,
    FreeGyroSimulator,
    spin_axis_from_free_gyro_angles,
)
from gyro_attitude.core.scene import SceneSimulator, SceneSpec
from gyro_attitude.io.scene_file import load_scene

SLOW = dict(spin_inertia=1e-4, transverse_inertia=6e-5, spin_rate=50.0, model="full",
            inner_gimbal_inertia=(2e-5, 2.5e-5, 1.5e-5), outer_gimbal_inertia=(3e-5, 3.5e-5, 4e-5),
            initial_angles=(0.0, math.radians(80.0)), initial_rates=(0.0, 2.0), max_step=1e-3)


def _at_rest(t):
    return np.zeros((np.shape(t)[0], 3))


def test_full_model_flips_through_the_lock_conserving_energy_and_momentum():
    """Base at rest, no torque: T and the angular momentum about the outer axis L_z (the case's
    bearings only take torques about x_c, y_c) are constants of the motion.  The inner gimbal
    passes 90° (goes over the top) and back; the spin axis crosses the outer axis, its azimuth
    turning by 180°.  Implicit midpoint at h = 1 ms: measured drift 7e-10 in T; bounds 1e-7
    relative."""
    sim = FreeGyroSimulator(FreeGyroParams(**SLOW), _at_rest)
    e0, l0 = sim.kinetic_energy(), sim.angular_momentum()
    t = np.linspace(0.0, 2.0, 401)
    energies, momenta, angles = [], [], []
    for k in range(1, t.size):
        a, _ = sim.run_until(t[k:k + 1])
        angles.append(a[0])
        energies.append(sim.kinetic_energy())
        momenta.append(sim.angular_momentum())
    beta = np.array(angles)[:, 1]
    assert np.max(beta) > math.radians(100.0)  # over the top ...
    assert np.min(beta[beta.argmax():]) < math.radians(90.0)  # ... and back: through twice
    s = spin_axis_from_free_gyro_angles(np.array(angles))
    az = np.arctan2(s[:, 1], s[:, 0])
    assert np.ptp(np.abs(az)) > math.radians(170.0)  # the spin axis's azimuth flips by ~180°
    np.testing.assert_allclose(energies, e0, rtol=1e-7, atol=0)
    np.testing.assert_allclose(np.array(momenta)[:, 2], l0[2], rtol=0,
                               atol=1e-7 * np.linalg.norm(l0))


def test_angular_momentum_changes_under_a_torque_by_its_impulse():
    """dL/dt = M: a constant outer-axis torque M_α on a base at rest raises L_z by M_α t
    (the outer axis is the case z axis).  Bound: the midpoint rule's O(h²) over 0.5 s
    (measured 1.6e-6 relative)."""
    m_a = 1e-4
    sim = FreeGyroSimulator(FreeGyroParams(**{**SLOW, "constant_torque": (m_a, 0.0)}), _at_rest)
    l0 = sim.angular_momentum()
    sim.run_until([0.5])
    np.testing.assert_allclose(sim.angular_momentum()[2] - l0[2], m_a * 0.5, rtol=1e-5, atol=0)


def test_precession_model_refuses_at_the_lock_and_says_why():
    """The case turning about its y axis (the inner axis at α = 0) tips the inertially fixed
    spin axis toward the outer axis: β = −q t reaches −90° after π/(2q)."""
    q = 1.0
    p = FreeGyroParams(1e-4, 6e-5, 2513.0, max_step=1e-3)
    sim = FreeGyroSimulator(p, lambda t: np.tile([0.0, q, 0.0], (np.shape(t)[0], 1)))
    a, _ = sim.run_until([1.0])
    assert a[0, 1] == pytest.approx(-1.0, abs=1e-9)
    with pytest.raises(ValueError, match=r"gimbal lock\): the precession model divides by cos β"):
        sim.run_until([2.0])


def test_full_model_without_outer_inertia_refuses_at_the_lock():
    """No I_oz and no I_gx: M_11 = (J_t + I_gz) cos²β vanishes at the lock.  The case turning
    about its y axis drives β to −90° (as in the precession test)."""
    p = FreeGyroParams(**{**SLOW, "inner_gimbal_inertia": (0.0, 2e-5, 2e-5),
                          "outer_gimbal_inertia": (3e-5, 3e-5, 0.0),
                          "initial_angles": (0.0, 0.0), "initial_rates": None})
    sim = FreeGyroSimulator(p, lambda t: np.tile([0.0, 1.0, 0.0], (np.shape(t)[0], 1)))
    with pytest.raises(ValueError, match="outer-axis inertia vanished"):
        sim.run_until([3.0])


def test_start_at_the_lock_needs_the_full_model_with_rates():
    with pytest.raises(ValueError, match="gimbal lock"):
        FreeGyroParams(1e-4, 6e-5, 100.0, initial_angles=(0.0, math.pi / 2))
    FreeGyroParams(**{**SLOW, "initial_angles": (0.0, math.pi / 2)})  # full + rates: allowed


def test_gimbal_lock_flip_scene_goes_over_the_top_and_precession_refuses():
    spec = load_scene("gimbal_lock_flip")
    b = SceneSimulator(spec, 50.0).next_block(101)
    assert b.gimbal.names == ("outer_gimbal", "inner_gimbal")
    assert np.max(b.gimbal.positions[:, 1]) > math.radians(100.0)
    # the published inner rate is the derivative of the published angle (trapezoid, 20 ms)
    t = (b.t_ns - b.t_ns[0]) / 1e9
    incr = np.diff(b.gimbal.positions[:, 1])
    trap = 0.5 * np.diff(t) * (b.gimbal.velocities[1:, 1] + b.gimbal.velocities[:-1, 1])
    np.testing.assert_allclose(incr, trap, rtol=0, atol=2e-3)
    d = dict(spec.source)
    d["free_gyro"] = {**d["free_gyro"], "model": "precession", "initial_rates": None,
                      "initial_angles": [0.0, 0.0],
                      "inner_gimbal_inertia": [0.0, 0.0, 0.0],
                      "outer_gimbal_inertia": [0.0, 0.0, 0.0]}
    d["motion"] = {"type": "profile", "segments": [{"duration_s": 10.0,
                                                    "angular_rate_deg_s": [0.0, 30.0, 0.0]}]}
    with pytest.raises(ValueError, match="gimbal lock"):
        SceneSimulator(SceneSpec.from_dict(d), 50.0).next_block(201)  # β = −90° at 3 s
