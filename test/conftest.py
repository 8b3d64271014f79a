"""Fixtures shared by every test folder (no rclpy import here: core tests never load it).

``ros_domain_id``: each test process claims its own ROS_DOMAIN_ID (an flock on a file per id
under the temp dir, so concurrent pytest runs on one machine never share a domain) and keeps
DDS on loopback (ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST); both are set in os.environ before
any rclpy.init and passed on to node processes.
"""

from __future__ import annotations

import fcntl
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

_DOMAIN_RANGE = range(40, 100)  # 0..101 are safe on Linux; leave the low ids to users
_lock_file = None


def _claim_domain_id() -> int:
    global _lock_file
    lock_dir = Path(tempfile.gettempdir()) / "gyro_attitude_ros_domains"
    lock_dir.mkdir(exist_ok=True)
    start = os.getpid() % len(_DOMAIN_RANGE)
    for i in range(len(_DOMAIN_RANGE)):
        domain = _DOMAIN_RANGE[(start + i) % len(_DOMAIN_RANGE)]
        f = open(lock_dir / f"{domain}.lock", "w")  # held for the session
        try:
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            f.close()
            continue
        _lock_file = f  # keep the lock until this process exits
        return domain
    raise RuntimeError("no free ROS_DOMAIN_ID for the test process")


@pytest.fixture(scope="session")
def ros_domain_id() -> int:
    domain = _claim_domain_id()
    os.environ["ROS_DOMAIN_ID"] = str(domain)
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    os.environ.setdefault("AMENT_PREFIX_PATH", sys.prefix)
    return domain


@pytest.fixture
def small_disk(tmp_path):
    """A 256 kB tmpfs (needs root, as on the CI machine; skipped otherwise)."""
    d = tmp_path / "disk"
    d.mkdir()
    if os.geteuid() != 0:
        pytest.skip("mounting a small tmpfs needs root")
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=256k", "tmpfs", str(d)],
                       capture_output=True, text=True)
    if r.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs: {r.stderr.strip()}")
    try:
        yield d
    finally:
        subprocess.run(["umount", "-l", str(d)], check=False)
