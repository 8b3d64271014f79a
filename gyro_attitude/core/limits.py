"""Physically plausible limits of every scene value (one home; the scene schema and registry and
the pose checks of ``core.trajectory`` read them).

A value outside these is refused at validation with the key's path, before anything is
simulated, so that no valid scene writes a file of implausible rates. The limits are set
one to two orders of magnitude beyond the most extreme real case named beside each, so no
real use is refused, yet 1e300 and 1e-300 are:

- speed: Earth escape speed is 11.2 km/s; nothing the local-level ENU model describes moves
  faster (a rifle bullet ~1 km/s, a re-entry vehicle ~7.8 km/s);
- body rate: a rifle bullet spins at up to ~5000 rev/s (3e4 rad/s); MEMS gyros saturate at
  ±2000–4000 °/s, so 1e4 rev/s bounds every rate any motion may reach;
- acceleration: gun-hardened IMUs are rated for 20,000 g at launch (2e5 m/s²);
- periods: at least 1 ms (a vibration at 1 kHz, the upper end of shaker tables) and at most a
  day (a longer "period" is a drift, not an oscillation);
- sensor errors: roughly 100x the worst consumer MEMS (bias 1 rad/s ≈ 57 °/s, noise density
  0.1 rad/√s ≈ 340 °/√h, accelerometer bias 1 g);
- mechanical instruments: rotor angular momentum up to 1e4 N·m·s (a large ship's gyrocompass
  ~10 N·m·s, a spacecraft control moment gyro ~1e3), inertias up to 1e3 kg·m², torques up to
  1e6 N·m.
"""

from __future__ import annotations

import math

#: Highest sample rate a scene may ask for (Hz). Simulated IMUs run at 100 Hz…10 kHz; 1 MHz
#: leaves room for stress tests while a block of a fraction of a second stays small.
MAX_RATE_HZ = 1.0e6
#: Longest suggested run (s): about 116 days.
MAX_DURATION_S = 1.0e7
#: Fastest carrier speed (m/s) — and each ENU velocity component.
MAX_SPEED_MPS = 1.2e4
#: Lowest and highest ellipsoidal height (m) of a scene's origin and of a trajectory's poses.
MIN_HEIGHT_M = -12_000.0
MAX_HEIGHT_M = 1.0e6
#: Closest approach to a pole (rad of latitude, 1e-4° ≈ 11 m): the ENU frame has no East
#: and North at the pole, and the longitude rate v_E/((R_N+h) cos L) diverges as L → ±90°.
POLE_MARGIN_RAD = math.radians(1e-4)
#: Fastest rotation any motion may reach (rev/s = Hz); in rad/s below.
MAX_ROTATION_HZ = 1.0e4
MAX_BODY_RATE_RAD_S = 2.0 * math.pi * MAX_ROTATION_HZ
#: Largest acceleration (m/s²), per component of a profile segment and for a ship's heave.
MAX_ACCEL_MPS2 = 2.0e5
#: Shortest and longest period of an oscillation (s).
MIN_PERIOD_S = 1.0e-3
MAX_PERIOD_S = 86_400.0
#: Largest ship oscillation amplitudes: roll/pitch 90° (capsized beyond), yaw 180°, heave
#: 100 m (the highest recorded waves are ~30 m).
MAX_TILT_AMPLITUDE_DEG = 90.0
MAX_YAW_AMPLITUDE_DEG = 180.0
MAX_HEAVE_M = 100.0
#: Longest scene description (characters): it is one line.
MAX_DESCRIPTION_CHARS = 10_000
#: Largest seed (SeedSequence takes any int; 2⁶⁴ − 1 keeps it a machine word).
MAX_SEED = 2**64 - 1

#: Sensor error keys (SI value as written): (lo, hi). Vectors are bounded per element.
GYRO_ERROR_LIMITS = {
    "bias_rad_s": (-1.0, 1.0),
    "scale_factor": (-1.0, 1.0),
    "misalignment_rad": (-0.1, 0.1),  # small-angle model: 0.1 rad ≈ 5.7°
    "arw_rad_sqrt_s": (0.0, 0.1),
    "bias_instability_rad_s": (0.0, 1.0),
    "bias_instability_tau_s": (1.0e-3, 1.0e7),
    "quantization_rad": (0.0, 0.1),
    # datasheet terms, bounded after conversion to SI
    "arw": (0.0, 0.1),
    "bias_instability": (0.0, 1.0),
    "rate_random_walk": (0.0, 0.1),
}
ACCEL_ERROR_LIMITS = {
    "bias_m_s2": (-10.0, 10.0),
    "scale_factor": (-1.0, 1.0),
    "misalignment_rad": (-0.1, 0.1),
    "vrw_m_s_sqrt_s": (0.0, 1.0),
    "bias_instability_m_s2": (0.0, 10.0),
    "bias_instability_tau_s": (1.0e-3, 1.0e7),
    "quantization_m_s": (0.0, 1.0),
    "vrw": (0.0, 1.0),
    "bias_instability": (0.0, 10.0),
    "acceleration_random_walk": (0.0, 1.0),
}

_INERTIA = (0.0, 1.0e3)  # kg·m²
_TORQUE = (-1.0e6, 1.0e6)  # N·m
_RATE = (-MAX_BODY_RATE_RAD_S, MAX_BODY_RATE_RAD_S)  # rad/s
_ANGLE = (-2.0 * math.pi, 2.0 * math.pi)  # rad
_TIME = (0.0, 1.0e7)  # s (the longest scene)

#: Numeric fields of the parameter dataclasses a scene section is built from (free_gyro,
#: gyro.rate_gyro, gyro.integrating_gyro, harmonic torques, impacts): (lo, hi, unit), per
#: element of a pair or triple. The dataclass's own checks (positive, non-zero) still apply.
PARAM_LIMITS: dict[str, dict[str, tuple[float, float, str]]] = {
    "FreeGyroParams": {
        "spin_inertia": (*_INERTIA, "kg·m²"),
        "transverse_inertia": (*_INERTIA, "kg·m²"),
        "spin_rate": (*_RATE, "rad/s"),
        "inner_gimbal_inertia": (*_INERTIA, "kg·m²"),
        "outer_gimbal_inertia": (*_INERTIA, "kg·m²"),
        "initial_angles": (*_ANGLE, "rad"),
        "initial_rates": (*_RATE, "rad/s"),
        "constant_torque": (*_TORQUE, "N·m"),
        "viscous_friction": (0.0, 1.0e6, "N·m·s"),
        "coulomb_friction": (0.0, 1.0e6, "N·m"),
        "coulomb_smoothing_rate": (1.0e-15, 1.0, "rad/s"),
        "max_step": (1.0e-9, 3600.0, "s"),
        "steps_per_nutation": (1.0, 1.0e4, ""),
        "base_rate_derivative_step": (1.0e-12, 1.0, "s"),
        "mass_unbalance": (-1.0, 1.0, "kg·m"),
        "outer_gimbal_stops": (*_ANGLE, "rad"),
        "inner_gimbal_stops": (*_ANGLE, "rad"),
        "stop_restitution": (0.0, 1.0, ""),
        "stop_rest_rate": (1.0e-15, 1.0e3, "rad/s"),
    },
    "HarmonicTorque": {
        "amplitude": (*_TORQUE, "N·m"),
        "frequency_hz": (0.0, MAX_ROTATION_HZ, "Hz"),
        "phase_rad": (*_ANGLE, "rad"),
    },
    "ImpactTorque": {
        "t_start": (*_TIME, "s"),
        "duration": (1.0e-9, 1.0e7, "s"),
        "impulse": (-1.0e4, 1.0e4, "N·m·s"),
    },
    "RateGyroParams": {
        "natural_frequency_hz": (0.0, 1.0e5, "Hz"),
        "damping_ratio": (0.0, 100.0, ""),
        "cross_coupling": (-1.0, 1.0, ""),
        "gimbal_gain_s": (0.0, 1.0e3, "s"),
        "mass_unbalance": (-1.0, 1.0, "kg·m"),
        "spin_momentum": (0.0, 1.0e4, "N·m·s"),
    },
    "IntegratingGyroParams": {
        "time_constant_s": (0.0, 1.0e4, "s"),
        "gimbal_gain": (0.0, 1.0e6, ""),
        "cross_coupling": (-1.0, 1.0, ""),
        "mass_unbalance": (-1.0, 1.0, "kg·m"),
        "spin_momentum": (0.0, 1.0e4, "N·m·s"),
    },
}
