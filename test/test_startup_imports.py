"""What a command, a node or a pool worker loads before it does any work: scipy is imported
where it is used (its signal module alone takes longer to import than all the rest), so that
`gyro-attitude simulate`, a refused command line, `ros2 run` of a node and a pool worker start
without it."""

import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

STARTUP_MODULES = [
    "gyro_attitude.cli",
    "gyro_attitude.commands.simulate",
    "gyro_attitude.commands.replay",
    "gyro_attitude.commands.montecarlo",
    "gyro_attitude.offline.montecarlo",  # what the pool's forkserver imports
    "gyro_attitude.offline.fleet",
    "gyro_attitude.ros.gyro_sim_node",
    "gyro_attitude.ros.attitude_integrator_node",
]


@pytest.mark.parametrize("module", STARTUP_MODULES)
def test_starting_imports_no_scipy(module):
    code = (f"import sys, {module}\n"
            "print(','.join(sorted(m for m in sys.modules if m.split('.')[0] == 'scipy')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120, cwd=REPO, check=True).stdout.strip()
    assert out == "", f"importing {module} loads {out.split(',')[:5]}"

