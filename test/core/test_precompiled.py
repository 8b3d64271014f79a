"""The causal estimator's recording loop compiled ahead of time (core/jit.precompiled, built by
io/precompile): taken only when built from this very source, never handed arrays it was not
built for, and a causal run with it needs no numba in the process."""

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from gyro_attitude.core import jit
from gyro_attitude.core.attitude import chain

REPO = Path(__file__).resolve().parents[2]


def _built_or_skip():
    loop = jit.precompiled(chain.run_rows)
    if loop is None:
        if os.environ.get("CI") == "true":
            pytest.fail("dev.sh builds the precompiled loop in CI (gyro_attitude.io.precompile)")
        pytest.skip("the precompiled loop is not built here")
    return loop


def _loop_args(n=400, t=None, w=None):
    from gyro_attitude.core.attitude.stream import AttitudeStream, StreamConfig

    s = AttitudeStream(config=StreamConfig(aiding="none"))
    t = np.arange(1, n + 1, dtype=np.int64) * 5_000_000 if t is None else t
    rng = np.random.default_rng(3)
    w = 0.3 * rng.standard_normal((n, 3)) if w is None else w
    return (s.coef, s.state, s.bias_ring, s.align_ring, s.align_buffer, 0, t, w,
            np.zeros(n, np.int64), -1, False, np.zeros((1, 3)), False, np.zeros((1, 9)), False,
            np.zeros(n, np.int64), np.zeros((1, 3)), np.zeros(n, np.int8),
            np.zeros(n, np.int64), np.zeros((n, 4)), np.zeros((n, 3)), np.zeros(n, bool),
            np.full(chain.N_EVENTS, -1, np.int64), np.zeros((chain.N_EVENTS, 5), np.int64), 0)


@pytest.mark.parametrize("odd", ["strided rates", "int32 stamps", "float32 rates"])
def test_arrays_it_was_not_built_for_are_integrated_by_the_jit_instead(odd):
    """The machine code does not check what it is given (a strided array would be read as a
    contiguous one, int32 stamps crash it): such calls go to numba's form, with its numbers."""
    loop = _built_or_skip()
    n = 400
    t = np.arange(1, n + 1, dtype=np.int64) * 5_000_000
    w = 0.3 * np.random.default_rng(3).standard_normal((n, 3))
    odd_t, odd_w = {"strided rates": (t, np.repeat(w, 2, axis=1)[:, ::2]),
                    "int32 stamps": (t.astype(np.int32), w),
                    "float32 rates": (t, w.astype(np.float32))}[odd]
    got = _loop_args(n, odd_t, odd_w)
    want = _loop_args(n, odd_t, odd_w)
    loop(*got)
    jit.compiled(chain.run_rows)(*want)
    np.testing.assert_array_equal(got[19], want[19])  # the attitudes
    assert np.isfinite(got[19]).all()


def test_the_precompiled_loop_gives_the_jit_loops_bits():
    loop = _built_or_skip()
    got, want = _loop_args(), _loop_args()
    r1 = loop(*got)
    r2 = jit.compiled(chain.run_rows)(*want)
    assert tuple(r1) == tuple(r2)
    for k in range(17, 24):  # action, rows, attitudes, variances, known, first events
        np.testing.assert_array_equal(got[k], want[k])
    assert got[1].tobytes() == want[1].tobytes()  # the whole state record


def test_a_module_built_from_other_source_is_never_taken(tmp_path, monkeypatch):
    """The module's name carries a digest of every source file of the core (kernels, and the
    constants numba freezes into them, in any file) and of the build script: a change to
    any of them renames it."""
    core = tmp_path / "core"
    (core / "attitude").mkdir(parents=True)
    (tmp_path / "io").mkdir()
    (core / "jit.py").write_text("# jit\n")
    (core / "earth.py").write_text("OMEGA_IE = 7.292115e-5\n")
    (core / "attitude" / "chain.py").write_text("def run_rows(): pass\n")
    (tmp_path / "io" / "precompile.py").write_text("# build\n")
    monkeypatch.setattr(jit, "__file__", str(core / "jit.py"))
    names = []
    for path, text in ((None, None), (core / "earth.py", "OMEGA_IE = 7.3e-5\n"),
                       (core / "attitude" / "chain.py", "def run_rows(): return 1\n"),
                       (tmp_path / "io" / "precompile.py", "# build 2\n")):
        if path is not None:
            path.write_text(text)
        jit._source_digest.cache_clear()
        names.append(jit.precompiled_name(chain.run_rows))
    jit._source_digest.cache_clear()
    assert len(set(names)) == 4 and all(n.startswith("_aot_run_rows_") for n in names)


CAUSAL_RUN = """
import sys
import numpy as np
from gyro_attitude.core.attitude.stream import AttitudeStream, StreamConfig
n = 3000
t = np.arange(1, n + 1, dtype=np.int64) * 5_000_000
rng = np.random.default_rng(1)
w = rng.normal(0.0, 1e-3, (n, 3)); w[1000:2000, 2] += 0.5
a = np.tile([0.3, -0.2, 9.79], (n, 1)) + rng.normal(0.0, 0.02, (n, 3))
for aiding in ("none", "auto"):
    res = AttitudeStream(config=StreamConfig(aiding=aiding)).run(t, w, "imu", None, a)
    assert res.q.shape == (n, 4) and np.isfinite(res.q).all()
print(",".join(m for m in sys.modules if m.split(".")[0] == "numba"))
"""


def test_a_causal_run_with_the_precompiled_loop_loads_no_numba():
    _built_or_skip()
    out = subprocess.run([sys.executable, "-c", CAUSAL_RUN], capture_output=True, text=True,
                         timeout=300, cwd=REPO, check=True).stdout.strip()
    assert out == "", f"the causal run imported {out.split(',')[:4]}"


def test_a_read_only_output_is_refused_by_the_jit_not_written_by_the_machine_code():
    """(The machine code would write into it: a read-only memory map crashed the process.)"""
    loop = _built_or_skip()
    args = list(_loop_args())
    args[19] = np.zeros_like(args[19])
    args[19].flags.writeable = False
    with pytest.raises(Exception, match="(?i)read.?only|readonly|immutable"):
        loop(*args)
