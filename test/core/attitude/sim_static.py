"""Synthetic IMU samples for the attitude building-block tests, written out from the formulas.

Not the package's simulator: truth comes from closed forms here (Earth rate rotated into the body,
gravity +g up, constant bias, white noise), so the tests check the code against physics.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

OMEGA_IE = 7.292115e-5
G = 9.80665


def static_imu(n, rate_hz, q_nb, lat_rad, gyro_bias=(0, 0, 0), gyro_noise=0.0, accel_bias=(0, 0, 0),
               accel_noise=0.0, seed=0, t0_ns=0):
    """(t_ns, gyro, accel) of a body at rest at attitude q_nb (x, y, z, w) in ENU at lat_rad."""
    rng = np.random.default_rng(seed)
    c_bn = Rotation.from_quat(q_nb).inv()
    w_n = np.array([0.0, OMEGA_IE * np.cos(lat_rad), OMEGA_IE * np.sin(lat_rad)])
    f_n = np.array([0.0, 0.0, G])
    t = t0_ns + np.round(np.arange(n) * 1e9 / rate_hz).astype(np.int64)
    gyro = c_bn.apply(w_n) + np.asarray(gyro_bias) + gyro_noise * rng.standard_normal((n, 3))
    accel = c_bn.apply(f_n) + np.asarray(accel_bias) + accel_noise * rng.standard_normal((n, 3))
    return t, np.broadcast_to(gyro, (n, 3)).copy(), np.broadcast_to(accel, (n, 3)).copy()


def rest_motion_rest(rate_hz=200.0, rests=(3.0, 2.0, 3.0), motions=(2.0, 1.5), bias=(0.008, -0.004, 0.01),
                     gyro_noise=0.002, accel_noise=0.03, seed=1):
    """Alternating rest/motion gyro+accel with the true motion mask (rest = True).

    Motion: rotation rate 1 rad/s·sin about a tilted axis and a ±2 m/s² shake (a hand-held
    gesture); the accelerometer shows the shake on top of gravity.
    """
    rng = np.random.default_rng(seed)
    parts, mask = [], []
    for i, r in enumerate(rests):
        parts.append(("rest", r))
        if i < len(motions):
            parts.append(("move", motions[i]))
    gyro, accel = [], []
    for kind, dur in parts:
        n = int(round(dur * rate_hz))
        s = np.arange(n) / rate_hz
        w = np.zeros((n, 3))
        f = np.tile([0.0, 0.0, G], (n, 1))
        if kind == "move":
            w += np.outer(np.sin(2 * np.pi * s / dur) * 1.0, [0.6, 0.0, 0.8])
            f[:, 0] += 2.0 * np.sin(4 * np.pi * s / dur)
        gyro.append(w)
        accel.append(f)
        mask.append(np.full(n, kind == "rest"))
    n_all = sum(len(m) for m in mask)
    gyro = np.concatenate(gyro) + np.asarray(bias) + gyro_noise * rng.standard_normal((n_all, 3))
    accel = np.concatenate(accel) + accel_noise * rng.standard_normal(gyro.shape)
    t = np.round(np.arange(gyro.shape[0]) * 1e9 / rate_hz).astype(np.int64)
    return t, gyro, accel, np.concatenate(mask)
