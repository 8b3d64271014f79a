"""Every scene value is bounded at validation (with the key's path); a run over a pole says when and why."""

import math

import numpy as np
import pytest
import yaml

from gyro_attitude.cli import main as cli_main
from gyro_attitude.core import earth
from gyro_attitude.core.gyro.free_gyro import FreeGyroParams, HarmonicTorque, ImpactTorque
from gyro_attitude.core.gyro.rate_gyro import IntegratingGyroParams, RateGyroParams
from gyro_attitude.core.limits import (
    ACCEL_ERROR_LIMITS,
    GYRO_ERROR_LIMITS,
    PARAM_LIMITS,
)
from gyro_attitude.core.scene import SceneSimulator, SceneSpec
from gyro_attitude.core.scene.fields import Kind
from gyro_attitude.core.scene.registry import INSTRUMENTS, MOTIONS
from gyro_attitude.core.scene.schema import (
    _ACCEL_DATASHEET_KEYS,
    _ACCEL_ERROR_KEYS,
    _GYRO_DATASHEET_KEYS,
    _GYRO_ERROR_KEYS,
)

FREE = {"spin_inertia": 1e-4, "transverse_inertia": 6e-5, "spin_rate": 2000.0}
RATE = {"natural_frequency_hz": 30.0, "damping_ratio": 0.6}


def scene(**overrides):
    d = {"description": "bounds", "seed": 1, "earth": {"latitude_deg": 45.0},
         "motion": {"type": "stationary"}}
    d.update(overrides)
    return d


def ship(**osc):
    return scene(motion={"type": "ship", "speed_mps": 5.0, **osc})


def profile(*segments, **extra):
    return scene(motion={"type": "profile", "segments": list(segments), **extra})


ABSURD = [
    # the case: a roll period of 1e-300 s once wrote a file of implausible rates
    (ship(roll={"amplitude_deg": 5.0, "period_s": 1e-300}), r"^motion\.roll\.period_s: must be >= 0\.001"),
    (ship(roll={"amplitude_deg": 5.0, "period_s": 1e300}), r"^motion\.roll\.period_s: must be <= 86400"),
    (ship(pitch={"amplitude_deg": 1e300, "period_s": 7.0}), r"^motion\.pitch\.amplitude_deg: must be <= 90"),
    (ship(yaw_oscillation={"amplitude_deg": 5.0, "period_s": 7.0, "phase_deg": 1e300}),
     r"^motion\.yaw_oscillation\.phase_deg: must be <= 360"),
    (ship(heave={"amplitude_m": 1e300, "period_s": 7.0}), r"^motion\.heave\.amplitude_m: must be <= 100"),
    (ship(heave={"amplitude_m": 50.0, "period_s": 0.01}), r"^motion\.heave\.period_s: .*peak acceleration"),
    # 1e300 m/s was refused by a confusing latitude message from the simulator
    (scene(motion={"type": "constant_velocity", "speed_mps": 1e300}),
     r"^motion\.speed_mps: must be <= 12000"),
    (scene(motion={"type": "coordinated_turn", "speed_mps": 1e300, "turn_rate_deg_s": 3.0}),
     r"^motion\.speed_mps: must be <= 12000"),
    (scene(motion={"type": "spinning_projectile", "spin_rate_hz": 50.0, "half_angle_deg": 2.0,
                   "coning_frequency_hz": 5.0, "speed_mps": 1e300}), r"^motion\.speed_mps: must be <="),
    (scene(motion={"type": "coning", "half_angle_deg": 2.0, "frequency_hz": 1e300}),
     r"^motion\.frequency_hz: must be <= 10000"),
    (scene(motion={"type": "spinning_projectile", "spin_rate_hz": -1e300, "half_angle_deg": 2.0,
                   "coning_frequency_hz": 5.0}), r"^motion\.spin_rate_hz: must be >= -10000"),
    (profile({"duration_s": 1e300}), r"^motion\.segments\[0\]\.duration_s: must be <= 1e\+07"),
    (profile({"duration_s": 1.0, "angular_rate_deg_s": [0.0, 1e300, 0.0]}),
     r"^motion\.segments\[0\]\.angular_rate_deg_s: each value must lie in"),
    (profile({"duration_s": 1.0, "acceleration_enu_mps2": [1e300, 0.0, 0.0]}),
     r"^motion\.segments\[0\]\.acceleration_enu_mps2: each value must lie in"),
    (profile({"duration_s": 1.0}, velocity_enu_mps=[0.0, 1e300, 0.0]),
     r"^motion\.velocity_enu_mps: each value must lie in"),
    # each acceleration is plausible, the speed it builds up is not
    (profile({"duration_s": 10.0}, {"duration_s": 1000.0, "acceleration_enu_mps2": [0.0, 20.0, 0.0]}),
     r"^motion\.segments\[1\]: the speed reaches 2e\+04 m/s .*t = 1010 s"),
    (profile(*[{"duration_s": 9e6}] * 2), r"^motion\.segments\[1\]\.duration_s: the segments last more"),
    (scene(gyro={"errors": {"bias_rad_s": 1e300}}), r"^gyro\.errors\.bias_rad_s: must lie in \[-1, 1\]"),
    (scene(gyro={"errors": {"arw_rad_sqrt_s": [0.0, 1e300, 0.0]}}),
     r"^gyro\.errors\.arw_rad_sqrt_s: must lie in"),
    (scene(gyro={"errors": {"arw": "1e300 deg/sqrt(h)"}}), r"^gyro\.errors\.arw: must lie in"),
    (scene(gyro={"errors": {"bias_instability_tau_s": 1e300}}),
     r"^gyro\.errors\.bias_instability_tau_s: must lie in"),
    (scene(accelerometer={"errors": {"bias_m_s2": -1e300}}),
     r"^accelerometer\.errors\.bias_m_s2: must lie in"),
    (scene(accelerometer={"errors": {"acceleration_random_walk": 1e300}}),
     r"^accelerometer\.errors\.acceleration_random_walk: must lie in"),
    (scene(free_gyro={**FREE, "spin_rate": 1e300}), r"^free_gyro\.spin_rate: must lie in"),
    (scene(free_gyro={**FREE, "constant_torque": [0.0, 1e300]}), r"^free_gyro\.constant_torque: must lie in"),
    (scene(free_gyro={**FREE, "harmonic_torques": [{"amplitude": [0.0, 1e-6], "frequency_hz": 1e300}]}),
     r"^free_gyro\.harmonic_torques\[0\]\.frequency_hz: must lie in"),
    (scene(free_gyro={**FREE, "impacts": [{"t_start": 1e300, "duration": 0.01, "impulse": [0.0, 1e-6]}]}),
     r"^free_gyro\.impacts\[0\]\.t_start: must lie in"),
    (scene(gyro={"model": "rate_gyro", "rate_gyro": {**RATE, "natural_frequency_hz": 1e300}}),
     r"^gyro\.rate_gyro\.natural_frequency_hz: must lie in"),
    (scene(gyro={"model": "integrating_gyro", "integrating_gyro": {"time_constant_s": 1e300}}),
     r"^gyro\.integrating_gyro\.time_constant_s: must lie in"),
    (scene(instrument={"type": "gyrocompass", "angular_momentum": 1e300, "schuler_tuned": True}),
     r"^instrument\.angular_momentum: must be <= 10000"),
    (scene(instrument={"type": "spinning_shell", "spin_inertia": 1e300, "transverse_inertia": 1.0,
                       "spin_rate": 100.0, "stability_factor": 1.5}),
     r"^instrument\.spin_inertia: must be <="),
    (scene(seed=2**70), r"^seed: must be <= "),
    (scene(description="x" * 20_000), r"^description: at most 10000 characters"),
]


@pytest.mark.parametrize("d, message", ABSURD)
def test_absurd_value_is_refused_at_validation_naming_the_key(d, message):
    with pytest.raises(ValueError, match=message):
        SceneSpec.from_dict(d)


def test_values_at_the_plausible_extremes_still_pass():
    """The limits leave real cases alone: a rifle bullet's spin, a re-entry speed, a 1 kHz
    vibration, a large ship's roll."""
    SceneSpec.from_dict(scene(motion={"type": "spinning_projectile", "spin_rate_hz": 5000.0,
                                      "half_angle_deg": 1.0, "coning_frequency_hz": 50.0,
                                      "speed_mps": 7800.0}))
    SceneSpec.from_dict(ship(roll={"amplitude_deg": 40.0, "period_s": 25.0},
                             heave={"amplitude_m": 15.0, "period_s": 12.0}))
    SceneSpec.from_dict(ship(pitch={"amplitude_deg": 0.01, "period_s": 0.001}))
    SceneSpec.from_dict(scene(gyro={"errors": {"bias_rad_s": 0.1, "arw": "3 deg/sqrt(h)"}}))


def test_every_declared_number_has_both_bounds():
    """A new motion or instrument key cannot be added unbounded."""
    def walk(fields, where):
        for fl in fields:
            if fl.kind in (Kind.NUMBER, Kind.INTEGER, Kind.VECTOR3):
                assert fl.lo is not None and fl.hi is not None, f"{where}.{fl.key} is unbounded"
            walk(fl.fields, f"{where}.{fl.key}")

    for name, kind in MOTIONS.items():
        walk(kind.fields, f"motion[{name}]")
    for name, kind in INSTRUMENTS.items():
        walk(kind.fields, f"instrument[{name}]")
    assert set(GYRO_ERROR_LIMITS) == set(_GYRO_ERROR_KEYS) | set(_GYRO_DATASHEET_KEYS)
    assert set(ACCEL_ERROR_LIMITS) == set(_ACCEL_ERROR_KEYS) | set(_ACCEL_DATASHEET_KEYS)
    import dataclasses
    for cls in (FreeGyroParams, HarmonicTorque, ImpactTorque, RateGyroParams, IntegratingGyroParams):
        numeric = {f.name for f in dataclasses.fields(cls)
                   if f.name not in ("model", "integrator", "hold", "output_axis_acceleration",
                                     "harmonic_torques", "impacts")}
        missing = numeric - set(PARAM_LIMITS[cls.__name__])
        assert not missing, (cls.__name__, missing)


def _meridian_arc(lat_a, lat_b, n=20001):
    """Distance along the meridian (m), by the trapezoid rule on R_M (independent of the
    simulator's Simpson/Picard integration)."""
    lat = np.linspace(lat_a, lat_b, n)
    r_m, _ = earth.radii_of_curvature(lat)
    return float(np.sum(0.5 * (r_m[1:] + r_m[:-1]) * np.diff(lat)))


def test_crossing_a_pole_says_when_and_why():
    lat0 = 89.9
    speed = 100.0
    d = scene(earth={"latitude_deg": lat0},
              motion={"type": "constant_velocity", "speed_mps": speed,
                      "attitude": {"yaw_deg": 90.0}})  # nose North
    sim = SceneSimulator(SceneSpec.from_dict(d), 100.0)
    t_pole = _meridian_arc(math.radians(lat0), math.pi / 2) / speed  # ≈ 111.7 s
    with pytest.raises(ValueError, match=r"^position: the carrier reaches the North pole at "
                                         r"t ≈ ([\d.]+) s .*no East or North") as exc:
        for _ in range(20):
            sim.next_block(4096)
    said = float(exc.value.args[0].split("t ≈ ")[1].split(" s")[0])
    assert said == pytest.approx(t_pole, rel=1e-3)


def test_simulate_over_the_south_pole_is_one_line_and_exit_1(tmp_path, capsys):
    d = scene(earth={"latitude_deg": -89.95},
              motion={"type": "constant_velocity", "speed_mps": 50.0,
                      "attitude": {"yaw_deg": -90.0}})  # nose South
    path = tmp_path / "south.yaml"
    path.write_text(yaml.safe_dump(d))
    out = tmp_path / "o.mcap"
    assert cli_main(["simulate", str(path), "--duration", "300", "--out", str(out),
                     "--quiet"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "South pole at t ≈" in err[0] and "Traceback" not in err[0]
    assert not out.exists()
