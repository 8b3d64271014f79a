"""The scene's magnetometer (core/scene/magnetometer.py): the WMM field against the field recorded
in Berlin (BROAD), the given field against its closed form, the sensor model, schema errors, and
the simulate output."""

import copy
import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from gyro_attitude.core.scene import SceneSimulator, SceneSpec
from gyro_attitude.core.scene.magnetometer import (
    field_from_angles,
    geomagnetic_field,
    magnetometer_covariance,
)

SCENE = {
    "description": "mag", "seed": 5, "start_time_ns": 10**9, "rate_hz": 100.0,
    "earth": {"latitude_deg": 52.5, "longitude_deg": 13.3, "height_m": 40.0},
    "motion": {"type": "profile", "attitude": {"roll_deg": 10.0, "pitch_deg": -20.0,
                                               "yaw_deg": 35.0},
               "segments": [{"duration_s": 5.0},
                            {"duration_s": 10.0, "angular_rate_deg_s": [3.0, -5.0, 20.0]}]},
    "accelerometer": {},
    "magnetometer": {"model": "given", "declination_deg": 10.0, "inclination_deg": 60.0,
                     "intensity_ut": 50.0},
}


def scene(**mag):
    d = copy.deepcopy(SCENE)
    d["magnetometer"].update(mag)
    d["magnetometer"] = {k: v for k, v in d["magnetometer"].items() if v is not None}
    return SceneSpec.from_dict(d)


def test_given_field_is_the_closed_form_of_declination_inclination_and_intensity():
    b = scene().magnetometer.field_enu
    h = 50e-6 * math.cos(math.radians(60.0))
    np.testing.assert_allclose(b, [h * math.sin(math.radians(10.0)),
                                   h * math.cos(math.radians(10.0)),
                                   -50e-6 * math.sin(math.radians(60.0))], rtol=1e-12)


def test_wmm_field_at_berlin_agrees_with_the_field_recorded_there():
    # BROAD (TU Berlin, 52.5°N 13.3°E): the field at rest seen in the truth's ENU frame
    from gyro_attitude.benchmarks.real import real_dir

    real = real_dir() / "broad_05_slow_rotation_with_breaks.mcap"
    if not real.exists():
        pytest.skip("shared/real recordings not present")
    from gyro_attitude.io.imu_fast import read_magnetic_field_arrays, read_quaternion_stamped_arrays

    m = read_magnetic_field_arrays(real, "/imu/mag").magnetic_field[:2000]
    q = read_quaternion_stamped_arrays(real, "/truth/attitude").quaternion[:2000]
    b_rec = Rotation.from_quat(q).apply(m).mean(axis=0)
    b = geomagnetic_field(math.radians(52.5), math.radians(13.3), 40.0, 2025.5)
    dip = lambda v: math.degrees(math.atan2(-v[2], math.hypot(v[0], v[1])))  # noqa: E731
    # the recording's north is magnetic north: compare what does not depend on it
    assert dip(b) == pytest.approx(dip(b_rec), abs=1.5)
    # indoors the intensity reads lower (steel in the building): within 15 %
    assert np.linalg.norm(b) == pytest.approx(np.linalg.norm(b_rec), rel=0.15)
    assert 3.0 < math.degrees(math.atan2(b[0], b[1])) < 7.0  # declination ~5° E in 2025


def test_sensor_model_is_soft_iron_of_the_rotated_field_plus_hard_iron_and_disturbance():
    soft = [[1.1, 0.05, 0.0], [0.05, 0.9, 0.02], [0.0, 0.02, 1.0]]
    spec = scene(hard_iron_ut=[10.0, -5.0, 3.0], soft_iron=soft,
                 disturbances=[{"start_s": 6.0, "duration_s": 2.0, "field_ut": [1.0, 2.0, 3.0],
                                "frame": "body"},
                               {"start_s": 9.0, "duration_s": 1.0, "field_ut": [0.0, 0.0, 20.0],
                                "frame": "enu"}])
    b = next_block = SceneSimulator(spec, 100.0).next_block(1500)
    rot = Rotation.from_quat(b.truth_q_nb)
    t = (b.t_ns - 10**9) * 1e-9
    ext = np.tile(spec.magnetometer.field_enu, (t.size, 1))
    ext[(t >= 9.0) & (t < 10.0), 2] += 20e-6
    expect = rot.apply(ext, inverse=True) @ np.array(soft).T + [10e-6, -5e-6, 3e-6]
    expect[(t >= 6.0) & (t < 8.0)] += [1e-6, 2e-6, 3e-6]
    np.testing.assert_allclose(next_block.magnetic_field_b, expect, atol=1e-15)


def test_noise_has_its_sigma_and_does_not_depend_on_the_block_split():
    spec = scene(noise_ut=0.5)
    whole = SceneSimulator(spec, 100.0).next_block(1500).magnetic_field_b
    sim = SceneSimulator(spec, 100.0)
    parts = np.concatenate([sim.next_block(n).magnetic_field_b for n in (1, 700, 799)])
    np.testing.assert_array_equal(whole, parts)
    clean = SceneSimulator(scene(), 100.0).next_block(1500).magnetic_field_b
    assert np.std(whole - clean) == pytest.approx(0.5e-6, rel=0.05)
    np.testing.assert_allclose(magnetometer_covariance(spec.magnetometer)[[0, 4, 8]],
                               0.25e-12, rtol=1e-12)


def test_adding_a_magnetometer_leaves_the_gyro_and_accelerometer_noise_of_a_seed():
    d = copy.deepcopy(SCENE)
    d["gyro"] = {"errors": {"arw_rad_sqrt_s": 1e-3}}
    d["accelerometer"] = {"errors": {"vrw_m_s_sqrt_s": 1e-2}}
    with_mag = SceneSimulator(SceneSpec.from_dict(d), 100.0).next_block(300)
    del d["magnetometer"]
    without = SceneSimulator(SceneSpec.from_dict(d), 100.0).next_block(300)
    np.testing.assert_array_equal(with_mag.omega_ib_b, without.omega_ib_b)
    np.testing.assert_array_equal(with_mag.specific_force_b, without.specific_force_b)
    assert without.magnetic_field_b is None


@pytest.mark.parametrize("change,key", [
    ({"inclination_deg": None}, "magnetometer.inclination_deg"),
    ({"model": "wmm"}, "magnetometer.declination_deg"),
    ({"model": "igrf"}, "magnetometer.model"),
    ({"soft_iron": [[1, 0, 0], [0, 0, 0], [0, 0, 1]]}, "magnetometer.soft_iron"),
    ({"soft_iron": [[1, 0], [0, 1]]}, "magnetometer.soft_iron"),
    ({"noise_ut": -1.0}, "magnetometer.noise_ut"),
    ({"intensity_ut": float("nan")}, "magnetometer.intensity_ut"),
    ({"hard_iron_ut": [1e300, 0, 0]}, "magnetometer.hard_iron_ut"),
    ({"decimal_year": 2024.0}, "magnetometer.decimal_year"),
    ({"disturbances": [{"start_s": 1.0, "duration_s": 0.0, "field_ut": [1, 2, 3]}]},
     r"magnetometer.disturbances\[0\].duration_s"),
    ({"disturbances": [{"start_s": 1.0, "duration_s": 1.0, "field_ut": [1, 2, 3],
                        "frame": "ned"}]}, r"magnetometer.disturbances\[0\].frame"),
    ({"tesla": 1}, "magnetometer.tesla"),
])
def test_bad_magnetometer_section_is_refused_naming_the_key(change, key):
    with pytest.raises(ValueError, match=key):
        scene(**change)


def test_wmm_needs_no_angles_and_refuses_a_date_outside_the_model():
    d = copy.deepcopy(SCENE)
    d["magnetometer"] = {"model": "wmm", "decimal_year": 2027.0}
    spec = SceneSpec.from_dict(d)
    assert spec.magnetometer.intensity == pytest.approx(50e-6, rel=0.05)
    d["magnetometer"]["decimal_year"] = 2030.0
    with pytest.raises(ValueError, match="decimal_year"):
        SceneSpec.from_dict(d)


def test_field_from_angles_points_down_north_at_positive_dip():
    b = field_from_angles(0.0, math.radians(90.0), 1.0)
    np.testing.assert_allclose(b, [0, 0, -1.0], atol=1e-15)
