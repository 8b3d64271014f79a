"""Single-gimbal rate gyro (§4-2 of the textbook) against the closed-form second-order model and
scipy.signal (independent linear-system oracle)."""

import numpy as np
import pytest
from scipy import optimize, signal

from gyro_attitude.core.gyro.rate_gyro import RateGyroParams, RateGyroTriad, rate_gyro_step_response

#: The textbook transfer function ω_n²/(s² + 2ζω_n s + ω_n²) alone: gimbal deflection so small
#: that cos β = 1 to round-off, and no base angular acceleration about the output axis.
LINEAR = dict(gimbal_gain_s=1e-9, output_axis_acceleration=False)


def _analytic_step(t, fn_hz, zeta):
    """Unit-step response of ω_n²/(s² + 2ζω_n s + ω_n²), written out here (not imported)."""
    wn = 2 * np.pi * fn_hz
    if zeta < 1:
        wd = wn * np.sqrt(1 - zeta**2)
        return 1 - np.exp(-zeta * wn * t) * (
            np.cos(wd * t) + zeta / np.sqrt(1 - zeta**2) * np.sin(wd * t))
    if zeta == 1:
        return 1 - np.exp(-wn * t) * (1 + wn * t)
    r = np.sqrt(zeta**2 - 1)
    s1, s2 = -wn * (zeta - r), -wn * (zeta + r)
    return 1 - (s2 * np.exp(s1 * t) - s1 * np.exp(s2 * t)) / (s2 - s1)


@pytest.mark.parametrize("zeta", [0.2, 0.7, 1.0, 2.5])
def test_zoh_step_response_equals_analytic_second_order(zeta):
    fn, dt = 40.0, 1e-3
    gyro = RateGyroTriad(RateGyroParams(fn, zeta, hold="zoh", **LINEAR), dt, initial="rest")
    rates = np.array([1.0, -0.5, 2e-3])
    n = 3000
    out = gyro.step_block(np.tile(rates, (n, 1)))
    t = np.arange(n) * dt
    expected = _analytic_step(t, fn, zeta)[:, None] * rates
    assert np.max(np.abs(out - expected)) < 1e-12
    # the public closed form agrees with the one written here
    assert np.max(np.abs(rate_gyro_step_response(t, fn, zeta) - _analytic_step(t, fn, zeta))) < 1e-14


def test_steady_state_output_equals_input_rate():
    gyro = RateGyroTriad(RateGyroParams(25.0, 0.6, **LINEAR), 2e-3, initial="steady")
    w = np.array([0.3, -1.2, 7.292115e-5])
    out = gyro.step_block(np.tile(w, (500, 1)))
    assert np.max(np.abs(out - w)) < 1e-14
    rest = RateGyroTriad(RateGyroParams(25.0, 0.6, **LINEAR), 2e-3, initial="rest")
    out = rest.step_block(np.tile(w, (2000, 1)))  # 4 s = 63 time constants 1/(ζω_n)
    assert np.max(np.abs(out[-1] - w)) < 1e-12


@pytest.mark.parametrize("hold, interp", [("foh", True), ("zoh", False)])
def test_hold_matches_scipy_lsim_for_a_smooth_input(hold, interp):
    """scipy's lsim is the oracle: interp=True interpolates the input linearly between samples
    (first-order hold), interp=False holds each sample until the next (zero-order hold: over
    [t_{k-1}, t_k] the input is u_{k-1}, the sample at the START of the interval). A step
    cannot tell which sample a ZOH holds (they differ at one instant only); this smooth input
    can: holding u_k instead shifts the output by about dt·u̇ (1e-3 here)."""
    fn, zeta, dt = 12.0, 0.45, 2e-3
    t = np.arange(4000) * dt
    u = np.stack((np.sin(2 * np.pi * 3.0 * t) + 0.2 * t, np.cos(2 * np.pi * 17.0 * t),
                  np.where(t > 1.0, 1.0, 0.0) * t), axis=1)
    out = RateGyroTriad(RateGyroParams(fn, zeta, hold=hold, **LINEAR), dt, initial="rest").step_block(u)
    wn = 2 * np.pi * fn
    sys = signal.lti([wn**2], [1.0, 2 * zeta * wn, wn**2])
    for ax in range(3):
        _, y, _ = signal.lsim(sys, u[:, ax], t, interp=interp)
        # both are exact discretizations of the same system and agree to rounding (measured
        # ≤ 1.4e-15 relative to the output's peak); 1e-14 leaves ~10× margin
        assert np.max(np.abs(out[:, ax] - y)) < 1e-14 * np.max(np.abs(y))


def test_sine_gain_at_bandwidth_is_minus_3_db():
    for zeta in (0.3, 0.7071, 1.5):
        p = RateGyroParams(30.0, zeta)
        wn = p.natural_frequency_rad_s
        w = 2 * np.pi * p.bandwidth_hz
        gain = abs(wn**2 / ((1j * w) ** 2 + 2 * zeta * wn * 1j * w + wn**2))
        assert gain == pytest.approx(1 / np.sqrt(2), rel=1e-12)


def test_simulated_sine_amplitude_matches_transfer_function():
    p = RateGyroParams(30.0, 0.4, **LINEAR)
    dt = 1e-4
    f = 20.0
    t = np.arange(40000) * dt
    u = np.sin(2 * np.pi * f * t)
    out = RateGyroTriad(p, dt, initial="rest").step_block(np.stack((u, u, u), axis=1))
    tail = out[-int(2 / f / dt):, 0]  # last two periods, transient long gone (e^{-ζω_n t})
    wn, w = p.natural_frequency_rad_s, 2 * np.pi * f
    gain = abs(wn**2 / (-(w**2) + 2j * 0.4 * wn * w + wn**2))
    assert np.max(tail) == pytest.approx(gain, rel=2e-4)


def test_blocks_resume_exactly():
    p = RateGyroParams(50.0, 0.5)
    rng = np.random.default_rng(3)
    u = rng.normal(size=(1000, 3))
    whole = RateGyroTriad(p, 1e-3).step_block(u)
    g = RateGyroTriad(p, 1e-3)
    parts = np.concatenate([g.step_block(u[a:b]) for a, b in ((0, 1), (1, 400), (400, 401),
                                                              (401, 1000))])
    assert np.array_equal(parts, whole)
    assert g.samples == 1000


def test_cross_coupling_steady_state_solves_tilted_input_axis_equation():
    c, k = 1.0, 0.05  # gimbal deflection 0.05 rad per rad/s
    p = RateGyroParams(40.0, 0.7, cross_coupling=c, gimbal_gain_s=k)
    w = np.array([2.0, 1.5, -0.8])
    out = RateGyroTriad(p, 1e-3, initial="rest").step_block(np.tile(w, (3000, 1)))
    spin = np.array([w[1], w[2], w[0]])
    for ax in range(3):
        # x = ω_I cos(kx) − c ω_S sin(kx), solved independently by Brent's method
        x = optimize.brentq(lambda x, ax=ax: x - (w[ax] * np.cos(k * x) - c * spin[ax] * np.sin(k * x)),
                            -10, 10, xtol=1e-15)
        assert out[-1, ax] == pytest.approx(x, abs=1e-10)
        assert abs(x - w[ax]) > 1e-3  # the effect is really there


def test_from_physical_parameters():
    h, j, d, k = 0.02, 1e-6, 2e-4, 0.05
    p = RateGyroParams.from_physical(h, j, d, k)
    assert p.natural_frequency_rad_s == pytest.approx(np.sqrt(k / j), rel=1e-14)
    assert p.damping_ratio == pytest.approx(d / (2 * np.sqrt(k * j)), rel=1e-14)
    assert p.gimbal_gain_s == pytest.approx(h / k, rel=1e-14)


@pytest.mark.parametrize("kwargs, word", [
    (dict(natural_frequency_hz=0.0, damping_ratio=0.5), "natural_frequency_hz"),
    (dict(natural_frequency_hz=10.0, damping_ratio=-1.0), "damping_ratio"),
    (dict(natural_frequency_hz=10.0, damping_ratio=0.5, hold="cubic"), "hold"),
    (dict(natural_frequency_hz=np.nan, damping_ratio=0.5), "natural_frequency_hz"),
])
def test_bad_parameters_raise(kwargs, word):
    with pytest.raises(ValueError, match=word):
        RateGyroParams(**kwargs)


def test_bad_inputs_raise():
    g = RateGyroTriad(RateGyroParams(10.0, 0.5), 1e-3)
    with pytest.raises(ValueError, match="shape"):
        g.step_block(np.zeros((5, 2)))
    with pytest.raises(ValueError, match="non-finite"):
        g.step_block(np.full((2, 3), np.inf))
    with pytest.raises(ValueError, match="dt"):
        RateGyroTriad(RateGyroParams(10.0, 0.5), 0.0)
