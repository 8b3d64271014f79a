"""Node parameter files and parameter checking (no node processes)."""

import math
from pathlib import Path

import pytest
import yaml

from gyro_attitude.ros import gyro_sim_node
from gyro_attitude.ros.params import ParamSpec, check_value

REPO = Path(__file__).resolve().parents[2]


def _integrator_specs():
    from gyro_attitude.ros import attitude_integrator_node

    return attitude_integrator_node.parameter_specs()


def _recorder_specs():
    from gyro_attitude.ros import mcap_recorder_node

    return mcap_recorder_node.parameter_specs()


def _player_specs():
    from gyro_attitude.ros import mcap_player_node

    return mcap_player_node.parameter_specs()


@pytest.mark.parametrize(
    "node_name, specs_fn",
    [("gyro_sim", gyro_sim_node.parameter_specs), ("attitude_integrator", _integrator_specs),
     ("mcap_recorder", _recorder_specs), ("mcap_player", _player_specs)],
)
def test_parameter_file_declares_every_parameter_with_valid_values(node_name, specs_fn):
    data = yaml.safe_load((REPO / "config" / f"{node_name}.yaml").read_text())
    params = data[node_name]["ros__parameters"]
    specs = {s.name: s for s in specs_fn()}
    assert set(params) == set(specs)
    for name, value in params.items():
        assert check_value(specs[name], value) is None, (name, value)
        default = specs[name].default
        if isinstance(default, tuple):
            default = list(default)
        assert specs[name].description, name
        assert value == default, f"{node_name}.yaml {name} differs from the node default"


def test_check_value_names_the_parameter_and_the_problem():
    rate = ParamSpec("rate_hz", 1.0, "rate", low=0.0, high=10.0)
    assert check_value(rate, 5) is None  # an int for a float parameter is fine
    assert "'rate_hz' must be <= 10.0" in check_value(rate, 11.0)
    assert "'rate_hz' must be >= 0.0" in check_value(rate, -1.0)
    assert "'rate_hz' must be finite" in check_value(rate, math.nan)
    assert "'rate_hz' must be a number" in check_value(rate, "fast")
    assert "'rate_hz' must be a number" in check_value(rate, True)
    mode = ParamSpec("time_mode", "realtime", "mode", choices=("realtime", "fast"))
    assert "'time_mode' must be one of" in check_value(mode, "slow")
    depth = ParamSpec("qos_depth", 10, "depth", low=1, high=100)
    assert "'qos_depth' must be an integer" in check_value(depth, 2.5)
    q = ParamSpec("initial_attitude", (0.0, 0.0, 0.0, 1.0), "q", length=4)
    assert check_value(q, [0, 0, 0, 1]) is None
    assert "4 elements" in check_value(q, [0.0, 1.0])
    assert "finite" in check_value(q, [0.0, 0.0, math.inf, 1.0])
    topics = ParamSpec("topics", ("imu/data_raw",), "topics")
    assert check_value(topics, ["a", "b"]) is None
    assert "array of strings" in check_value(topics, 5)
    assert "array of strings" in check_value(topics, "imu/data_raw")
    assert "array of strings" in check_value(topics, [1.0, 2.0])


def test_local_enu_position_against_arc_lengths():
    import numpy as np

    from gyro_attitude.core.earth import radii_of_curvature

    lat0 = math.radians(45.0)
    llh0 = np.array([lat0, 0.1, 100.0])
    r_m, r_n = radii_of_curvature(lat0)
    # 1e-5 rad north, 2e-5 rad east, 3 m up: meridian and parallel arc lengths
    llh = np.array([[lat0 + 1e-5, 0.1 + 2e-5, 103.0]])
    enu = gyro_sim_node.local_enu_position(llh, llh0)
    np.testing.assert_allclose(
        enu[0], [2e-5 * (r_n + 100.0) * math.cos(lat0), 1e-5 * (r_m + 100.0), 3.0], rtol=1e-9
    )


def test_descriptors_carry_ranges_and_descriptions(ros_domain_id):
    """What `ros2 param describe` shows: description, numeric range, allowed strings."""
    import rclpy
    from rclpy.context import Context

    from gyro_attitude.ros.attitude_integrator_node import AttitudeIntegratorNode

    context = Context()
    rclpy.init(context=context, domain_id=ros_domain_id)
    try:
        sim = gyro_sim_node.GyroSimNode(context=context)
        integ = AttitudeIntegratorNode(context=context)
        rate = sim.describe_parameter("rate_hz")
        assert rate.description and rate.floating_point_range[0].to_value == 100000.0
        assert sim.describe_parameter("qos_depth").integer_range[0].from_value == 1
        assert "realtime, fast" in sim.describe_parameter("time_mode").additional_constraints
        gap = integ.describe_parameter("max_gap_s")
        assert gap.floating_point_range[0].from_value > 0
        assert "fixed after start" in integ.describe_parameter("frame").additional_constraints
        assert "fixed after start" not in integ.describe_parameter(
            "algorithm").additional_constraints
        sim.close()
        sim.destroy_node()
        integ.destroy_node()
    finally:
        rclpy.shutdown(context=context)


@pytest.mark.parametrize("scene", ["coning", "handheld_mems"])
def test_gyro_sim_publishes_the_imu_rclpy_would_serialize(ros_domain_id, scene):
    """gyro_sim serializes a block's Imu messages at once (io/cdr_arrays): each equals
    rclpy's serialization of convert.imu_msg for its row (noise covariances, accelerometer
    or its absence), bytes outside the alignment padding included."""
    import numpy as np
    import rclpy
    from rclpy.context import Context
    from rclpy.parameter import Parameter
    from rclpy.serialization import deserialize_message, serialize_message
    from sensor_msgs.msg import Imu

    from gyro_attitude.ros import convert

    context = Context()
    rclpy.init(context=context, domain_id=ros_domain_id)
    try:
        sim = gyro_sim_node.GyroSimNode(
            context=context, parameter_overrides=[Parameter("scene", value=scene)])
        sim._start_ns = 1_763_700_000_123_456_789
        sim._next_block()
        f = sim._block_fields
        gyro_var, accel_var = sim._sim.imu_variances()
        for k in (0, 1, len(sim._block) - 1):
            sf = None if f.specific_force is None else f.specific_force[k]
            ref = serialize_message(convert.imu_msg(
                sim._start_ns + int(f.t_rel_ns[k]), sim._frame_id, f.angular_velocity[k], sf,
                gyro_var, accel_var))
            raw = sim._imu_raw[k]
            assert deserialize_message(raw, Imu) == deserialize_message(ref, Imu)
            head = 16 + len(sim._frame_id.encode()) + 1
            body = len(ref) - 37 * 8
            assert len(raw) == len(ref) and raw[:head] == ref[:head]
            assert raw[body:] == ref[body:]
        assert (f.specific_force is None) == (scene == "coning")
        assert scene == "coning" or np.any(np.asarray(gyro_var) > 0)
        sim.close()
        sim.destroy_node()
    finally:
        rclpy.shutdown(context=context)
