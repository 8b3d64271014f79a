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
    s2 = np.sin(lat) ** 2
    d = 1.0 - WGS84_E2 * s2
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
    r_m, r_n = radii_of_curvature(lat)
    ve, vn = v[..., 0], v[..., 1]
    return np.stack(
        (-vn / (r_m + h), ve / (r_n + h), ve * np.tan(lat) / (r_n + h)), axis=-1
    )


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
    h = np.asarray(h, dtype=np.float64)
    s2 = np.sin(lat) ** 2
    g0 = _G_EQUATOR * (1.0 + _G_K * s2) / np.sqrt(1.0 - WGS84_E2 * s2)
    g = g0 - (_FREE_AIR_1 - _FREE_AIR_LAT * s2) * h + _FREE_AIR_2 * h * h
    z = np.zeros_like(g)
    return np.stack((z, z, -g), axis=-1)


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
    """Geodetic ``(lat, lon, h)`` (rad, rad, m) of ECEF positions ``(..., 3)``.

    Bowring's parametric-latitude start, then Newton-like fixed-point steps on
    ``tan L = (z + e² R_N sin L) / p``; three steps reach float precision for any height
    from the Earth's centre region outward (each step multiplies the error by ~e² h/R).
    Written by hand: numpy/scipy have no geodetic conversion.
    """
    xyz = np.asarray(xyz, dtype=np.float64)
    x, y, z = xyz[..., 0], xyz[..., 1], xyz[..., 2]
    p = np.hypot(x, y)
    b = WGS84_A * np.sqrt(1.0 - WGS84_E2)
    ep2 = WGS84_E2 / (1.0 - WGS84_E2)
    u = np.arctan2(z * WGS84_A, p * b)
    lat = np.arctan2(z + ep2 * b * np.sin(u) ** 3, p - WGS84_E2 * WGS84_A * np.cos(u) ** 3)
    for _ in range(3):
        r_n = WGS84_A / np.sqrt(1.0 - WGS84_E2 * np.sin(lat) ** 2)
        lat = np.arctan2(z + WGS84_E2 * r_n * np.sin(lat), p)
    sl, cl = np.sin(lat), np.cos(lat)
    r_n = WGS84_A / np.sqrt(1.0 - WGS84_E2 * sl * sl)
    # height along the normal, stable at every latitude
    h = p * cl + z * sl - WGS84_A * WGS84_A / r_n
    return np.stack((lat, np.arctan2(y, x), h), axis=-1)
