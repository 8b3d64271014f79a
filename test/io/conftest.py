"""Shared fixtures for the io tests: reference rosbag2 files and small recordings."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
REFERENCE = REPO.parent / "shared" / "reference" / "rosbag2"

os.environ.setdefault("AMENT_PREFIX_PATH", sys.prefix)


@pytest.fixture(scope="session")
def reference_dir() -> Path:
    if not (REFERENCE / "only_topics.mcap").is_file():
        message = f"rosbag2 reference files not found at {REFERENCE} (<repo>/../shared)"
        if os.environ.get("CI"):
            pytest.fail(message + ": CI always has ../shared beside the clone")
        pytest.skip(message)
    return REFERENCE
