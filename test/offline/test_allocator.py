"""Freed array memory kept for reuse in processes that run batch tasks."""

import os
import platform
import subprocess
import sys

import pytest

glibc = pytest.mark.skipif(platform.system() != "Linux" or platform.libc_ver()[0] != "glibc",
                           reason="the setting is glibc's")

# chunk-sized arrays made and freed as a run makes them; prints the minor page faults
_PATTERN = """
import resource, sys
import numpy as np
from gyro_attitude.offline.allocator import keep_freed_memory
applied = keep_freed_memory() if sys.argv[1] == "1" else None
f0 = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
for _ in range(50):
    a = np.ones((61440, 4)); b = a * 2.0; c = np.ones((360000, 3)); d = c + 1.0
    del a, b, c, d
print(applied, resource.getrusage(resource.RUSAGE_SELF).ru_minflt - f0)
"""


def _run(call: bool, **env) -> tuple[str, int]:
    clean = {k: v for k, v in os.environ.items()
             if not k.startswith("MALLOC_") and k != "GLIBC_TUNABLES"}
    out = subprocess.run([sys.executable, "-c", _PATTERN, "1" if call else "0"],
                         env={**clean, **env}, capture_output=True, text=True, timeout=60,
                         check=True).stdout.split()
    return out[0], int(out[1])


@glibc
def test_freed_arrays_are_reused_instead_of_faulted_in_again():
    applied, tuned = _run(True)
    _, default = _run(False)
    assert applied == "True"
    # the default maps and faults in every array afresh: ~ 50 x 3.4 MB of 4-KiB pages
    assert default > 20 * tuned, (default, tuned)


@glibc
@pytest.mark.parametrize("env", [{"MALLOC_MMAP_THRESHOLD_": "131072"},
                                 {"GLIBC_TUNABLES": "glibc.malloc.trim_threshold=131072"}])
def test_the_users_own_malloc_setting_wins(env):
    applied, _ = _run(True, **env)
    assert applied == "False"
