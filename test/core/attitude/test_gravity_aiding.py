"""Gravity aiding: tilt converges at the loop rate k_p from a wrong start, heading untouched,
tilt bias learned, gated during acceleration, stream == batch."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from sim_static import static_imu

from gyro_attitude.core.attitude.gravity_aiding import GravityAiding, gravity_aided_attitude


def _tilt(q_est, q_true):
    u = Rotation.from_quat(q_est).inv().apply([0, 0, 1])
    v = Rotation.from_quat(q_true).inv().apply([0, 0, 1])
    return np.arccos(np.clip(np.sum(u * v, axis=-1), -1, 1))


def test_tilt_error_decays_at_kp_and_heading_is_untouched():
    q_true = Rotation.from_euler("ZYX", [30, 0, 0], degrees=True).as_quat()
    t, g, a = static_imu(2000, 100.0, q_true, 0.0)  # Earth rate ~7e-5: negligible over 20 s
    g[:] = 0.0
    q0 = (Rotation.from_quat(q_true) * Rotation.from_euler("x", 2, degrees=True)).as_quat()
    q, _ = gravity_aided_attitude(t, g, a, q0, kp=0.5, ki=0.0)
    err = _tilt(q, q_true)
    # First-order loop: δ(t) = δ0 e^(−k_p t) (small angles: sin δ ≈ δ).
    k = 200  # t = 2 s
    np.testing.assert_allclose(err[k], np.radians(2) * np.exp(-0.5 * 2.0), rtol=0.02)
    assert err[-1] < 1e-5
    yaw = Rotation.from_quat(q).as_euler("ZYX", degrees=True)[:, 0]
    np.testing.assert_allclose(yaw[-1], 30.0, atol=1e-6)


def test_tilt_bias_is_learned():
    q_true = Rotation.from_euler("ZYX", [0, 0, 0], degrees=True).as_quat()
    t, g, a = static_imu(30000, 100.0, q_true, 0.0)
    g[:] = [1e-3, -2e-3, 0.0]  # horizontal-axis bias, rad/s
    _, bias = gravity_aided_attitude(t, g, a, q_true, kp=1.0, ki=0.05)
    np.testing.assert_allclose(bias[-1, :2], [1e-3, -2e-3], rtol=0.02)


def test_gated_off_under_acceleration_and_stream_equals_batch():
    q_true = Rotation.from_euler("ZYX", [0, 0, 0], degrees=True).as_quat()
    t, g, a = static_imu(500, 100.0, q_true, 0.0, gyro_noise=1e-3, accel_noise=0.05, seed=3)
    a[:, 0] += 5.0  # ‖f‖ ≈ 13.8 m/s²: 4 m/s² off g, beyond the 2 m/s² gate
    a[:, 2] += 3.0
    aid = GravityAiding()
    for k in range(t.size):
        aid.update(int(t[k]), g[k], a[k], q_true)
    assert aid.aided_samples == 0
    t, g, a = static_imu(500, 100.0, q_true, 0.0, gyro_noise=1e-3, accel_noise=0.05, seed=4)
    q, bias = gravity_aided_attitude(t, g, a, q_true)
    from gyro_attitude.core.attitude.streaming import StreamingIntegrator

    aid, integ = GravityAiding(), StreamingIntegrator("exp_map", q0=q_true)
    cur = integ.quaternion
    for k in range(t.size):
        cur = integ.update(int(t[k]), aid.update(int(t[k]), g[k], a[k], cur))
        np.testing.assert_array_equal(cur, q[k])


def test_bad_input():
    with pytest.raises(ValueError, match="kp"):
        GravityAiding(kp=-1)
    with pytest.raises(ValueError, match="accel"):
        GravityAiding().update(0, [0, 0, 0], [np.inf, 0, 0], [0, 0, 0, 1])
    with pytest.raises(ValueError, match="q_nb"):
        GravityAiding().update(0, [0, 0, 0], [0, 0, 9.8], [0, 0, 0])
