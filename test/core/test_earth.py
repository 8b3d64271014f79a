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


# WGS-84 written out here (docs/equations.md, NIMA TR8350.2), not taken from earth.py.
_A, _F = 6378137.0, 1 / 298.257223563
_E2 = _F * (2 - _F)
_OMEGA = 7.292115e-5


def _nav_rate_formula(lat, h, v):
    """ω_ie^n + ω_en^n, docs/equations.md: [0, Ω cos L, Ω sin L] + [−v_N/(R_M+h), v_E/(R_N+h),
    v_E tan L/(R_N+h)], R_M = a(1−e²)/(1−e² sin²L)^1.5, R_N = a/(1−e² sin²L)^0.5."""
    s2 = np.sin(lat) ** 2
    r_m = _A * (1 - _E2) / (1 - _E2 * s2) ** 1.5
    r_n = _A / np.sqrt(1 - _E2 * s2)
    ve, vn = v[..., 0], v[..., 1]
    return np.stack((-vn / (r_m + h), _OMEGA * np.cos(lat) + ve / (r_n + h),
                     _OMEGA * np.sin(lat) + ve * np.tan(lat) / (r_n + h)), axis=-1)


def test_nav_rate_enu_matches_written_out_formulas():
    rng = np.random.default_rng(12)
    lat = rng.uniform(-1.4, 1.4, 50)
    h = rng.uniform(-400.0, 12_000.0, 50)
    v = rng.uniform(-300.0, 300.0, (50, 3))
    got = earth.nav_rate_enu(lat, h, v)
    np.testing.assert_allclose(got, _nav_rate_formula(lat, h, v), rtol=1e-13, atol=0)
    # The transport part alone (Earth rate removed): signs and sizes, ~1e-5 rad/s.
    transport = got - earth.nav_rate_enu(lat, h, np.zeros_like(v))
    expected = _nav_rate_formula(lat, h, v) - _nav_rate_formula(lat, h, np.zeros_like(v))
    np.testing.assert_allclose(transport, expected, rtol=1e-9, atol=0)


def _normal_gravity_at_height(lat, h):
    """TR8350.2 eq. (4-3): g_h = g(L)·[1 − 2/a (1 + f + m − 2f sin²L) h + 3 h²/a²] with
    m = ω² a² b / GM and Somigliana's g(L) = g_e (1 + k sin²L)/√(1 − e² sin²L)."""
    gm = 3.986004418e14
    b = _A * (1 - _F)
    m = _OMEGA**2 * _A**2 * b / gm
    s2 = np.sin(lat) ** 2
    g0 = 9.7803253359 * (1 + 0.00193185265241 * s2) / np.sqrt(1 - _E2 * s2)
    return g0 * (1 - 2 / _A * (1 + _F + m - 2 * _F * s2) * h + 3 * h**2 / _A**2)


@pytest.mark.parametrize("h", [1.0, 1000.0, 10_000.0])
def test_gravity_decrease_with_height_matches_free_air_formula(h):
    """The decrease g(L, 0) − g(L, h) (3e-6 .. 3e-2 m/s²) against the published formula,
    relative 2e-4 (earth.py rounds the gradient coefficients), atol=0."""
    lat = np.radians(np.array([0.0, 30.0, 47.0, 90.0]))
    drop = -earth.gravity_enu(lat, 0.0)[:, 2] + earth.gravity_enu(lat, h)[:, 2]
    expected = _normal_gravity_at_height(lat, 0.0) - _normal_gravity_at_height(lat, h)
    np.testing.assert_allclose(drop, expected, rtol=2e-4, atol=0)
