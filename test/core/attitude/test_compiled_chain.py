"""The causal chain's kernels (core/jit.py): written once, run compiled (numba) or as Python with
the same numbers; a causal aided replay steps its samples compiled, not through the interpreter;
the stages' state arrays survive their resets (the compiled loop holds them)."""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from test_stream_real import MODES, hostile_field, hostile_rest_motion_rest

from gyro_attitude.core.attitude.stream import RUNNING, AttitudeStream
from gyro_attitude.core.jit import backend, compiled, direct, kernel

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[2]
AIDED = ("default", "gravity_retired", "tilt_enu", "tilt", "level_tilt", "magnetometer",
         "level_magnetometer_enu")

_RUN = """
import json, sys
import numpy as np
sys.path.insert(0, {here!r})
from sim_static import rest_motion_rest
from test_stream_real import MODES, hostile_field, hostile_rest_motion_rest
from gyro_attitude.core.attitude.stream import AttitudeStream
from gyro_attitude.core.jit import backend
t, g, a, cov = hostile_rest_motion_rest()
out = {{"backend": backend()}}
for mode in {modes!r}:
    mag = hostile_field(t.size) if "magnetometer" in mode else None
    res = AttitudeStream(config=MODES[mode]).run(t, g, "imu", cov, a, mag)
    s = AttitudeStream(config=MODES[mode])
    pushed = [s.push(int(t[k]), g[k], "imu", cov[k], a[k], None if mag is None else mag[k])[1]
              for k in range(t.size)]
    pushed = np.array([q for q in pushed if q is not None])
    out[mode] = [res.q.tolist(), res.variance.tolist(), pushed.tolist(), res.counts]
json.dump(out, sys.stdout)
"""


def _python(code: str, timeout: float = 300, cwd=REPO, pythonpath=(), **env) -> str:
    """Run ``code`` in a fresh interpreter on this source tree: (stdout, stderr); ``env`` set
    (None: removed)."""
    environ = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [*map(str, pythonpath), str(REPO), os.environ.get("PYTHONPATH", "")]))
    for key, value in env.items():
        if value is None:
            environ.pop(key, None)
        else:
            environ[key] = value
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=timeout, cwd=cwd, env=environ)
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout, done.stderr


def _attitudes(jit: str) -> dict:
    return json.loads(_python(_RUN.format(here=str(HERE), modes=AIDED), 600,
                              GYRO_ATTITUDE_JIT=jit)[0])


@pytest.mark.skipif(backend() != "numba", reason="numba is not installed")
def test_compiled_and_python_kernels_give_the_same_attitudes_bit_for_bit():
    fast, slow = _attitudes("1"), _attitudes("0")
    assert (fast.pop("backend"), slow.pop("backend")) == ("numba", "python")
    for mode in AIDED:
        q_run, var_run, q_push, counts = fast[mode]
        assert q_run == slow[mode][0] and q_push == slow[mode][2], mode
        assert var_run == slow[mode][1] and counts == slow[mode][3], mode
        assert len(q_run) > 1000


@kernel
def _scaled(x, k):
    return x * k


@pytest.mark.skipif(backend() != "numba", reason="numba is not installed")
def test_direct_calls_the_one_compiled_form_and_leaves_the_dispatch_otherwise():
    form = compiled(_scaled)
    assert direct(form) is form  # nothing compiled yet
    assert form(2.0, 3.0) == 6.0
    fast = direct(form)
    assert fast is not form and fast(2.0, 4.0) == 8.0  # the machine code of (float, float)
    assert form(2, 3) == 6  # a second set of types: the dispatch is needed again
    assert direct(form) is form


def test_a_function_not_written_as_a_kernel_is_refused():
    def plain(x):
        return x

    with pytest.raises(TypeError, match="not marked as a kernel"):
        compiled(plain)

    @kernel
    def twice(x):
        return 2.0 * x

    assert compiled(twice)(1.5) == 3.0




@pytest.mark.parametrize("form", ["list", "tuple", "float32", "int_cov", "cov_3x3", "readonly"])
def test_pushed_inputs_of_any_numeric_form_give_the_attitudes_of_float64_arrays(form):
    # push() converts what it is given once; the compiled step then always gets one set of
    # argument types (it is called without numba's dispatch): any numeric form of the same
    # values gives the same attitudes, variances and counts, to the last bit
    t, g, a, cov = hostile_rest_motion_rest()
    mag = hostile_field(t.size)
    with np.errstate(over="ignore"):  # (the hostile 1e300 rate becomes inf in float32)
        g32 = g.astype(np.float32).astype(np.float64)  # values a float32 array holds exactly
    if form == "int_cov":  # integers, as a driver may send them (4 (rad/s)² per axis)
        cov = np.tile(np.diag([4.0, 4.0, 4.0]).reshape(9), (t.size, 1))
    convert = {
        "list": lambda x: x.tolist(), "tuple": lambda x: tuple(x.tolist()),
        "float32": lambda x: x.astype(np.float32), "int_cov": lambda x: x,
        "cov_3x3": lambda x: x, "readonly": lambda x: np.frombuffer(x.tobytes()),
    }[form]

    def pushed(as_given):
        s = AttitudeStream(config=MODES["level_magnetometer_enu"])
        out = []
        for k in range(t.size):
            c = cov[k]
            if as_given and form == "int_cov":
                c = c.astype(np.int64)
            elif as_given and form == "cov_3x3":
                c = c.reshape(3, 3)
            w = convert(g32[k].astype(np.float64)) if as_given else g32[k]
            acc = convert(a[k]) if as_given and form != "float32" else a[k]
            q = s.push(int(t[k]), w, "imu", c, acc, mag[k])[1]
            out.append(None if q is None else (q.tolist(), s.variance.tolist()))
        return out, s.counts

    assert pushed(True) == pushed(False)


def test_the_pushed_input_rate_and_jitter_are_the_stamps():
    # the interval statistics of the diagnostics, from the compiled step's ring
    rng = np.random.default_rng(4)
    t = 1_000_000_000 + np.cumsum(rng.integers(4_900_000, 5_100_000, 3000))
    s = AttitudeStream(config=MODES["tilt"])
    for k in range(t.size):
        s.push(int(t[k]), 1e-3 * rng.standard_normal(3), "imu", None,
               np.array([0.0, 0.0, 9.81]), None)
    dt = np.diff(t)[-2000:] * 1e-9
    got = s.intervals.summary()
    assert got["rate_hz"] == pytest.approx(1.0 / dt.mean(), rel=1e-12)
    assert got["jitter_s"] == pytest.approx(dt.std(), rel=1e-9)
    assert got["max_dt_s"] == dt.max()



@pytest.mark.skipif(backend() != "numba", reason="numba is not installed")
def test_kernels_compile_where_no_cache_can_be_written(tmp_path):
    # A read-only installation run by a user without a home: numba finds no cache locator.
    # The kernels are compiled in the process instead, said once; the numbers are the same.
    (tmp_path / "toy_kernels.py").write_text(
        "from gyro_attitude.core.jit import kernel\n\n"
        "@kernel\ndef half(x):\n    return 0.5 * x\n\n"
        "@kernel\ndef quarter(x):\n    return half(half(x))\n")
    (tmp_path / "__pycache__").write_text("not a directory")
    code = ("from gyro_attitude.core.jit import compiled\nimport toy_kernels\n"
            "print(compiled(toy_kernels.quarter)(3.0))\n")
    out, err = _python(code, cwd=tmp_path, pythonpath=[tmp_path], HOME="/dev/null",
                       XDG_CACHE_HOME="/dev/null/cache", PYTHONDONTWRITEBYTECODE="1",
                       NUMBA_CACHE_DIR=None)
    assert out.strip() == "0.75"
    assert err.count("numba cannot cache the compiled kernels") == 1



def test_compile_kernels_warms_the_steps_of_a_start_that_cannot_align_on_its_recording():
    # a gyrocompassing start never aligns on the synthetic recording: the kernels its running
    # phase needs are compiled all the same (from a given attitude)
    code = ("from gyro_attitude.core.attitude.stream import compile_kernels\n"
            "from gyro_attitude.core.attitude.settings import StreamConfig\n"
            "from gyro_attitude.core.jit import compiled, backend\n"
            "cfg = StreamConfig(aiding='tilt', initial_attitude_source='level',\n"
            "                   heading_source='gyrocompass', gyro_bias='parameter',\n"
            "                   gyro_bias_sigma_rad_s=1e-7, frame='enu', latitude_rad=0.8)\n"
            "compile_kernels(cfg)\n"
            "print(backend(), compiled.cache_info().currsize)\n")
    name, n = _python(code)[0].split()
    assert name == "python" or int(n) >= 8


@pytest.mark.parametrize("axis", [0, 1, 2])
@pytest.mark.parametrize("mode", ["tilt", "level_enu", "level_magnetometer_enu"])
def test_a_nan_on_any_accelerometer_axis_is_counted_and_skipped_while_aligning_or_running(
        mode, axis):
    # (a test of the compiled step's bound: max() skips a NaN that is not first, so one NaN on
    # y or z went into the rest sums, and while levelling the stream never aligned)
    t, g, a, cov = hostile_rest_motion_rest()
    a = a.copy()
    ok = np.isfinite(a).all(axis=1) & (np.abs(a) <= 1e6).all(axis=1)
    for k in (300, 1500):  # during the first rest (aligning) and in motion (running)
        k = int(np.flatnonzero(ok[k:])[0]) + k
        a[k, axis] = np.nan
    mag = hostile_field(t.size) if "magnetometer" in mode else None
    s = AttitudeStream(config=MODES[mode])
    pushed = [s.push(int(t[k]), g[k], "imu", cov[k], a[k], None if mag is None else mag[k])[1]
              for k in range(t.size)]
    s_ref = AttitudeStream(config=MODES[mode])
    s_ref._fast = None  # the Python steps for every sample
    ref = [s_ref.push(int(t[k]), g[k], "imu", cov[k], a[k], None if mag is None else mag[k])[1]
           for k in range(t.size)]
    assert s.phase is RUNNING
    assert s.counts == s_ref.counts
    assert s.counts["integrator_error"] == 0
    assert [q is None for q in pushed] == [q is None for q in ref]
    got = np.array([q for q in pushed if q is not None])
    assert np.all(np.isfinite(got))
    assert np.max(np.abs(got - np.array([q for q in ref if q is not None]))) <= 1e-12
