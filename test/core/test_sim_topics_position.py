"""The odometry position of gyro_sim's truth (core/sim_topics.local_enu_position)."""

import math

import numpy as np

from gyro_attitude.core.earth import radii_of_curvature
from gyro_attitude.core.sim_topics import local_enu_position


def test_a_path_across_the_antimeridian_moves_metres_east_not_around_the_earth():
    lat = 0.3
    lon0 = math.pi - 1e-6
    llh0 = np.array([lat, lon0, 10.0])
    # 2e-6 rad east: from just west of +180° to just east of −180°
    llh = np.array([[lat, lon0, 10.0], [lat, -math.pi + 1e-6, 10.0]])
    enu = local_enu_position(llh, llh0)
    r_n = radii_of_curvature(lat)[1]
    expected_east = 2e-6 * (r_n + 10.0) * math.cos(lat)  # ~12 m
    assert abs(enu[1, 0] - expected_east) < 1e-6 * expected_east
    # and westward across it
    enu_w = local_enu_position(np.array([[lat, lon0 - 3e-6, 10.0]]),
                               np.array([lat, -math.pi + 1e-6, 10.0]))
    assert abs(enu_w[0, 0] + 5e-6 * (r_n + 10.0) * math.cos(lat)) < 1e-5
