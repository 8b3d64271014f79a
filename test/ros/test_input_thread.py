"""ros/input_thread.py: input subscriptions taken on a thread of their own.

In-process (own context, the test's ROS_DOMAIN_ID, loopback): the thread must deliver every
message in order while the executor spinning the same node never sees them, wake at once to
stop, hand its QoS events to their callbacks (the executor no longer waits on them), and let a
handler's exception end the spin with that exception.
"""

from __future__ import annotations

import threading
import time
from types import SimpleNamespace

import pytest

pytest.importorskip("rclpy")

from geometry_msgs.msg import QuaternionStamped
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.qos import QoSProfile, ReliabilityPolicy

from gyro_attitude.ros.input_thread import InputThread, spin_with_inputs

RELIABLE = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)


def _message(i: int) -> QuaternionStamped:
    m = QuaternionStamped()
    m.header.stamp.sec = i
    m.quaternion.w = 1.0
    return m


def _publish_when_matched(node, pub, count: int) -> None:
    assert node.spin_until(lambda: pub.get_subscription_count() >= 1, 30.0)
    for i in range(count):
        pub.publish(_message(i))


def test_thread_takes_every_message_in_order_and_the_executor_none(ros_node):
    seen, by_executor = [], []
    inputs = InputThread(ros_node.context, threading.Lock(), wait_s=1.0)
    sub = ros_node.create_subscription(QuaternionStamped, "inputs_order",
                                       lambda m: by_executor.append(m), RELIABLE,
                                       callback_group=inputs.group)
    inputs.add(sub, lambda m: seen.append(m.header.stamp.sec))
    pub = ros_node.create_publisher(QuaternionStamped, "inputs_order", RELIABLE)
    inputs.start()
    try:
        _publish_when_matched(ros_node, pub, 500)
        # the executor spins the node all along: it must not take a single message
        assert ros_node.spin_until(lambda: len(seen) >= 500, 30.0), len(seen)
        ros_node.spin_until(lambda: False, 0.2)
    finally:
        assert inputs.stop()
    assert seen == list(range(500))
    assert by_executor == []
    assert inputs.failure is None


def test_stop_wakes_a_waiting_thread_at_once(ros_node):
    inputs = InputThread(ros_node.context, threading.Lock(), wait_s=30.0)
    sub = ros_node.create_subscription(QuaternionStamped, "inputs_idle", lambda m: None,
                                       RELIABLE, callback_group=inputs.group)
    inputs.add(sub, lambda m: None)
    inputs.start()
    time.sleep(0.3)  # in its 30-s wait by now
    t0 = time.monotonic()
    assert inputs.stop(timeout_s=5.0)
    assert time.monotonic() - t0 < 2.0
    assert not inputs.running


def test_qos_events_of_its_subscriptions_reach_their_callbacks(ros_node):
    """An incompatible publisher (best effort offered, reliable requested): the event is the
    thread's to take, the executor does not wait on it."""
    events = []
    inputs = InputThread(ros_node.context, threading.Lock(), wait_s=1.0)
    sub = ros_node.create_subscription(
        QuaternionStamped, "inputs_qos", lambda m: None, RELIABLE,
        callback_group=inputs.group,
        event_callbacks=SubscriptionEventCallbacks(incompatible_qos=events.append))
    inputs.add(sub, lambda m: None)
    inputs.start()
    try:
        ros_node.create_publisher(QuaternionStamped, "inputs_qos",
                                  QoSProfile(depth=10,
                                             reliability=ReliabilityPolicy.BEST_EFFORT))
        assert ros_node.spin_until(lambda: bool(events), 30.0)
    finally:
        assert inputs.stop()
    assert events[0].total_count >= 1


def test_a_failing_handler_ends_the_spin_with_its_exception(ros_node):
    inputs = InputThread(ros_node.context, threading.Lock(), wait_s=1.0)
    sub = ros_node.create_subscription(QuaternionStamped, "inputs_fail", lambda m: None,
                                       RELIABLE, callback_group=inputs.group)

    def handler(m):
        if m.header.stamp.sec == 3:
            raise ZeroDivisionError("handler failed on message 3")

    inputs.add(sub, handler)
    pub = ros_node.create_publisher(QuaternionStamped, "inputs_fail", RELIABLE)
    assert ros_node.spin_until(lambda: pub.get_subscription_count() >= 1, 30.0)
    for i in range(10):
        pub.publish(_message(i))
    owner = SimpleNamespace(inputs=inputs, context=ros_node.context)
    with pytest.raises(ZeroDivisionError, match="message 3"):
        spin_with_inputs(owner, ros_node.executor_)
    assert not inputs.running


def test_the_integrator_takes_its_inputs_however_it_is_spun(ros_node):
    """Spun by a plain rclpy executor (not run_node's spin): the node's own thread takes the
    Imu messages; destroy_node stops and joins it."""
    from sensor_msgs.msg import Imu

    from gyro_attitude.ros.attitude_integrator_node import AttitudeIntegratorNode

    node = AttitudeIntegratorNode(context=ros_node.context, namespace=ros_node.get_namespace())
    ros_node.executor_.add_node(node)  # the test's executor spins both nodes
    try:
        assert node.inputs is not None and node.inputs.running
        pub = ros_node.create_publisher(Imu, "imu/data_raw", RELIABLE)
        assert ros_node.spin_until(lambda: pub.get_subscription_count() >= 1, 30.0)
        for k in range(1, 201):
            m = Imu()
            m.header.stamp.sec, m.header.stamp.nanosec = 1, k * 5_000_000
            m.header.frame_id = "imu"
            m.linear_acceleration.z = 9.81
            pub.publish(m)
        assert ros_node.spin_until(lambda: node._stream.accepted >= 200, 30.0), \
            node._stream.accepted
    finally:
        ros_node.executor_.remove_node(node)
        node.destroy_node()
    assert not node.inputs.running
