"""Increment (coning) algorithms in a navigation frame: a case a mutation run showed untested."""

import math

import numpy as np
import pytest
from attitude_truth import Q0, angle_between, nav_rate_written_out
from scipy.spatial.transform import Rotation

from gyro_attitude.core.attitude import ALGORITHMS, NavFrame, integrate_batch

INCR_ALGS = [a for a, i in ALGORITHMS.items() if i.consumes == "increment"]


@pytest.mark.parametrize("quadrature", ["trapezoid", "cubic"])
@pytest.mark.parametrize("algorithm", INCR_ALGS)
def test_body_at_rest_in_nav_stays_put(algorithm, quadrature):
    # Closed form: at rest in ENU the gyro measures C_bn ω_ie^n, constant, so every
    # increment and every ζ are exact and q_nb stays q0.  Ignoring (or adding) the nav rate
    # would turn it by ω_ie·T ≈ 7e-4 rad over these 10 s.
    lat = math.radians(35.0)
    n = 1001
    t_ns = np.arange(n, dtype=np.int64) * 10_000_000
    w = Rotation.from_quat(Q0).inv().apply(nav_rate_written_out(lat, 0.0, (0.0, 0.0, 0.0)))
    q = integrate_batch(t_ns, np.broadcast_to(w, (n, 3)), Q0, algorithm,
                        nav=NavFrame(lat), quadrature=quadrature)
    # round-off of 1000 quaternion products
    assert angle_between(q, np.broadcast_to(Q0, q.shape)).max() < 1e-12
