"""The shipped hand-held MEMS scene: it loads, the simulator runs it in blocks, and bias
estimation, levelling and tilt aiding bring the end error within the stream's own 3σ
(truth from the simulator's closed-form motion), while the raw gyro is far off."""


import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from gyro_attitude.core.attitude import NavFrame
from gyro_attitude.core.attitude.stream import AttitudeStream, StreamConfig
from gyro_attitude.core.scene.simulator import SceneSimulator
from gyro_attitude.io.scene_file import load_scene


@pytest.fixture(scope="module")
def scene():
    spec = load_scene("handheld_mems")
    sim = SceneSimulator(spec, spec.rate_hz)
    n = int(spec.duration_s * spec.rate_hz)
    blocks = [sim.next_block(1000) for _ in range(n // 1000)]
    gyro_var, accel_var = sim.imu_variances()
    return spec, blocks, gyro_var, accel_var


def _cat(blocks, name):
    return np.concatenate([getattr(b, name) for b in blocks])


def test_scene_loads_and_simulates_blocks(scene):
    spec, blocks, gyro_var, accel_var = scene
    assert spec.motion.__class__.__name__ == "SegmentProfile"
    t = _cat(blocks, "t_ns")
    assert t.size == 4000 and np.all(np.diff(t) == 5_000_000) and t[0] > 0
    v = _cat(blocks, "velocity_enu")
    np.testing.assert_allclose(v[-1], 0.0, atol=1e-9)  # put back: at rest again
    assert np.all(gyro_var > 0) and accel_var is not None


@pytest.mark.parametrize("mode", ["auto", "level", "level_tilt"])
def test_pipeline_on_handheld_scene_within_3_sigma(scene, mode):
    spec, blocks, gyro_var, _ = scene
    t, w, f, q_true = (_cat(blocks, k) for k in ("t_ns", "omega_ib_b", "specific_force_b",
                                                  "truth_q_nb"))
    cov = np.tile(np.diag(gyro_var).reshape(9), (t.size, 1))
    nav = NavFrame(latitude_rad=spec.earth.latitude_rad,
                   height_m=spec.earth.height_m)
    kw = {"gyro_bias_sigma_rad_s": 0.01}
    if mode != "auto":
        kw |= {"initial_attitude_source": "level", "initial_heading_deg": 70.0}  # yaw 20° from east
    kw["aiding"] = "tilt" if mode == "level_tilt" else "none"
    res = AttitudeStream("rotvec_cubic", q0=q_true[0], nav=nav, config=StreamConfig(**kw)).run(
        t, w, "imu", cov, f)
    e = (Rotation.from_quat(res.q[-1]) * Rotation.from_quat(q_true[res.index[-1]]).inv())
    sigma = np.sqrt(res.variance[-1])
    print(f"\nhandheld_mems {mode}: end error {np.degrees(e.as_rotvec()).round(3)}° "
          f"(1σ {np.degrees(sigma).round(3)}°), bias {res.bias.bias.round(5)} rad/s")
    assert np.all(np.abs(e.as_rotvec()) <= 3 * sigma)
    assert res.bias.rests_used == 2 and res.bias.earth_rate_removed
    # the scene's bias (0.0052, -0.0087, 0.0105) rad/s plus bias instability (1.7e-4)
    np.testing.assert_allclose(res.bias.bias, [0.0052, -0.0087, 0.0105], rtol=0, atol=5e-4)
    raw = AttitudeStream("rotvec_cubic", q0=q_true[0], nav=nav, config=StreamConfig(
        gyro_bias="none")).run(t, w, "imu")
    raw_e = Rotation.from_quat(raw.q[-1]) * Rotation.from_quat(q_true[-1]).inv()
    assert raw_e.magnitude() > 20 * e.magnitude()
