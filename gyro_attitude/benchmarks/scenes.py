"""Benchmark suite ``scenes``: what each scene and each effect costs to simulate.

For every shipped scene, samples per second of :class:`SceneSimulator.next_block` at three
block sizes (1 = one sample per call, 20 = a node's typical timer block, 10 000 = offline
bulk), best of a few repeats. Then one scene grown effect by effect (stationary ideal gyro →
+ accelerometers → + gyro noise → + bias instability → + quantization → moving carrier) to
show that a scene pays only for what it calls for. Figures are noisy on a shared machine, so
each row also gives its cost relative to the cheapest variant measured in the same run.
"""

from __future__ import annotations

import copy
import pathlib
import time

from gyro_attitude.benchmarks import simulate as simulate_bench
from gyro_attitude.core.scene import SceneSimulator, SceneSpec
from gyro_attitude.core.trajectory import TrajectoryMotion
from gyro_attitude.io.scene_file import list_scenes, load_scene

BLOCKS = (1, 20, 10_000)

_BASE = {
    "description": "benchmark base: level IMU at rest",
    "seed": 0,
    "earth": {"latitude_deg": 45.0},
    "motion": {"type": "stationary"},
}
# Each variant adds one effect to the previous one.
_STEPS = [
    ("ideal gyro at rest", {}),
    ("+ accelerometer", {"accelerometer": {}}),
    ("+ gyro white noise", {"gyro": {"errors": {"arw_rad_sqrt_s": 1e-4}}}),
    ("+ bias instability", {"gyro": {"errors": {"bias_instability_rad_s": 1e-5,
                                                "bias_instability_tau_s": 100.0}}}),
    ("+ quantization", {"gyro": {"errors": {"quantization_rad": 1e-6}}}),
    ("+ Allan-floor bias instability", {"gyro": {"errors": {"bias_instability": "3 deg/h"}}}),
    ("+ rate random walk", {"gyro": {"errors": {"rate_random_walk": "30 deg/h/sqrt(h)"}}}),
    ("+ moving (position, transport)", {"motion": {"type": "constant_velocity",
                                                   "speed_mps": 100.0}}),
]


def _merge(base: dict, change: dict) -> dict:
    out = copy.deepcopy(base)
    for k, v in change.items():
        if isinstance(v, dict) and isinstance(out.get(k), dict) and k != "motion":
            out[k] = _merge(out[k], v)
        else:
            out[k] = copy.deepcopy(v)
    return out


def _throughput(spec: SceneSpec, rate_hz: float, block: int, budget_s: float) -> float:
    """Best-of-3 samples/s for blocks of ``block`` samples (each repeat ~budget_s/3)."""
    best = 0.0
    for _ in range(3):
        sim = SceneSimulator(spec, rate_hz)
        sim.next_block(block)  # warm-up (first-call set-up)
        calls, t0 = 0, time.perf_counter()
        while True:
            sim.next_block(block)
            calls += 1
            elapsed = time.perf_counter() - t0
            if elapsed > budget_s / 3 or calls * block >= 2_000_000:
                break
        best = max(best, calls * block / elapsed)
    return best


def run(quick: bool, out_dir: pathlib.Path) -> list[dict]:
    """Run the suite, print its table and return the JSON rows (no plot)."""
    budget = 0.15 if quick else 0.6
    rows: list[dict] = []
    print("scenes: samples/s of SceneSimulator.next_block (best of 3)")
    print(f"{'scene':<22}" + "".join(f"{'block ' + str(b):>16}" for b in BLOCKS))
    for name, _ in list_scenes():
        spec = load_scene(name)
        if isinstance(spec.motion, TrajectoryMotion):
            continue  # a pose file of fixed span: measured by suite "trajectory"
        sim = SceneSimulator(spec, spec.rate_hz)
        sim.next_block(1)
        line = f"{name:<22}"
        for block in BLOCKS:
            if spec.free_gyro_params is not None and block > 20 and quick:
                continue
            sps = _throughput(spec, spec.rate_hz, block, budget)
            rows.append({"suite": "scenes", "kind": "scene", "scene": name,
                         "rate_hz": spec.rate_hz, "block": block, "samples_per_s": sps,
                         "effects": sorted(sim.effects_run)})
            line += f"{sps:>16,.0f}"
        print(line)

    print("\ncost of effects, added one by one (block 10000; relative to the cheapest variant "
          "of this run)")
    variant_rows = []
    d = _BASE
    for label, change in _STEPS:
        d = _merge(d, change)
        spec = SceneSpec.from_dict(d, name="bench")
        sps = _throughput(spec, 200.0, 10_000, budget)
        variant_rows.append({"suite": "scenes", "kind": "effect", "variant": label,
                             "block": 10_000, "samples_per_s": sps})
    fastest = max(r["samples_per_s"] for r in variant_rows)
    for r in variant_rows:
        r["relative_cost"] = fastest / r["samples_per_s"]
        print(f"  {r['variant']:<32}{r['samples_per_s']:>14,.0f} samples/s"
              f"{r['relative_cost']:>8.2f}x")
    return rows + variant_rows + simulate_bench.run(quick, out_dir)


if __name__ == "__main__":  # pragma: no cover
    import json
    import sys

    out = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else "bench_out")
    result = run(quick="--quick" in sys.argv, out_dir=out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "scenes.json").write_text(json.dumps(result, indent=1))
