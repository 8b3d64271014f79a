"""Scene schema: every bad value is refused with the key's path; sizes that drive allocation are bounded."""

import copy

import numpy as np
import pytest

from gyro_attitude.core.scene import MAX_LIST_ITEMS, MAX_RATE_HZ, SceneSpec


def scene(**overrides):
    d = {
        "description": "test scene",
        "seed": 7,
        "earth": {"latitude_deg": 45.0},
        "motion": {"type": "stationary"},
    }
    d.update(overrides)
    return d


def _with(path, value):
    d = copy.deepcopy(scene(gyro={"errors": {}}, accelerometer={}))
    node = d
    keys = path.split(".")
    for k in keys[:-1]:
        node = node.setdefault(k, {})
    if value is DELETE:
        del node[keys[-1]]
    else:
        node[keys[-1]] = value
    return d


DELETE = object()


@pytest.mark.parametrize(
    "path, value, message",
    [
        ("earth.latitude_deg", 91.0, r"^earth\.latitude_deg: must be <= 90"),
        ("earth.latitude_deg", -90.5, r"^earth\.latitude_deg: must be >= -90"),
        ("earth.latitude_deg", DELETE, r"^earth\.latitude_deg: required value is missing"),
        ("earth.latitude_deg", "north", r"^earth\.latitude_deg: must be a number"),
        ("earth.latitude", 45.0, r"^earth\.latitude: unknown key"),
        ("earth.rotation", "yes", r"^earth\.rotation: must be true or false"),
        ("seed", DELETE, r"^seed: required value is missing"),
        ("seed", -1, r"^seed: must be >= 0"),
        ("description", DELETE, r"^description: required"),
        ("colour", "red", r"^colour: unknown key"),
        ("rate_hz", -100.0, r"^rate_hz: must be > 0"),
        ("motion.type", "teleport", r"^motion\.type: must be one of"),
        ("motion.speed_mps", 3.0, r"^motion\.speed_mps: unknown key"),  # not for stationary
        ("motion.attitude", {"yaw": 3.0}, r"^motion\.attitude\.yaw: unknown key"),
        ("gyro.model", "laser", r"^gyro\.model: must be one of"),
        ("gyro.errors.arw_rad_sqrt_s", -1e-3, r"^gyro\.errors\.arw_rad_sqrt_s: must be >= 0"),
        ("gyro.errors.bias_rad_s", [1.0, 2.0], r"^gyro\.errors\.bias_rad_s: must have shape"),
        ("gyro.errors.misalignment_rad", np.eye(3).tolist(),
         r"^gyro\.errors\.misalignment_rad: diagonal must be zero"),
        ("gyro.errors.bias_instability_tau_s", 0.0,
         r"^gyro\.errors\.bias_instability_tau_s: must be > 0"),
        ("gyro.errors.arw_deg_sqrt_h", 1.0, r"^gyro\.errors\.arw_deg_sqrt_h: unknown key"),
        ("accelerometer.errors.quantization_rad", 1.0,
         r"^accelerometer\.errors\.quantization_rad: unknown key"),
        ("gyro.rate_gyro", {"natural_frequency_hz": 10.0},
         r"^gyro\.rate_gyro: given but gyro\.model is 'ideal'"),
        ("earth", DELETE, r"^earth: required section is missing"),
    ],
)
def test_bad_scene_is_refused_naming_the_key(path, value, message):
    with pytest.raises(ValueError, match=message):
        SceneSpec.from_dict(_with(path, value))


def test_bad_profile_and_motion_values_are_refused_naming_the_key():
    bad_segment = scene(motion={"type": "profile", "segments": [{"duration_s": 1.0}, {}]})
    with pytest.raises(ValueError, match=r"^motion\.segments\[1\]\.duration_s: required"):
        SceneSpec.from_dict(bad_segment)
    neg = scene(motion={"type": "profile", "segments": [{"duration_s": -1.0}]})
    with pytest.raises(ValueError, match=r"^motion\.segments\[0\]\.duration_s: must be > 0"):
        SceneSpec.from_dict(neg)
    speed = scene(motion={"type": "constant_velocity", "speed_mps": -5.0})
    with pytest.raises(ValueError, match=r"^motion\.speed_mps: must be >= 0"):
        SceneSpec.from_dict(speed)
    ship = scene(motion={"type": "ship", "roll": {"amplitude_deg": 3.0, "period_s": 0.0}})
    with pytest.raises(ValueError, match=r"^motion\.roll\.period_s: must be >= 0\.001"):
        SceneSpec.from_dict(ship)
    with pytest.raises(ValueError, match=r"^motion: must be a mapping"):
        SceneSpec.from_dict(scene(motion="stationary"))


def test_bad_instrument_parameters_are_refused_naming_the_key():
    d = scene(gyro={"model": "rate_gyro", "rate_gyro": {"natural_frequency_hz": 10.0,
                                                        "damping_ratio": 0.5, "wobble": 1}})
    with pytest.raises(ValueError, match=r"^gyro\.rate_gyro\.wobble: unknown key"):
        SceneSpec.from_dict(d)
    d = scene(free_gyro={"spin_inertia": 1e-4, "transverse_inertia": 6e-5, "spin_rate": 0.0})
    with pytest.raises(ValueError, match=r"^free_gyro: .*spin_rate"):
        SceneSpec.from_dict(d)
    d = scene(free_gyro={"spin_inertia": 1e-4, "transverse_inertia": 6e-5, "spin_rate": 10.0,
                         "impacts": [{"t_start": 1.0}]})
    with pytest.raises(ValueError, match=r"^free_gyro\.impacts\[0\]"):
        SceneSpec.from_dict(d)


def test_empty_accelerometer_entry_asks_for_accelerometers_and_top_level_must_be_mapping():
    d = scene()
    d["accelerometer"] = None  # `accelerometer:` with nothing after it in YAML
    spec = SceneSpec.from_dict(d)
    assert spec.accelerometer and spec.gravity
    with pytest.raises(ValueError, match=r"^scene: must be a mapping"):
        SceneSpec.from_dict(["not", "a", "scene"])


# --------------------------------------------------------------------------- bounded sizes
@pytest.mark.parametrize(
    "path, value, message",
    [
        # 1e12 Hz once passed and then died allocating a 373 GiB block in the simulator node
        ("rate_hz", 1.0e12, r"^rate_hz: must be <= 1e\+06, got 1e\+12"),
        ("rate_hz", MAX_RATE_HZ * (1 + 1e-12), r"^rate_hz: must be <= 1e\+06"),
        ("rate_hz", 1e300, r"^rate_hz: must be <= 1e\+06"),
        ("rate_hz", float("inf"), r"^rate_hz: must be finite"),
        ("rate_hz", float("nan"), r"^rate_hz: must be finite"),
        ("rate_hz", True, r"^rate_hz: must be a number"),
        ("duration_s", 1e8, r"^duration_s: must be <= 1e\+07"),
        ("start_time_ns", 2**63, r"^start_time_ns: must be <= 4611686018427387904"),
        ("start_time_ns", 1.5, r"^start_time_ns: must be an integer"),
    ],
)
def test_sizes_that_drive_allocation_are_refused_naming_the_key(path, value, message):
    with pytest.raises(ValueError, match=message):
        SceneSpec.from_dict(scene(**{path: value}))


def test_largest_rate_is_accepted():
    assert SceneSpec.from_dict(scene(rate_hz=MAX_RATE_HZ)).rate_hz == MAX_RATE_HZ


@pytest.mark.parametrize("key", ["frequency_hz"])
def test_motion_frequencies_are_bounded(key):
    d = scene(motion={"type": "coning", "half_angle_deg": 1.0, key: 1e300})
    with pytest.raises(ValueError, match=rf"^motion\.{key}: must be <= 10000"):
        SceneSpec.from_dict(d)


def test_too_many_segments_are_refused_before_they_are_built():
    segs = [{"duration_s": 1.0}] * (MAX_LIST_ITEMS + 1)
    d = scene(motion={"type": "profile", "segments": segs})
    with pytest.raises(ValueError, match=rf"^motion\.segments: at most {MAX_LIST_ITEMS} entries"):
        SceneSpec.from_dict(d)


def test_array_bomb_is_refused_by_shape_without_expanding_it():
    # What a YAML alias bomb loads as: each level repeats the one below 9 times, shared, so
    # the mapping is small but np.asarray would build 9**9 = 387 M floats (3 GB).
    level = [1.0] * 9
    for _ in range(8):
        level = [level] * 9
    d = scene(gyro={"errors": {"bias_rad_s": level}})
    with pytest.raises(ValueError, match=r"^gyro\.errors\.bias_rad_s: must have shape \(3,\), "
                                         r"got a list of 9"):
        SceneSpec.from_dict(d)
    d = scene(gyro={"errors": {"misalignment_rad": [[0, 1, 2], [3, 0, "x"], [4, 5, 0]]}})
    with pytest.raises(ValueError, match=r"^gyro\.errors\.misalignment_rad: must be numbers"):
        SceneSpec.from_dict(d)
    d = scene(gyro={"errors": {"bias_rad_s": [1.0, True, 2.0]}})
    with pytest.raises(ValueError, match=r"^gyro\.errors\.bias_rad_s: must be numbers"):
        SceneSpec.from_dict(d)


def test_a_single_torque_mapping_counts_as_one_item():
    d = scene(free_gyro={"spin_inertia": 1e-4, "transverse_inertia": 6e-5, "spin_rate": 10.0,
                         "harmonic_torques": {"amplitude": [0.0, 1e-6], "frequency_hz": 2.0}})
    spec = SceneSpec.from_dict(d)
    assert len(spec.free_gyro_params.harmonic_torques) == 1
    assert spec.free_gyro_params.harmonic_torques[0].frequency_hz == 2.0
