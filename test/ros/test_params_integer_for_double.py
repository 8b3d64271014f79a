"""An integer given for a double parameter (``-p max_gap_s:=1``, ``ros2 param set ... 2``) is
taken as that double and the parameter stays a DOUBLE (issue 38 item 10); other types are still
refused in words.  In-process node, no graph traffic."""

import pytest

from gyro_attitude.ros.params import ParamSpec, check_update, declare_all

SPECS = [ParamSpec("max_gap_s", 0.5, "gap", low=1e-3, high=60.0, runtime=True),
         ParamSpec("qos_depth", 10, "depth", low=1, high=1000)]


@pytest.fixture
def node_with(ros_domain_id):
    import rclpy
    from rclpy.context import Context
    from rclpy.node import Node

    context = Context()
    rclpy.init(context=context, domain_id=ros_domain_id)
    nodes = []

    def make(*overrides):
        node = Node("params_probe", context=context,
                    cli_args=["--ros-args", *[a for o in overrides for a in ("-p", o)]])
        nodes.append(node)
        values = declare_all(node, SPECS)
        by_name = {s.name: s for s in SPECS}

        def on_set(params):
            from rcl_interfaces.msg import SetParametersResult
            reason = check_update(by_name, params)
            return SetParametersResult(successful=reason is None, reason=reason or "")
        node.add_on_set_parameters_callback(on_set)
        return node, values
    yield make
    for n in nodes:
        n.destroy_node()
    rclpy.shutdown(context=context)


def test_an_integer_override_of_a_double_parameter_stays_a_double(node_with):
    from rclpy.parameter import Parameter

    node, values = node_with("max_gap_s:=1", "qos_depth:=7")
    p = node.get_parameter("max_gap_s")
    assert p.type_ is Parameter.Type.DOUBLE and p.value == 1.0 and values["max_gap_s"] == 1.0
    q = node.get_parameter("qos_depth")
    assert q.type_ is Parameter.Type.INTEGER and q.value == 7


def test_an_integer_set_at_runtime_on_a_double_parameter_stays_a_double(node_with):
    from rclpy.parameter import Parameter

    node, _ = node_with()
    r = node.set_parameters([Parameter("max_gap_s", Parameter.Type.INTEGER, 2)])
    assert r[0].successful
    p = node.get_parameter("max_gap_s")
    assert p.type_ is Parameter.Type.DOUBLE and p.value == 2.0
    r = node.set_parameters([Parameter("max_gap_s", Parameter.Type.STRING, "fast")])
    assert not r[0].successful and "must be a number" in r[0].reason
    assert node.get_parameter("max_gap_s").value == 2.0
