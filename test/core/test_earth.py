"""WGS-84 Earth model against the closed forms of docs/conventions.md and independent numbers."""

import numpy as np
import pytest

from gyro_attitude.core import earth


def test_radii_at_equator_and_pole_match_ellipsoid_closed_form():
    a, f = 6378137.0, 1 / 298.257223563
    b = a * (1 - f)
    r_m, r_n = earth.radii_of_curvature(np.array([0.0, np.pi / 2]))
    # Equator: R_N = a, R_M = b²/a; pole: both equal a²/b.
    assert r_n[0] == pytest.approx(a, rel=1e-15)
    assert r_m[0] == pytest.approx(b * b / a, rel=1e-14)
    assert r_n[1] == pytest.approx(a * a / b, rel=1e-14)
    assert r_m[1] == pytest.approx(a * a / b, rel=1e-14)


def test_earth_rate_magnitude_and_direction():
    lat = np.radians(np.array([0.0, 30.0, -45.0, 90.0]))
    w = earth.earth_rate_enu(lat)
    assert np.allclose(np.linalg.norm(w, axis=-1), 7.292115e-5, rtol=1e-15)
    assert np.allclose(w[:, 2], 7.292115e-5 * np.sin(lat), rtol=1e-15)
    assert np.all(w[:, 0] == 0.0)


def test_transport_rate_east_and_north():
    lat, h = np.radians(40.0), 1000.0
    r_m, r_n = earth.radii_of_curvature(lat)
    w = earth.transport_rate_enu(lat, h, [100.0, 0.0, 0.0])
    assert w == pytest.approx([0.0, 100.0 / (r_n + h), 100.0 * np.tan(lat) / (r_n + h)], rel=1e-15)
    w = earth.transport_rate_enu(lat, h, [0.0, 50.0, 0.0])
    assert w == pytest.approx([-50.0 / (r_m + h), 0.0, 0.0], rel=1e-15)


def test_normal_gravity_matches_published_wgs84_values():
    # WGS-84 normal gravity: 9.7803253359 at the equator, 9.8321849378 at the poles.
    g = earth.gravity_enu(np.array([0.0, np.pi / 2]))
    assert -g[0, 2] == pytest.approx(9.7803253359, abs=1e-9)
    assert -g[1, 2] == pytest.approx(9.8321849378, abs=1e-9)


@pytest.mark.parametrize("bad", [np.radians(90.5), -2.0, np.nan])
def test_latitude_out_of_range_is_refused(bad):
    with pytest.raises(ValueError, match="latitude"):
        earth.earth_rate_enu(bad)
