"""Round trip: simulate the shipped lab_bench scene for 2 h, analyse it, get its noise terms back."""

import numpy as np
import pytest

from gyro_attitude.io.imu_fast import read_imu_arrays
from gyro_attitude.io.scene_file import load_scene
from gyro_attitude.offline.allan import analyse_mcap
from gyro_attitude.offline.simulate import simulate


def _oadev(rate: np.ndarray, dt: float, m: np.ndarray) -> np.ndarray:
    """Overlapping Allan deviation straight from docs/equations.md: θ = ∫ rate,
    σ²(τ) = ⟨(θ_{k+2m} − 2θ_{k+m} + θ_k)²⟩ / (2τ²), τ = m·dt."""
    theta = np.concatenate(([0.0], np.cumsum(rate) * dt))
    out = []
    for mm in m:
        d = theta[2 * mm:] - 2 * theta[mm:-mm] + theta[:-2 * mm]
        out.append(np.sqrt(np.mean(d**2) / (2 * (mm * dt) ** 2)))
    return np.array(out)


@pytest.fixture(scope="module")
def lab_bench_2h(tmp_path_factory):
    out = tmp_path_factory.mktemp("rt") / "lab_bench_2h.mcap"
    simulate("lab_bench", 7200.0, out, publish_truth=False)
    return out, analyse_mcap(out)


def test_lab_bench_terms_come_back(lab_bench_2h):
    _, r = lab_bench_2h
    spec = load_scene("lab_bench")
    g = spec.gyro_errors
    assert r.samples == 1_440_000 and r.dt_s == pytest.approx(0.005, rel=1e-12)
    for axis, i in zip("xyz", range(3), strict=True):
        t = r.gyro[axis].terms
        # Tolerances from the statistics of a 2 h record: N from ~10⁵ clusters (±0.5 %),
        # B from the 10-50 s floor (±5 % rms over seeds), K from the few long clusters
        # (±13 % rms over seeds, largest error 31 %: measured on seeds 1-8 x 3 axes, with
        # the floor from independent processes and from the shared-input bank alike; the
        # 20 % asked before failed 3-4 seeds of 8): 3 rms.
        assert t.random_walk == pytest.approx(g.noise_density[i], rel=0.10)
        assert t.rate_random_walk == pytest.approx(g.rate_random_walk[i], rel=0.40)
        assert t.bias_instability == pytest.approx(g.bias_instability_floor[i], rel=0.25)
    a = spec.accel_errors
    for axis, i in zip("xyz", range(3), strict=True):
        t = r.accel[axis].terms
        assert t.random_walk == pytest.approx(a.noise_density[i], rel=0.10)
        assert t.bias_instability == pytest.approx(a.bias_instability_floor[i], rel=0.25)


def test_deviation_matches_an_independent_computation(lab_bench_2h):
    path, r = lab_bench_2h
    imu = read_imu_arrays(path)
    m = np.rint(r.tau_s / r.dt_s).astype(np.int64)
    for i, axis in enumerate("xyz"):
        ref = _oadev(imu.angular_velocity[:, i], r.dt_s, m)
        # Same estimator, two implementations: they agree to rounding of the cumulative sum
        # (~1e-9 here), far inside the 3 % asked for.
        assert np.allclose(r.gyro[axis].adev, ref, rtol=1e-6, atol=0)
        # 1-σ bounds from the number of non-overlapping clusters K = n/m: σ(1 ∓ 1/√(2(K−1))).
        half = 1 / np.sqrt(2 * (np.floor(r.samples / m) - 1))
        assert np.allclose(r.gyro[axis].lower, ref * (1 - half), rtol=1e-6, atol=0)
        assert np.allclose(r.gyro[axis].upper, ref * (1 + half), rtol=1e-6, atol=0)
