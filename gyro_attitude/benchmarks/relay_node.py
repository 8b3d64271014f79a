"""The floor of ``bench --suite nodes``: a node that does nothing but the integrator's I/O.

It takes ``imu/data_raw`` serialized on an :class:`~gyro_attitude.ros.input_thread.InputThread`
(as ``attitude_integrator`` does by default) and publishes for each message an ``attitude``
with the message's stamp and the identity quaternion, counting what it took in
``/diagnostics`` (``accepted``, as the integrator reports it). No estimation: what this relay
loses, or how late it answers, no estimator in a Python rclpy node on the same machine and
middleware can do better. Not a user-facing node (no entry point): the benchmark starts it
with ``python -m gyro_attitude.benchmarks.relay_node``.
"""

from __future__ import annotations

import sys
import threading

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import QuaternionStamped
from rclpy.node import Node
from sensor_msgs.msg import Imu

from gyro_attitude.io.cdr_arrays import QuaternionStampedCdr
from gyro_attitude.ros.input_thread import InputThread, spin_with_inputs
from gyro_attitude.ros.node_main import run_node
from gyro_attitude.ros.qos import imu_qos

NODE_NAME = "bench_relay"
_STAMP = slice(4, 12)  # CDR: 4-byte encapsulation header, then header.stamp (sec, nanosec)


class RelayNode(Node):
    def __init__(self, **kwargs):
        super().__init__(NODE_NAME, **kwargs)
        self._lock = threading.Lock()
        self.inputs = InputThread(self.context, self._lock, name=f"{NODE_NAME} inputs")
        self._taken = 0
        self._cdr = QuaternionStampedCdr("relay")
        self._pub = self.create_publisher(QuaternionStamped, "attitude", 1000)
        self._pub_diag = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        sub = self.create_subscription(Imu, "imu/data_raw", self._on_imu, imu_qos(
            "best_effort", 1000), raw=True, callback_group=self.inputs.group)
        self.inputs.add(sub, self._on_imu)
        self.create_timer(0.25, self._diagnostics)

    def _on_imu(self, raw: bytes) -> None:
        self._taken += 1
        self._pub.publish(self._cdr.encode(raw[_STAMP], 0.0, 0.0, 0.0, 1.0))

    def _diagnostics(self) -> None:
        status = DiagnosticStatus(name=f"{NODE_NAME}: imu input")
        with self._lock:
            status.values = [KeyValue(key="accepted", value=str(self._taken))]
        self._pub_diag.publish(DiagnosticArray(status=[status]))


def main(args=None) -> int:
    return run_node(NODE_NAME, RelayNode, args, spin=spin_with_inputs)


if __name__ == "__main__":
    sys.exit(main())
