"""Default ``AMENT_PREFIX_PATH`` to the install prefix that holds this package's ament index;
find the installed node executables (as ``ros2 run`` does) and the environment to start them in."""

from __future__ import annotations

import os
import sys
from pathlib import Path

__all__ = ["ensure_ament_prefix_path", "node_command", "node_environment"]

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


def node_command(exe: str) -> list[str]:
    """The command ``ros2 run gyro_attitude <exe>`` would run, or ``python -m`` fallback."""
    try:
        from ament_index_python.packages import PackageNotFoundError, get_package_prefix

        try:
            path = Path(get_package_prefix(PACKAGE)) / "lib" / PACKAGE / exe
            if path.is_file() and os.access(path, os.X_OK):
                return [str(path)]
        except PackageNotFoundError:
            pass
    except ImportError:
        pass
    return [sys.executable, "-m", f"{PACKAGE}.ros.{exe}_node"]


def node_environment() -> dict[str, str]:
    """The environment for node processes we start (demo, bench): loopback DDS and a domain of
    its own unless the user chose; the ament index of this interpreter's prefix when none is
    set (so `ros2 run`-style lookup finds the package)."""
    import random

    env = dict(os.environ)
    env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    env.setdefault("ROS_DOMAIN_ID", str(random.Random(os.getpid()).randint(40, 99)))
    env.setdefault("AMENT_PREFIX_PATH", sys.prefix)
    env.setdefault("PYTHONUNBUFFERED", "1")
    # a `python -m` fallback must import this very package
    here = str(Path(__file__).resolve().parents[2])
    env["PYTHONPATH"] = here + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    return env
