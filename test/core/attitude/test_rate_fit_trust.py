"""A rate fit that cannot be trusted (samples that alias the motion near the Nyquist rate; a fit
that leaves its samples' range on uneven stamps) moves the step toward the exponential map and is
counted; where the fit can be trusted nothing changes, bit for bit.

Oracle: the closed-form coning attitude (docs/equations.md); the exponential map ``exp_map`` is
the peer the fallback must match near Nyquist."""

from pathlib import Path

import numpy as np
import pytest

import gyro_attitude.core.attitude.interpolation as ip
import gyro_attitude.core.attitude.streaming as streaming
from gyro_attitude.core.attitude import StreamingIntegrator, integrate_batch
from gyro_attitude.core.attitude.offline import estimate_offline
from gyro_attitude.core.attitude.settings import StreamConfig
from gyro_attitude.core.attitude.stream import RATE_FIT_FALLBACK, AttitudeStream
from gyro_attitude.core.motion import coning_quat_and_rate
from gyro_attitude.core.rotation import quat_conjugate, quat_multiply
from gyro_attitude.core.scene.simulator import SceneSimulator
from gyro_attitude.io.scene_file import load_scene

RATE_HZ = 100.0
NO_BIAS = StreamConfig(gyro_bias="none")


def _coning(omega, alpha_deg=1.0, seconds=1.0, rate_hz=RATE_HZ):
    n = int(seconds * rate_hz) + 1
    t_ns = 1_000_000_000 + np.arange(n, dtype=np.int64) * int(round(1e9 / rate_hz))
    q, w = coning_quat_and_rate(np.radians(alpha_deg), omega, (t_ns - t_ns[0]) * 1e-9)
    return t_ns, w, q


def _rms(q, truth):
    d = quat_multiply(quat_conjugate(truth), q)
    e = 2.0 * np.arctan2(np.linalg.norm(d[:, :3], axis=1), np.abs(d[:, 3]))
    return float(np.sqrt(np.mean(e * e)))


def _rule_off(monkeypatch):
    """The rule off in the vectorized offline kernel and in the causal step, the latter run as
    Python (compiled code keeps the functions it was compiled with)."""
    monkeypatch.setattr(ip, "untrusted_fits", lambda *a, **k: None)
    monkeypatch.setattr(ip, "untrusted_fit_scalar", lambda *a, **k: 0.0)
    monkeypatch.setattr(streaming, "compiled", lambda f: f)


@pytest.mark.parametrize("algorithm, margin", [("rotvec_cubic", 1.02), ("magnus6_quintic", 1.05),
                                               ("quat_rk4", 1.02)])
def test_nyquist_coning_falls_back_to_the_exponential_map_and_counts(algorithm, margin):
    # 300 rad/s coning sampled at 100 Hz: the rate turns by 3 rad (0.95 π) between samples.
    # Without the rule: cubic 3.79e-2, quintic 6.63e-2 rad RMS against exp_map's 3.44e-2.
    t, w, truth = _coning(300.0)
    fb = []
    q = integrate_batch(t, w, q0=truth[0], algorithm=algorithm, fallbacks=fb)
    ref = _rms(integrate_batch(t, w, q0=truth[0], algorithm="exp_map"), truth)
    assert _rms(q, truth) <= margin * ref
    assert sum(f.size for f in fb) == t.size - 1  # every interval


@pytest.mark.parametrize("algorithm", ["rotvec_cubic", "quat_rk4"])
def test_streaming_applies_the_same_rule_and_count_as_the_batch(algorithm):
    t, w, truth = _coning(300.0)
    fb = []
    qb = integrate_batch(t, w, q0=truth[0], algorithm=algorithm, fallbacks=fb)
    s = StreamingIntegrator(algorithm, q0=truth[0])
    qs = np.array([s.update(int(a), b) for a, b in zip(t, w, strict=True)])
    assert np.max(np.abs(qs - qb)) < 1e-12
    assert s.fit_fallbacks == sum(f.size for f in fb) == t.size - 1


def test_the_stream_counts_fallbacks_in_push_run_and_offline():
    t, w, truth = _coning(300.0)
    pushed = AttitudeStream("rotvec_cubic", q0=truth[0], config=NO_BIAS)
    for a, b in zip(t, w, strict=True):
        pushed.push(int(a), b)
    ran = AttitudeStream("rotvec_cubic", q0=truth[0], config=NO_BIAS).run(t, w)
    off = estimate_offline(t, w, config=NO_BIAS, q0=truth[0])
    assert pushed.counts[RATE_FIT_FALLBACK] == ran.counts[RATE_FIT_FALLBACK] == t.size - 1
    assert off.counts[RATE_FIT_FALLBACK] == t.size - 1
    assert "alias" in ran.details[RATE_FIT_FALLBACK]


@pytest.mark.parametrize("omega, rate_hz", [(62.8, 1000.0), (62.8, 100.0), (200.0, 100.0)])
@pytest.mark.parametrize("algorithm", ["rotvec_cubic", "magnus6_quintic", "quat_rk4"])
def test_resolved_coning_is_untouched_bit_for_bit(omega, rate_hz, algorithm, monkeypatch):
    # up to Ωh = 2 rad the fit is better than the exponential map (docs/bench/nyquist.json):
    # no fallback, and the attitudes are those of the kernel without the rule
    t, w, truth = _coning(omega, alpha_deg=5.0, rate_hz=rate_hz)
    fb = []
    q = integrate_batch(t, w, q0=truth[0], algorithm=algorithm, fallbacks=fb)
    assert sum(f.size for f in fb) == 0
    _rule_off(monkeypatch)
    assert np.array_equal(q, integrate_batch(t, w, q0=truth[0], algorithm=algorithm))


@pytest.mark.parametrize("name", ["coning", "spinning_projectile", "handheld_mems", "ship"])
def test_shipped_scenes_have_no_fallback(name, monkeypatch):
    spec = load_scene(name)
    rate = float(spec.source.get("rate_hz", 200.0))
    block = SceneSimulator(spec, rate).next_block(int(min(2.0, spec.source.get("duration_s", 2.0))
                                                      * rate))
    for algorithm in ("rotvec_cubic", "magnus6_quintic", "quat_rk4"):
        fb = []
        q = integrate_batch(block.t_ns, block.omega_ib_b, algorithm=algorithm, fallbacks=fb)
        assert sum(f.size for f in fb) == 0, (name, algorithm)
        with monkeypatch.context() as m:
            _rule_off(m)
            assert np.array_equal(q, integrate_batch(block.t_ns, block.omega_ib_b,
                                                     algorithm=algorithm))


@pytest.mark.parametrize("algorithm", ["rotvec_cubic", "magnus6_quintic", "quat_rk4"])
def test_a_very_noisy_gyro_at_rest_never_falls_back(algorithm, monkeypatch):
    # white noise of 5e-3 rad/sqrt(s) at 50 Hz (~20x a poor MEMS gyro): its changes turn past
    # the bound all the time, but they are no angle that matters
    rng = np.random.default_rng(4)
    n = 5000
    t = 1_000_000_000 + np.arange(n, dtype=np.int64) * 20_000_000
    w = rng.normal(scale=5e-3 * np.sqrt(50.0), size=(n, 3))
    fb = []
    q = integrate_batch(t, w, algorithm=algorithm, fallbacks=fb)
    assert sum(f.size for f in fb) == 0
    _rule_off(monkeypatch)
    assert np.array_equal(q, integrate_batch(t, w, algorithm=algorithm))


def test_a_fit_extrapolating_over_a_hole_falls_back():
    # a jolt two samples before four missing ones: the cubic through samples 0, 1, 2 and 7
    # (periods) dips to -4.7x the jolt inside the hole, where no sample shows anything like it
    t = 1_000_000_000 + np.arange(60, dtype=np.int64) * 10_000_000
    t = np.concatenate((t[:50], t[54:]))
    w = np.zeros((t.size, 3))
    w[:, 0] = 0.5
    w[48, 2] = 2.0
    fb = []
    q = integrate_batch(t, w, algorithm="rotvec_cubic", fallbacks=fb)
    # 50: the overshoot; 49: the jolt's rise and fall, a change that turns by π (unresolved)
    assert np.concatenate(fb).tolist() == [49, 50]
    exp_step = integrate_batch(t[49:51], w[49:51], q0=q[49], algorithm="exp_map")[1]
    assert np.max(np.abs(q[50] - exp_step)) < 1e-15
    s = StreamingIntegrator("rotvec_cubic")
    qs = np.array([s.update(int(a), b) for a, b in zip(t, w, strict=True)])
    assert s.fit_fallbacks == 2 and np.max(np.abs(qs - q)) < 1e-12


def test_rule_constants_are_documented():
    text = (Path(__file__).parents[3] / "docs" / "equations.md").read_text()
    assert "When a rate fit cannot be trusted" in text
    assert f"{ip.FIT_TURN_MAX_RAD:g} rad" in text


@pytest.mark.parametrize("k", [[5, 105, 50], [105, 5], [104, 105, 106, 5, 6]])
def test_scattered_intervals_are_judged_each_where_it_lies(k):
    # 300 rad/s turning by 3 rad a sample (aliased) around samples 100-111 only, a constant
    # rate elsewhere: intervals there fall back, intervals far from it never do, in any order
    t = np.arange(200, dtype=np.int64) * 10_000_000
    w = np.tile([300.0, 0.0, 0.0], (200, 1))
    j = np.arange(100, 112)
    w[j] = 300.0 * np.stack([np.cos(3.0 * j), np.sin(3.0 * j), 0.0 * j], axis=1)
    k = np.array(k)
    bad = ip.untrusted_fits(t, w, k, np.zeros((k.size, 3, 3)), None)
    assert bad is not None
    near = (k > 100) & (k < 112)
    assert (bad[near] > 0).all() and (bad[~near] == 0).all()
