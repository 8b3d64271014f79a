"""Building the precompiled recording loop (gyro_attitude.io.precompile) on a machine without a
C compiler: one line saying so, a nonzero status, and nothing in the package changed."""

import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
CORE = REPO / "gyro_attitude" / "core"


def _aot_files():
    return sorted((p.name, p.stat().st_mtime_ns) for p in CORE.iterdir()
                  if p.name.startswith(("_aot_", ".build-")))


def test_without_a_c_compiler_the_build_says_so_in_one_line_and_changes_nothing():
    before = _aot_files()
    env = dict(os.environ, CC="/nonexistent/cc", PYTHONPATH=str(REPO))
    proc = subprocess.run([sys.executable, "-m", "gyro_attitude.io.precompile", "--force"],
                          capture_output=True, text=True, timeout=600, cwd=REPO, env=env)
    assert proc.returncode == 1, proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("precompile: not built"), proc.stderr
    assert "C compiler" in lines[0]
    assert "Traceback" not in proc.stderr
    assert _aot_files() == before
