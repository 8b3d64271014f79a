"""Two-gimbal free gyro (textbook §2-1…§2-4, §4-6, §5-1…§5-3) against closed forms: rigid
kinematics of an inertially fixed spin axis (scipy Rotation), Earth and transport rates
(earth.py), precession M/H, and the linearized nutation solution."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from gyro_attitude.core.earth import OMEGA_IE, earth_rate_enu, nav_rate_enu, radii_of_curvature
from gyro_attitude.core.gyro.free_gyro import (
    FreeGyroParams,
    FreeGyroSimulator,
    HarmonicTorque,
    ImpactTorque,
    free_gyro_angles_from_spin_axis,
)

RPM_24000 = 24000 * 2 * np.pi / 60
ROTOR = dict(spin_inertia=1e-4, transverse_inertia=5e-5, spin_rate=RPM_24000)
LIGHT_GIMBALS = dict(inner_gimbal_inertia=(1e-5, 1.2e-5, 1e-5),
                     outer_gimbal_inertia=(2e-5, 2e-5, 3e-5))


def _const(w):
    w = np.asarray(w, dtype=float)
    return lambda t: np.tile(w, (len(t), 1))


def _angles_of_fixed_spin_axis(s_c0, rotvec_c):
    """Case rotating at constant ω_c (case axes): s_c(t) = exp(−[ω_c×] t) s_c(0)."""
    s = Rotation.from_rotvec(-rotvec_c).apply(s_c0)
    return free_gyro_angles_from_spin_axis(s)


def _angle_diff(a, b):
    return np.angle(np.exp(1j * (a - b)))


@pytest.mark.parametrize("model", ["precession", "full"])
def test_stationary_base_apparent_drift_is_earth_rate_sin_latitude(model):
    lat = np.radians(52.0)
    w_c = earth_rate_enu(lat)  # case axes = ENU (level, x east)
    extra = LIGHT_GIMBALS if model == "full" else {}
    params = FreeGyroParams(**ROTOR, **extra, model=model, initial_angles=(np.radians(30), 0.0),
                            max_step=0.5 if model == "precession" else 0.1)
    sim = FreeGyroSimulator(params, _const(w_c))
    t = np.linspace(0, 600.0 if model == "full" else 7200.0, 13)
    angles, rates = sim.run_until(t)
    s0 = [np.cos(np.radians(30)), np.sin(np.radians(30)), 0.0]
    expected = _angles_of_fixed_spin_axis(s0, np.outer(t, w_c))
    err = np.max(np.abs(_angle_diff(angles, expected)))
    # measured: precession 3.6e-15 rad (rounding; RK4 is exact for this slow linear motion),
    # full 5.9e-11 rad (forced nutation from the base rate, ~ω_ie J_t / H); ~10× margin
    assert err < (5e-14 if model == "precession" else 6e-10)
    # the apparent drift about the vertical at the start is exactly −ω_ie sin L (both models
    # start on the precession solution: measured equal to the last bit)
    assert rates[0, 0] == pytest.approx(-OMEGA_IE * np.sin(lat), rel=1e-12)


def test_moving_east_adds_transport_rate():
    lat, h, v_e = np.radians(35.0), 3000.0, 250.0
    w_c = nav_rate_enu(lat, h, [v_e, 0.0, 0.0])
    _, r_n = radii_of_curvature(lat)
    sim = FreeGyroSimulator(FreeGyroParams(**ROTOR, max_step=0.5), _const(w_c))
    t = np.linspace(0, 3600.0, 7)
    angles, rates = sim.run_until(t)
    expected_drift = -(OMEGA_IE * np.sin(lat) + v_e * np.tan(lat) / (r_n + h))
    assert rates[0, 0] == pytest.approx(expected_drift, rel=1e-12)
    expected = _angles_of_fixed_spin_axis([1.0, 0, 0], np.outer(t, w_c))
    assert np.max(np.abs(_angle_diff(angles, expected))) < 1e-12


def _ship_base(lat, yaw_rate, roll_amp, roll_hz):
    """Ship yawing at a constant rate and rolling sinusoidally; returns ω_ib^b(t) and the
    exact spin direction in body axes for a spin axis fixed in inertial space."""
    w_in = earth_rate_enu(lat)
    wr = 2 * np.pi * roll_hz

    def c_bn(t):
        yaw = Rotation.from_rotvec(np.outer(yaw_rate * t, [0, 0, 1]))
        roll = Rotation.from_rotvec(np.outer(roll_amp * np.sin(wr * t), [1, 0, 0]))
        return (yaw * roll).inv()

    def omega(t):
        t = np.asarray(t, dtype=float)
        roll = Rotation.from_rotvec(np.outer(roll_amp * np.sin(wr * t), [1, 0, 0]))
        # ω_nb^b = Rx(roll)ᵀ (yaw_rate e_z) + roll_rate e_x ; ω_in^b = C_bn ω_in^n
        w_nb = roll.inv().apply(np.tile([0, 0, yaw_rate], (len(t), 1)))
        w_nb[:, 0] += roll_amp * wr * np.cos(wr * t)
        return c_bn(t).apply(np.tile(w_in, (len(t), 1))) + w_nb

    def spin_b(t, s_n0):
        s_n = Rotation.from_rotvec(-np.outer(t, w_in)).apply(s_n0)  # n turns at ω_in
        return c_bn(t).apply(s_n)

    return omega, spin_b


@pytest.mark.parametrize("model", ["precession", "full"])
def test_gimbal_angles_follow_inertially_fixed_spin_axis_on_rolling_yawing_ship(model):
    lat = np.radians(40.0)
    omega, spin_b = _ship_base(lat, yaw_rate=0.05, roll_amp=np.radians(10), roll_hz=0.1)
    extra = LIGHT_GIMBALS if model == "full" else {}
    params = FreeGyroParams(**ROTOR, **extra, model=model, max_step=0.01)
    sim = FreeGyroSimulator(params, omega)
    t = np.linspace(0, 30.0, 31)
    angles, _ = sim.run_until(t)
    expected = free_gyro_angles_from_spin_axis(spin_b(t, [1.0, 0, 0]))
    err = np.max(np.abs(_angle_diff(angles, expected)))
    # precession: RK4 at 10 ms, measured 1.8e-13 rad; full model: gimbal inertia lags the
    # spin axis by ~ (base angular accel) J/H, measured 2.8e-6 rad; ~10× margin each
    assert err < (2e-12 if model == "precession" else 3e-5)
    assert np.ptp(angles[:, 0]) > 1.0  # the outer gimbal really turned (yaw 1.5 rad)


def test_harmonic_torque_on_inner_axis_precesses_outer_gimbal():
    amp, f, phase = 2e-3, 2.0, 0.4
    nu = 2 * np.pi * f
    params = FreeGyroParams(**ROTOR, harmonic_torques=(HarmonicTorque((0.0, amp), f, phase),),
                            max_step=2e-3)
    sim = FreeGyroSimulator(params, _const([0, 0, 0]))
    t = np.linspace(0, 3.0, 301)
    angles, rates = sim.run_until(t)
    hmom = params.spin_momentum
    # α̇ = M_β / H  ⇒  α(t) = A/(Hν) (cos φ − cos(νt + φ)); β stays 0 (no outer torque)
    expected = amp / (hmom * nu) * (np.cos(phase) - np.cos(nu * t + phase))
    # RK4 with 2 ms steps (1/250 of the torque period): measured 2.7e-10 of the amplitude
    assert np.max(np.abs(angles[:, 0] - expected)) < 3e-9 * (amp / (hmom * nu))
    assert np.max(np.abs(angles[:, 1])) == 0.0
    assert np.max(np.abs(rates[:, 0] - amp * np.sin(nu * t + phase) / hmom)) < 1e-15


def test_impact_on_inner_axis_jumps_outer_gimbal_by_s_over_h():
    s_imp = 5e-4
    imp = ImpactTorque(t_start=0.1, duration=1e-3, impulse=(0.0, s_imp))
    hmom = ROTOR["spin_inertia"] * ROTOR["spin_rate"]
    prec = FreeGyroSimulator(FreeGyroParams(**ROTOR, impacts=(imp,)), _const([0, 0, 0]))
    a_p, _ = prec.run_until(np.array([0.05, 0.5]))
    assert a_p[0, 0] == 0.0
    assert a_p[1, 0] == pytest.approx(s_imp / hmom, rel=1e-12)
    # full model: same mean jump plus a nutation of amplitude S/(A_y ω_nut) in β
    params = FreeGyroParams(**ROTOR, **LIGHT_GIMBALS, model="full", impacts=(imp,),
                            integrator="rk4", steps_per_nutation=40)
    full = FreeGyroSimulator(params, _const([0, 0, 0]))
    w_nut = params.nutation_frequency_rad_s()
    # 20 whole nutation periods (RK4 itself damps |R(iωh)| = 1 − (ωh)⁶/144 per step: keep
    # ωh small and the run short so that the numerical decay stays < 1e-6)
    t = np.linspace(0.2, 0.2 + 20 * 2 * np.pi / w_nut, 801)
    a_f, _ = full.run_until(t)
    # measured 1.4e-4 (the nutation's residual mean over the sampled window)
    assert np.mean(a_f[:, 0]) == pytest.approx(s_imp / hmom, rel=1e-3)
    a_y = ROTOR["transverse_inertia"] + LIGHT_GIMBALS["inner_gimbal_inertia"][1]
    beta_amp = 0.5 * np.ptp(a_f[:, 1])
    # a 1 ms pulse is not a Dirac impulse at ω_nut ≈ 3.6 krad/s: the finite-duration pulse
    # excites the nutation with the factor |sinc(ω τ / 2)|
    tau = imp.duration
    sinc = abs(np.sin(w_nut * tau / 2) / (w_nut * tau / 2))
    # measured 7.1e-4 (linearization and gimbal inertia in M_11); ~10× margin
    assert beta_amp == pytest.approx(s_imp / (a_y * w_nut) * sinc, rel=7e-3)


def test_friction_on_outer_axis_tilts_inner_gimbal_at_m_over_h():
    """§5-2: the base turning about the outer axis drags the outer bearing; its friction
    torque M precesses the inner gimbal: sin β(t) = −M t / H."""
    big_omega = 0.2  # rad/s, case turning about its z (= outer) axis
    cv, mc = 2e-5, 3e-5
    params = FreeGyroParams(**ROTOR, viscous_friction=(cv, 0.0), coulomb_friction=(mc, 0.0),
                            max_step=0.05)
    sim = FreeGyroSimulator(params, _const([0, 0, big_omega]))
    t = np.linspace(0, 20.0, 21)
    angles, rates = sim.run_until(t)
    hmom = params.spin_momentum
    m_total = mc + cv * big_omega  # relative outer rate is −Ω, friction opposes it
    assert np.max(np.abs(np.sin(angles[:, 1]) + m_total * t / hmom)) < 1e-12
    assert np.max(np.abs(rates[:, 0] + big_omega)) < 1e-12
    assert abs(angles[-1, 1]) > 2e-3  # a visible drift


def test_inner_coulomb_friction_root_is_unique_and_opposes_motion():
    # both axes with friction: the algebraic rate equation is solved by safeguarded Newton;
    # check the returned rates satisfy the precession equations they were solved from
    params = FreeGyroParams(**ROTOR, coulomb_friction=(2e-4, 1e-4), viscous_friction=(1e-5, 3e-5),
                            initial_angles=(0.3, 0.4), coulomb_smoothing_rate=1e-8)
    w = np.array([0.05, -0.1, 0.3])
    sim = FreeGyroSimulator(params, _const(w))
    (al, be), (ad, bd) = sim.state()
    hmom = params.spin_momentum
    m_a = -1e-5 * ad - 2e-4 * np.tanh(ad / 1e-8)
    m_b = -3e-5 * bd - 1e-4 * np.tanh(bd / 1e-8)
    c_gc = (Rotation.from_rotvec([0, 0, al]) * Rotation.from_rotvec([0, be, 0])).inv()
    wg = c_gc.apply(w)
    assert hmom * (wg[2] + ad * np.cos(be)) == pytest.approx(m_b, abs=1e-15)
    assert -hmom * np.cos(be) * (wg[1] + bd) == pytest.approx(m_a, abs=1e-15)


@pytest.mark.parametrize("integrator", ["rk4", "midpoint"])
def test_constant_torque_nutation_matches_linear_closed_form(integrator):
    """§4-3 with gimbals: from rest, torque M on the inner axis gives
    β = (M J/H²)(1 − cos ω t), α = (M/H)(t − sin(ω t)/ω), ω = H/J (massless gimbals)."""
    m = 1e-4
    spans = []
    for spin in (RPM_24000 / 4, RPM_24000):
        rotor = dict(ROTOR, spin_rate=spin)
        params = FreeGyroParams(**rotor, model="full", initial_rates=(0.0, 0.0),
                                constant_torque=(0.0, m), integrator=integrator,
                                max_step=1e-5, steps_per_nutation=40)
        hmom, jt = params.spin_momentum, ROTOR["transverse_inertia"]
        w = params.nutation_frequency_rad_s()
        assert w == pytest.approx(hmom / jt, rel=1e-15)
        sim = FreeGyroSimulator(params, _const([0, 0, 0]))
        t = np.linspace(0, 6 * 2 * np.pi / w, 241)
        angles, _ = sim.run_until(t)
        beta = m * jt / hmom**2 * (1 - np.cos(w * t))
        alpha = m / hmom * (t - np.sin(w * t) / w)
        amp = m * jt / hmom**2
        # measured (worst of the two spins, relative to amp): RK4 at 40 steps per nutation
        # 7.5e-7; the implicit midpoint rule at 10 µs (second order, phase error growing with
        # ωh) 4.8e-3. Each bound is ~10× what its method achieves.
        tol = {"rk4": 1e-5, "midpoint": 5e-2}[integrator] * amp
        assert np.max(np.abs(angles[:, 1] - beta)) < tol
        assert np.max(np.abs(angles[:, 0] - alpha)) < tol
        spans.append(np.ptp(angles[:, 1]))
    # nutation amplitude M J_t / H²: four times the spin, one sixteenth of the amplitude
    # (measured 1.0e-9 with RK4, 4.0e-8 with the midpoint rule)
    assert spans[0] / spans[1] == pytest.approx(16.0, rel={"rk4": 1e-8, "midpoint": 5e-7}[integrator])


def test_fast_rotor_unresolved_steps_stay_stable_and_conserve_energy():
    """24 000 rpm on light gimbals, inertial base, nutation excited by an initial gimbal rate;
    the implicit midpoint steps over ~6 nutation periods at a time. Energy (a conserved
    quantity of the torque-free system) stays bounded to round-off-free precision."""
    params = FreeGyroParams(**ROTOR, **LIGHT_GIMBALS, model="full", initial_rates=(0.3, -0.2),
                            initial_angles=(0.2, 0.5), max_step=1e-2)
    period = 2 * np.pi / params.nutation_frequency_rad_s(0.5)
    assert params.max_step > 5 * period
    sim = FreeGyroSimulator(params, _const([0, 0, 0]))
    e_rotor = 0.5 * params.spin_momentum**2 / params.spin_inertia
    e0 = sim.kinetic_energy() - e_rotor
    energies, betas = [], []
    for t_end in np.linspace(1.0, 20.0, 20):
        a, _ = sim.run_until([t_end])
        energies.append(sim.kinetic_energy() - e_rotor)
        betas.append(a[0, 1])
    energies = np.array(energies)
    # measured: energy within 2.4e-5·e0, β within 2.5e-5 rad of 0.5; ~10× margin
    assert np.max(np.abs(energies - e0)) < 3e-4 * e0
    assert np.max(np.abs(np.array(betas) - 0.5)) < 3e-4
    assert sim.steps == 2000


def test_full_model_converges_to_precession_model_as_spin_grows():
    """Start the gimbals at rest relative to a yawing, rolling case: the full model nutates
    about the precession solution with an amplitude ∝ 1/H."""
    lat = np.radians(30.0)
    omega, _ = _ship_base(lat, yaw_rate=0.1, roll_amp=np.radians(5), roll_hz=0.2)
    t = np.linspace(0, 5.0, 51)
    errors = []
    for spin in (RPM_24000 / 4, RPM_24000, 4 * RPM_24000):
        rotor = dict(ROTOR, spin_rate=spin)
        prec = FreeGyroSimulator(FreeGyroParams(**rotor, max_step=5e-3), omega)
        full = FreeGyroSimulator(FreeGyroParams(**rotor, **LIGHT_GIMBALS, model="full",
                                                initial_rates=(0.0, 0.0), max_step=5e-3), omega)
        a_p, _ = prec.run_until(t)
        a_f, _ = full.run_until(t)
        errors.append(np.max(np.abs(_angle_diff(a_f, a_p))))
    assert errors[0] > errors[1] > errors[2]
    assert errors[0] / errors[1] > 3.0 and errors[1] / errors[2] > 3.0
    assert errors[2] < 1e-4


def test_bad_parameters_and_inputs_raise():
    with pytest.raises(ValueError, match="spin_rate"):
        FreeGyroParams(1e-4, 5e-5, 0.0)
    with pytest.raises(ValueError, match="model"):
        FreeGyroParams(**ROTOR, model="exact")
    with pytest.raises(ValueError, match="viscous_friction"):
        FreeGyroParams(**ROTOR, viscous_friction=(-1.0, 0.0))
    with pytest.raises(ValueError, match="gimbal lock"):
        FreeGyroParams(**ROTOR, initial_angles=(0.0, np.pi / 2))
    sim = FreeGyroSimulator(FreeGyroParams(**ROTOR), _const([0, 0, 0]))
    sim.run_until([1.0])
    with pytest.raises(ValueError, match="non-decreasing"):
        sim.run_until([0.5])
    with pytest.raises(ValueError, match="omega_base_fn"):
        FreeGyroSimulator(FreeGyroParams(**ROTOR), lambda t: np.zeros((len(t), 2)))
    # a constant outer torque drives the inner gimbal into gimbal lock: clear error
    lock = FreeGyroSimulator(FreeGyroParams(**ROTOR, constant_torque=(0.05, 0.0)),
                             _const([0, 0, 0]))
    with pytest.raises(ValueError, match="gimbal lock"):
        lock.run_until([10.0])


def test_full_model_outer_friction_drift_matches_precession_law():
    """Gimbal inertia adds only a small nutation to the §5-2 friction drift sin β = −M t/H."""
    big_omega, mc = 0.2, 3e-4
    params = FreeGyroParams(**ROTOR, **LIGHT_GIMBALS, model="full", coulomb_friction=(mc, 0.0),
                            max_step=2e-3)
    sim = FreeGyroSimulator(params, _const([0, 0, big_omega]))
    t = np.linspace(0, 4.0, 41)
    angles, rates = sim.run_until(t)
    drift = -mc * t / params.spin_momentum
    assert abs(drift[-1]) > 4e-3
    # measured 3.6e-13 relative and 1.7e-12 rad/s (midpoint rule at 2 ms); ~10× margin
    assert np.max(np.abs(np.sin(angles[:, 1]) - drift)) < 5e-12 * abs(drift[-1])
    assert np.max(np.abs(rates[1:, 0] + big_omega)) < 2e-11


def test_harmonic_torque_at_nutation_frequency_resonates():
    """§4-6 with gimbals: a torque M sin(ω t) on the inner axis at the nutation frequency,
    from rest, grows as β = M/(2 A_y ω²) (sin ωt − ωt cos ωt) (linearized, massless gimbals:
    A_y = M_11 = J_t)."""
    params0 = FreeGyroParams(**ROTOR, model="full")
    w = params0.nutation_frequency_rad_s()
    m = 2e-5
    params = FreeGyroParams(**ROTOR, model="full", initial_rates=(0.0, 0.0), integrator="rk4",
                            steps_per_nutation=40,
                            harmonic_torques=(HarmonicTorque((0.0, m), w / (2 * np.pi)),))
    sim = FreeGyroSimulator(params, _const([0, 0, 0]))
    t = np.linspace(0, 30 * 2 * np.pi / w, 601)
    angles, _ = sim.run_until(t)
    jt = ROTOR["transverse_inertia"]
    beta = m / (2 * jt * w**2) * (np.sin(w * t) - w * t * np.cos(w * t))
    peak = np.max(np.abs(beta))
    # measured 4.6e-4 of the peak (RK4 at 40 steps per nutation, linearization); ~10× margin
    assert np.max(np.abs(angles[:, 1] - beta)) < 5e-3 * peak
    assert np.max(np.abs(angles[-60:, 1])) > 5 * np.max(np.abs(angles[:60, 1]))  # growing


def _rz(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _ry(b):
    c, s = np.cos(b), np.sin(b)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


@pytest.mark.parametrize("base_accel", ["given", "finite_difference"])
def test_full_model_satisfies_lagrange_equations_of_the_routhian(base_accel):
    """Independent derivation: the rotor spin angle is cyclic (p_φ = H), so the gimbal
    angles obey Lagrange's equations of the Routhian
    R = ½ ω_oᵀ I_o ω_o + ½ ω_gᵀ diag(I_gx, I_gy + J_t, I_gz + J_t) ω_g + H ω_gx,
    with generalized forces = the axis torques. Written here with plain matrices and
    checked by finite differences along the simulated trajectory (moving, accelerating
    base, unequal gimbal inertias, slow rotor so inertia terms matter)."""
    i_o = np.array([2e-4, 6e-4, 5e-4])
    i_g = np.array([1e-4, 2e-4, 3e-4])
    jt, js, spin = 5e-5, 1e-4, 100.0
    hmom = js * spin
    torque = (3e-4, -2e-4)

    def omega(t):
        t = np.asarray(t, dtype=float)
        return np.stack((0.5 * np.sin(1.3 * t), 0.4 * np.cos(0.7 * t), 0.3 + 0.2 * np.sin(2 * t)),
                        axis=1)

    def omega_dot(t):
        t = np.asarray(t, dtype=float)
        return np.stack((0.65 * np.cos(1.3 * t), -0.28 * np.sin(0.7 * t), 0.4 * np.cos(2 * t)),
                        axis=1)

    def routhian(q, qd, t):
        w_c = omega([t])[0]
        w_o = _rz(q[0]).T @ w_c + np.array([0.0, 0.0, qd[0]])
        w_g = _ry(q[1]).T @ w_o + np.array([0.0, qd[1], 0.0])
        a = np.array([i_g[0], i_g[1] + jt, i_g[2] + jt])
        return 0.5 * w_o @ (i_o * w_o) + 0.5 * w_g @ (a * w_g) + hmom * w_g[0]

    def grad(f, x, d):
        g = np.empty(2)
        for k in range(2):
            e = np.zeros(2)
            e[k] = d
            g[k] = (f(x + e) - f(x - e)) / (2 * d)
        return g

    params = FreeGyroParams(spin_inertia=js, transverse_inertia=jt, spin_rate=spin, model="full",
                            inner_gimbal_inertia=tuple(i_g), outer_gimbal_inertia=tuple(i_o),
                            initial_angles=(0.4, -0.3), initial_rates=(0.8, -0.5),
                            constant_torque=torque, integrator="rk4", max_step=2e-4)
    sim = FreeGyroSimulator(params, omega,
                            omega_base_dot_fn=omega_dot if base_accel == "given" else None)
    dt = 1e-4  # finite-difference error ~ (ω_nut dt)²/6 with ω_nut ≈ 22 rad/s here
    centres = np.array([0.3, 0.9, 1.7])
    t = np.sort(np.concatenate((centres - dt, centres, centres + dt)))
    q, qd = sim.run_until(t)
    worst = 0.0
    for k in range(len(centres)):
        i0, i1, i2 = 3 * k, 3 * k + 1, 3 * k + 2
        p_minus = grad(lambda v, i=i0: routhian(q[i], v, t[i]), qd[i0], 1e-3)
        p_plus = grad(lambda v, i=i2: routhian(q[i], v, t[i]), qd[i2], 1e-3)
        dp_dt = (p_plus - p_minus) / (2 * dt)
        d_r_dq = grad(lambda v, i=i1: routhian(v, qd[i], t[i]), q[i1], 1e-6)
        residual = dp_dt - d_r_dq - np.array(torque)
        scale = np.max(np.abs(d_r_dq)) + np.max(np.abs(dp_dt))
        worst = max(worst, np.max(np.abs(residual)) / scale)
    assert worst < 1e-6, f"worst relative residual {worst:.2e}"


def test_coulomb_friction_damps_nutation_until_the_gimbals_stick():
    """Dissipation: with dry friction on both axes (inertial base, no other torque) the
    kinetic energy never increases and the nutation dies out in finite time (the gimbals
    stick: relative rates exactly zero). Checked for the implicit step (friction taken
    backward-Euler) with a sharp tanh (ε = 1e-9 rad/s)."""
    params = FreeGyroParams(**ROTOR, **LIGHT_GIMBALS, model="full", initial_rates=(0.01, 0.02),
                            coulomb_friction=(1e-4, 1e-4), max_step=2e-4)
    sim = FreeGyroSimulator(params, _const([0, 0, 0]))
    e_rotor = 0.5 * params.spin_momentum**2 / params.spin_inertia
    energies = [sim.kinetic_energy() - e_rotor]
    for t_end in np.linspace(0.01, 0.5, 50):
        sim.run_until([t_end])
        energies.append(sim.kinetic_energy() - e_rotor)
    energies = np.array(energies)
    assert np.all(np.diff(energies) <= 1e-12 * energies[0])
    _, rates = sim.state()
    assert np.max(np.abs(rates)) < 1e-12
    assert energies[-1] < 1e-12 * energies[0]


@pytest.mark.parametrize("model", ["precession", "full"])
def test_run_until_in_blocks_matches_one_call(model):
    omega, _ = _ship_base(np.radians(30.0), yaw_rate=0.1, roll_amp=np.radians(5), roll_hz=0.2)
    extra = LIGHT_GIMBALS if model == "full" else {}
    params = FreeGyroParams(**ROTOR, **extra, model=model, max_step=5e-3,
                            harmonic_torques=(HarmonicTorque((1e-4, -2e-4), 1.5),),
                            impacts=(ImpactTorque(0.333, 2e-3, (1e-5, 2e-5)),))
    t = np.linspace(0, 1.0, 101)
    whole = FreeGyroSimulator(params, omega)
    a1, r1 = whole.run_until(t)
    parts = FreeGyroSimulator(params, omega)
    blocks = [parts.run_until(t[i:i + 7]) for i in range(0, len(t), 7)]
    a2 = np.concatenate([b[0] for b in blocks])
    r2 = np.concatenate([b[1] for b in blocks])
    # the step grids differ between the two runs (output times are grid points), so the
    # results agree to the integration error, not bit for bit
    assert np.max(np.abs(a1 - a2)) < 1e-9
    assert np.max(np.abs(r1 - r2)) < 1e-7
    assert parts.t == whole.t == 1.0
