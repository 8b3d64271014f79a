"""WGS-84 Earth model in the local ENU navigation frame (textbook §2-3, §2-4; docs/conventions.md).

All functions are batched over leading axes. Latitude ``lat`` and longitude ``lon`` in rad,
height ``h`` in m above the ellipsoid, velocities ``v_enu = (v_E, v_N, v_U)`` in m/s.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "OMEGA_IE",
    "STANDARD_GRAVITY",
    "WGS84_A",
    "WGS84_F",
    "WGS84_E2",
    "check_latitude",
    "radii_of_curvature",
    "earth_rate_enu",
    "transport_rate_enu",
    "nav_rate_enu",
    "position_rate",
    "gravity_enu",
    "enu_to_ecef_matrix",
    "ecef_from_llh",
    "llh_from_ecef",
    "geodetic_from_ecef",
    "normal_gravity",
    "transport_rate_components",
]

OMEGA_IE = 7.292115e-5  # Earth rotation rate, rad/s (WGS-84)
#: Standard gravity g0 (CGPM 1901), m/s²: the unit "g" and the default |f| of an IMU at rest.
STANDARD_GRAVITY = 9.80665
WGS84_A = 6378137.0  # semi-major axis, m
WGS84_F = 1.0 / 298.257223563  # flattening
WGS84_E2 = WGS84_F * (2.0 - WGS84_F)  # first eccentricity squared
WGS84_GM = 3.986004418e14  # m³/s²
# Somigliana normal gravity (WGS-84): equator and pole values and the free-air gradient.
_G_EQUATOR = 9.7803253359
_G_K = 0.00193185265241
_FREE_AIR_1 = 3.0877e-6  # 1/s²
_FREE_AIR_LAT = 4.4e-9  # 1/s² per sin²L
_FREE_AIR_2 = 7.2125e-13  # 1/(m s²): 3 g/a² (second-order free-air term)


def check_latitude(lat, name: str = "latitude") -> np.ndarray:
    """Validate latitudes in rad: finite and within ±π/2 (raises ``ValueError``)."""
    lat = np.asarray(lat, dtype=np.float64)
    if not np.all(np.isfinite(lat)):
        raise ValueError(f"{name} contains non-finite values")
    if np.any(np.abs(lat) > np.pi / 2):
        raise ValueError(f"{name} must lie within ±90° (±π/2 rad), got max |{name}| = "
                         f"{np.degrees(np.max(np.abs(lat))):.6g}°")
    return lat


def radii_of_curvature(lat) -> tuple[np.ndarray, np.ndarray]:
    """Meridian and prime-vertical radii ``(R_M, R_N)`` in m at geodetic latitude ``lat``."""
    lat = check_latitude(lat)
    return _radii(np.sin(lat) ** 2)


def _radii(sin2_lat):
    """``(R_M, R_N)`` from sin²L."""
    d = 1.0 - WGS84_E2 * sin2_lat
    r_n = WGS84_A / np.sqrt(d)
    r_m = WGS84_A * (1.0 - WGS84_E2) / (d * np.sqrt(d))
    return r_m, r_n


def earth_rate_enu(lat) -> np.ndarray:
    """Earth rate ``ω_ie^n = [0, ω_ie cos L, ω_ie sin L]`` in rad/s, shape ``(..., 3)``."""
    lat = check_latitude(lat)
    z = np.zeros_like(lat)
    return np.stack((z, OMEGA_IE * np.cos(lat), OMEGA_IE * np.sin(lat)), axis=-1)


def transport_rate_enu(lat, h, v_enu) -> np.ndarray:
    """Transport rate ``ω_en^n = [−v_N/(R_M+h), v_E/(R_N+h), v_E tan L/(R_N+h)]``.

    The vertical component grows without bound at the poles (tan L); it is the
    formula's own singularity of the ENU frame, not a numerical artefact.
    """
    lat = check_latitude(lat)
    h = np.asarray(h, dtype=np.float64)
    v = np.asarray(v_enu, dtype=np.float64)
    return np.stack(transport_rate_components(np.sin(lat), np.cos(lat), h, v[..., 0],
                                              v[..., 1]), axis=-1)


def transport_rate_components(sin_lat, cos_lat, h, v_east, v_north):
    """The three components of :func:`transport_rate_enu` from sin L and cos L (the form
    :func:`geodetic_from_ecef` gives them in: no trigonometry)."""
    r_m, r_n = _radii(sin_lat * sin_lat)
    east = v_east / (r_n + h)
    return -v_north / (r_m + h), east, east * (sin_lat / cos_lat)


def nav_rate_enu(lat, h=0.0, v_enu=(0.0, 0.0, 0.0)) -> np.ndarray:
    """``ω_in^n = ω_ie^n + ω_en^n``: the rate of the ENU frame against inertial space."""
    return earth_rate_enu(lat) + transport_rate_enu(lat, h, v_enu)


def position_rate(lat, h, v_enu) -> np.ndarray:
    """``(L̇, λ̇, ḣ) = (v_N/(R_M+h), v_E/((R_N+h) cos L), v_U)``, shape ``(..., 3)``."""
    lat = check_latitude(lat)
    h = np.asarray(h, dtype=np.float64)
    v = np.asarray(v_enu, dtype=np.float64)
    r_m, r_n = radii_of_curvature(lat)
    return np.stack(
        (v[..., 1] / (r_m + h), v[..., 0] / ((r_n + h) * np.cos(lat)), v[..., 2]), axis=-1
    )


def gravity_enu(lat, h=0.0) -> np.ndarray:
    """Normal gravity vector ``g^n = [0, 0, −g(L, h)]`` in m/s² (Somigliana + free air).

    This is plumb-bob gravity (gravitation plus centrifugal), so a level accelerometer
    at rest measures specific force ``f^n = −g^n = [0, 0, +g]``.
    """
    lat = check_latitude(lat)
    g = normal_gravity(np.sin(lat) ** 2, np.asarray(h, dtype=np.float64))
    z = np.zeros_like(g)
    return np.stack((z, z, -g), axis=-1)


def normal_gravity(sin2_lat, h):
    """Magnitude g(L, h) of :func:`gravity_enu` (m/s²) from sin²L and the height."""
    g0 = _G_EQUATOR * (1.0 + _G_K * sin2_lat) / np.sqrt(1.0 - WGS84_E2 * sin2_lat)
    return g0 - (_FREE_AIR_1 - _FREE_AIR_LAT * sin2_lat) * h + _FREE_AIR_2 * h * h


def enu_to_ecef_matrix(lat, lon) -> np.ndarray:
    """``C_en`` (..., 3, 3): columns East, North, Up of the ENU frame at (lat, lon) in ECEF."""
    lat = check_latitude(lat)
    lon = np.asarray(lon, dtype=np.float64)
    sl, cl, so, co = np.sin(lat), np.cos(lat), np.sin(lon), np.cos(lon)
    z = np.zeros_like(sl * so)
    east = np.stack((-so + z, co + z, z), axis=-1)
    north = np.stack((-sl * co, -sl * so, cl + z), axis=-1)
    up = np.stack((cl * co, cl * so, sl + z), axis=-1)
    return np.stack((east, north, up), axis=-1)


def ecef_from_llh(llh) -> np.ndarray:
    """Earth-centred Earth-fixed position (m), shape ``(..., 3)``, of geodetic ``(lat, lon, h)``."""
    llh = np.asarray(llh, dtype=np.float64)
    lat = check_latitude(llh[..., 0])
    lon, h = llh[..., 1], llh[..., 2]
    _, r_n = radii_of_curvature(lat)
    cl = np.cos(lat)
    return np.stack(((r_n + h) * cl * np.cos(lon), (r_n + h) * cl * np.sin(lon),
                     (r_n * (1.0 - WGS84_E2) + h) * np.sin(lat)), axis=-1)


def llh_from_ecef(xyz) -> np.ndarray:
    """Geodetic ``(lat, lon, h)`` (rad, rad, m) of ECEF positions ``(..., 3)``
    (:func:`geodetic_from_ecef`)."""
    xyz = np.asarray(xyz, dtype=np.float64)
    lat, lon, h, _, _ = geodetic_from_ecef(xyz[..., 0], xyz[..., 1], xyz[..., 2])
    return np.stack((lat, lon, h), axis=-1)


def geodetic_from_ecef(x, y, z):
    """Geodetic latitude, longitude, height and sin L, cos L of ECEF positions ``x, y, z``.

    Bowring's parametric-latitude start, then Newton-like fixed-point steps on
    ``tan L = (z + e² R_N sin L) / p``; three steps reach float precision for any height
    from the Earth's centre region outward (each step multiplies the error by ~e² h/R).
    Each angle is carried as the pair (numerator, denominator) of its tangent, so the
    steps need square roots only — no arctan2/sin/cos until the latitude itself (that is
    most of the cost on arrays). ``sin L, cos L`` come with it: the local vertical is
    ``(x cos L / p, y cos L / p, sin L) = (x, y, N) / |(p, N)|`` without the longitude.
    Written by hand: numpy/scipy have no geodetic conversion. Lengths are square roots of
    sums of squares, not ``np.hypot`` (~6x the cost on arrays, the largest part of this
    function's): their squares stay finite for |x|, |y|, |z| < 1e145 m, far beyond any
    position near the Earth.
    """
    p = np.sqrt(x * x + y * y)
    b = WGS84_A * np.sqrt(1.0 - WGS84_E2)
    ep2 = WGS84_E2 / (1.0 - WGS84_E2)
    # parametric latitude u: tan u = z a / (p b)
    za, pb = z * WGS84_A, p * b
    r = np.sqrt(za * za + pb * pb)
    su, cu = za / r, pb / r
    num = z + ep2 * b * (su * su * su)
    den = p - WGS84_E2 * WGS84_A * (cu * cu * cu)
    r = np.sqrt(num * num + den * den)
    sl, cl = num / r, den / r
    p2 = p * p
    for _ in range(3):
        r_n = WGS84_A / np.sqrt(1.0 - WGS84_E2 * (sl * sl))
        num = z + WGS84_E2 * r_n * sl
        r = np.sqrt(num * num + p2)
        sl, cl = num / r, p / r
    # height along the normal, stable at every latitude (a²/R_N = a √(1 − e² sin²L))
    h = p * cl + z * sl - WGS84_A * np.sqrt(1.0 - WGS84_E2 * (sl * sl))
    return np.arctan2(num, p), np.arctan2(y, x), h, sl, cl
