"""The causal estimator gives what it gave when these outputs were recorded (test/golden/record.py):
attitudes within 1e-12 rad, orientation variances to 1e-12 relative, every count, note, bias and
alignment figure the same -- in every mode on hostile samples, through push() and run(), and for
``replay --estimator causal`` of every shared BROAD recording in every aiding mode.

Recorded outputs are the oracle here on purpose: this is the regression test of the estimator's
rewrite (issue 37); a change that alters results on purpose records them again in the same commit
and says why."""

import json
import os

import numpy as np
import pytest
from golden_cases import AIDINGS, HERE, MODES, broad_files, broad_outputs, hostile_outputs

from gyro_attitude.core.rotation import quat_angle_between

HOSTILE = np.load(HERE / "hostile.npz")
HOSTILE_META = json.loads((HERE / "hostile.json").read_text())
BROAD = np.load(HERE / "broad.npz")
BROAD_META = json.loads((HERE / "broad.json").read_text())


def assert_same_attitudes(q, q_golden, what):
    assert q.shape == q_golden.shape, what
    if q.size:
        angle = quat_angle_between(q, q_golden)
        assert float(np.max(angle)) <= 1e-12, (what, float(np.max(angle)))


def assert_same_variances(v, v_golden, what):
    assert v.shape == v_golden.shape, what
    np.testing.assert_array_equal(np.isnan(v), np.isnan(v_golden), err_msg=what)
    ok = ~np.isnan(v_golden)
    np.testing.assert_allclose(v[ok], v_golden[ok], rtol=1e-12, atol=1e-300, err_msg=what)


def close_figures(a, b, path=""):
    """Equal JSON figures, floats to 1e-12 relative (the last bits of a sum may move)."""
    if isinstance(b, dict):
        assert isinstance(a, dict) and sorted(a) == sorted(b), (path, sorted(a), sorted(b))
        for k in b:
            close_figures(a[k], b[k], f"{path}/{k}")
    elif isinstance(b, list):
        assert isinstance(a, list) and len(a) == len(b), path
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            close_figures(x, y, f"{path}[{i}]")
    elif isinstance(b, float) and not isinstance(a, bool):
        assert isinstance(a, float | int), (path, a, b)
        if np.isnan(b):
            assert np.isnan(a), (path, a)
        else:
            assert a == pytest.approx(b, rel=1e-12, abs=1e-15), (path, a, b)
    else:
        assert a == b, (path, a, b)


@pytest.mark.parametrize("form", ["push", "run", "run_jit"])
@pytest.mark.parametrize("mode", sorted(MODES))
def test_hostile_samples_give_the_recorded_outputs(mode, form, monkeypatch):
    """``run`` takes the precompiled loop where it is built (dev.sh builds it), ``run_jit``
    numba's just-in-time form of the same loop: both give the recorded outputs."""
    if form == "run_jit":
        import gyro_attitude.core.attitude.stream as stream

        monkeypatch.setattr(stream, "precompiled", lambda func: None)
        form = "run"
    arrays, figures = hostile_outputs(mode, form)
    key = f"{mode}/{form}"
    for name, x in arrays.items():
        g = HOSTILE[f"{key}/{name}"]
        if name == "q":
            assert_same_attitudes(x, g, key)
        elif name == "variance":
            assert_same_variances(x, g, key)
        else:
            np.testing.assert_array_equal(x, g, err_msg=f"{key}/{name}")
    close_figures(figures, HOSTILE_META[key], key)


def _broad_cases():
    files = broad_files()
    if not files:
        if os.environ.get("CI"):
            pytest.fail("no BROAD recordings in ../shared/real: CI always has them")
        return [pytest.param(None, None, marks=pytest.mark.skip("no ../shared/real"))]
    return [pytest.param(p, a, id=f"{p.stem[:8]}-{a}") for p in files for a in AIDINGS]


@pytest.mark.slow
@pytest.mark.parametrize(("path", "aiding"), _broad_cases())
def test_broad_causal_replay_gives_the_recorded_outputs(path, aiding):
    arrays, figures = broad_outputs(path, aiding)
    key = f"{path.stem}/{aiding}"
    for name in ("q", "q_file"):
        assert_same_attitudes(arrays[name], BROAD[f"{key}/{name}"], key)
    assert_same_variances(arrays["variance"], BROAD[f"{key}/variance"], key)
    for name in ("t_ns", "index"):
        np.testing.assert_array_equal(arrays[name], BROAD[f"{key}/{name}"], err_msg=key)
    close_figures(figures, BROAD_META[key], key)
