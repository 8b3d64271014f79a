"""Scene positions (and all that depends on them) do not depend on how a run is split into blocks."""

import numpy as np
import pytest

from gyro_attitude.core.scene import SceneSimulator, SceneSpec
from gyro_attitude.core.scene.simulator import POSITION_SEGMENT
from gyro_attitude.io.scene_file import find_scene_file, load_scene, read_scene_dict

FIELDS = ("t_ns", "omega_ib_b", "specific_force_b", "truth_q_nb", "position_llh",
          "velocity_enu")


def _pieces(sim, total, rng):
    out, k = [], 0
    while k < total:
        n = int(min(rng.integers(1, 2 * POSITION_SEGMENT), total - k))
        out.append(sim.next_block(n))
        k += n
    return out


@pytest.mark.parametrize("name", ["ship", "aircraft_turn"])
def test_moving_scene_is_bit_identical_in_any_blocks(name):
    """gyro_sim asks for short blocks, simulate for long ones: the same bits either way
    (the position integral used to restart at every block: 1e-17 rad/s apart)."""
    spec = load_scene(name)
    total = 3 * POSITION_SEGMENT + 123
    whole = SceneSimulator(spec, spec.rate_hz).next_block(total)
    for seed in (0, 1):
        parts = _pieces(SceneSimulator(spec, spec.rate_hz), total, np.random.default_rng(seed))
        for f in FIELDS:
            got = np.concatenate([getattr(p, f) for p in parts])
            assert np.array_equal(got, getattr(whole, f)), f
    # ones and a block across every segment boundary
    sim = SceneSimulator(spec, spec.rate_hz)
    parts = [sim.next_block(1) for _ in range(POSITION_SEGMENT - 1)]
    parts.append(sim.next_block(total - len(parts)))
    got = np.concatenate([p.position_llh for p in parts])
    assert np.array_equal(got, whole.position_llh)


def test_free_gyro_on_a_moving_base_is_block_independent():
    """The free gyro asks for the case rate at its own sub-step times: those positions come
    from the same segment anchors, whatever the blocks."""
    d = read_scene_dict(find_scene_file("ship"))
    d["free_gyro"] = {"spin_inertia": 1.0e-4, "transverse_inertia": 6.0e-5, "spin_rate": 2513.0,
                      "model": "precession", "initial_angles": [0.0, 0.0]}
    d["gyro"] = {"model": "ideal"}
    spec = SceneSpec.from_dict(d)
    rate, total = 50.0, 2 * POSITION_SEGMENT + 77
    whole = SceneSimulator(spec, rate).next_block(total)
    parts = _pieces(SceneSimulator(spec, rate), total, np.random.default_rng(3))
    for f in ("position_llh", "omega_ib_b"):
        assert np.array_equal(np.concatenate([getattr(p, f) for p in parts]), getattr(whole, f))
    got = np.concatenate([p.gimbal.positions for p in parts])
    assert np.array_equal(got, whole.gimbal.positions)

