"""Default ``AMENT_PREFIX_PATH`` to the install prefix that holds this package's ament index."""

from __future__ import annotations

import os
import sys
from pathlib import Path

__all__ = ["ensure_ament_prefix_path"]

PACKAGE = "gyro_attitude"


def ensure_ament_prefix_path(environ=None, prefix: str | None = None) -> str | None:
    """Set ``AMENT_PREFIX_PATH`` to ``prefix`` (default ``sys.prefix``) when it is unset or
    empty and the prefix holds ``share/ament_index/resource_index/packages/gyro_attitude``.

    rclpy's type support, ``ament_index_python`` and ``ros2 run``'s lookup read the variable;
    a sourced ROS set-up sets it, a plain venv does not. A value the user set is never
    changed. Returns the value set, or None when nothing was changed.
    """
    env = os.environ if environ is None else environ
    if env.get("AMENT_PREFIX_PATH", "").strip():
        return None
    root = Path(sys.prefix if prefix is None else prefix)
    if not (root / "share" / "ament_index" / "resource_index" / "packages" / PACKAGE).is_file():
        return None
    env["AMENT_PREFIX_PATH"] = str(root)
    return str(root)
