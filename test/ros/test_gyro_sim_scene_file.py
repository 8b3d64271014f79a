"""gyro_sim with hostile or seedless scene files: an alias bomb is one line and exit 2 at
once (it used to ignore SIGINT and grow to 22 GB); seed:=N stands in for a missing seed."""

from __future__ import annotations

import resource
import textwrap
import time

import pytest

pytestmark = pytest.mark.ros

SIM = "gyro_attitude.ros.gyro_sim_node"
SCENE = textwrap.dedent("""\
    description: IMU at rest
    rate_hz: 100.0
    earth: {latitude_deg: 45.0}
    motion: {type: stationary}
    """)


def _bomb(key: str) -> str:
    lines = ['a0: &a0 ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]']
    lines += [f"a{i}: &a{i} [{','.join([f'*a{i - 1}'] * 9)}]" for i in range(1, 9)]
    return "\n".join(lines) + f"\n{key}: *a8\n"


def test_alias_bomb_scene_is_refused_at_once(launch, tmp_path):
    path = tmp_path / "bomb.yaml"
    path.write_text(SCENE + "seed: 1\n" + _bomb("other"), encoding="utf-8")
    start = time.monotonic()
    proc = launch(SIM, "-p", f"scene:={path}")
    assert proc.wait(timeout=60) == 2, proc.output()
    out = proc.output()
    assert time.monotonic() - start < 30
    [line] = [ln for ln in out.splitlines() if "invalid parameter" in ln]
    assert "bomb.yaml" in line and "aliases" in line and "Traceback" not in out
    child = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss  # kB, all children so far
    assert child < 2_000_000


def test_seed_parameter_stands_in_for_a_missing_seed(launch, tmp_path):
    path = tmp_path / "noseed.yaml"
    path.write_text(SCENE, encoding="utf-8")
    out = tmp_path / "rec.mcap"
    proc = launch(SIM, "-p", f"scene:={path}", "-p", "seed:=7", "-p", "time_mode:=fast",
                  "-p", "duration_s:=0.5", "-p", f"record_path:={out}")
    assert proc.wait(timeout=60) == 0, proc.output()
    assert out.is_file()
    proc = launch(SIM, "-p", f"scene:={path}")
    assert proc.wait(timeout=60) == 2
    assert "seed" in proc.output()
