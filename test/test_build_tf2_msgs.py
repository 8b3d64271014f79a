"""interfaces/build_tf2_msgs.sh on a machine without compilers: one line saying what is
missing, exit 0 (the set-up goes on), nothing stamped (a later run with a compiler builds)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
TOOLS = {"cc", "c++", "gcc", "g++", "make", "cmake"}


def test_missing_compiler_and_make_named_in_one_line_and_nothing_stamped(tmp_path):
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    for d in ("/usr/local/bin", "/usr/bin", "/bin"):
        for f in Path(d).iterdir() if Path(d).is_dir() else ():
            name = f.name
            if name in TOOLS or name.startswith(("x86_64-linux-gnu-g", "gcc-", "g++-")):
                continue
            if not (bin_dir / name).exists():
                (bin_dir / name).symlink_to(f)
    venv = tmp_path / "venv"
    (venv / "bin").mkdir(parents=True)
    (venv / "bin" / "python").symlink_to(sys.executable)
    hide = tmp_path / "hide" / "tf2_msgs"  # whatever this interpreter has, tf2_msgs is not
    hide.mkdir(parents=True)
    (hide / "__init__.py").write_text("raise ImportError('hidden by the test')\n")
    env = {**os.environ, "PATH": str(bin_dir), "PYTHONPATH": str(hide.parent)}
    p = subprocess.run(["bash", str(REPO / "interfaces" / "build_tf2_msgs.sh"), str(venv)],
                       env=env, capture_output=True, text=True, timeout=60)
    assert p.returncode == 0, p.stderr
    assert p.stdout == ""
    lines = p.stderr.splitlines()
    assert len(lines) == 1, p.stderr
    assert "tf2_msgs not built: missing a C compiler" in lines[0]
    assert "C++ compiler" in lines[0] and "make" in lines[0] and "publish_tf" in lines[0]
    assert not list(venv.glob(".tf2_msgs-*"))
