"""Helpers of the rotation tests: scipy as the independent oracle, random and edge-case inputs."""

import warnings

import numpy as np
from scipy.spatial.transform import Rotation

DEG = np.pi / 180.0


def scipy_angle(q1, q2):
    """Rotation angle between two attitudes, computed by scipy."""
    return (Rotation.from_quat(q1).inv() * Rotation.from_quat(q2)).magnitude()


def random_quats(n, seed):
    q = np.random.default_rng(seed).normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def edge_rotvecs():
    """Identity, 1e-12 rad, 90°, 180°, 179.999° about coordinate and skew axes."""
    axes = np.array(
        [[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0], [1, -2, 3], [-0.3, 0.1, -0.9]], float
    )
    axes /= np.linalg.norm(axes, axis=-1, keepdims=True)
    angles = np.array([0.0, 1e-12, 1e-8, 90 * DEG, 180 * DEG, 179.999 * DEG, 1e-4, 0.99e-4])
    return (angles[:, None, None] * axes[None, :, :]).reshape(-1, 3)


def quiet(fn, *args, **kw):
    """Call ignoring the gimbal-lock UserWarning (tested separately)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        return fn(*args, **kw)
