"""The one ``main()`` life cycle every gyro_attitude node shares (demo_nodes_py style).

init → build the node → ``gc.freeze()`` → spin → on SIGINT/SIGTERM exit 0 without a
traceback; an invalid parameter (:class:`~gyro_attitude.ros.params.ParameterError`) prints
one line naming it and exits 2; the node's own ``finish`` runs before it is destroyed.
"""

from __future__ import annotations

import gc
import sys
from collections.abc import Callable

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node

from gyro_attitude.ros.params import ParameterError

__all__ = ["run_node"]


def run_node(name: str, make_node: Callable[[], Node], args=None, *,
             spin: Callable[[Node], None] = rclpy.spin,
             finish: Callable[[Node], None] | None = None) -> int:
    """Run a node until it is done or signalled; returns the process exit status."""
    node = None
    status = 0
    try:
        rclpy.init(args=args)
        node = make_node()
        # Move everything allocated at start-up (modules, message classes, numpy) out of the
        # collector's reach: a full gen-2 collection then scans only recent objects instead
        # of ~10^5, which keeps its pauses (latency spikes at 1 kHz) well below a millisecond.
        gc.freeze()
        spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except ParameterError as exc:
        print(f"[{name}] invalid parameter: {exc}", file=sys.stderr, flush=True)
        status = 2
    finally:
        if node is not None:
            try:
                if finish is not None:
                    finish(node)
            finally:
                node.destroy_node()
        rclpy.try_shutdown()
    return status
