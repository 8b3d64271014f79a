"""Normal gravity away from the equator and the poles, against the classic Somigliana form."""

import numpy as np

from gyro_attitude.core.earth import WGS84_A, WGS84_F, gravity_enu

_G_POLE = 9.8321849378  # WGS-84 normal gravity at the poles, m/s² (NIMA TR8350.2)
_G_EQUATOR = 9.7803253359


def _somigliana(lat):
    # γ = (a γ_e cos²L + b γ_p sin²L) / √(a² cos²L + b² sin²L): the original form, from which
    # the module's (1 + k sin²L)/√(1 − e² sin²L) is derived.
    a, b = WGS84_A, WGS84_A * (1.0 - WGS84_F)
    c2, s2 = np.cos(lat) ** 2, np.sin(lat) ** 2
    return (a * _G_EQUATOR * c2 + b * _G_POLE * s2) / np.sqrt(a * a * c2 + b * b * s2)


def test_normal_gravity_at_all_latitudes_on_a_grid():
    lat = np.radians(np.array([[-80.0, -45.0, -10.0], [20.0, 45.0, 63.0]]))
    g = gravity_enu(lat)
    assert g.shape == (2, 3, 3)
    np.testing.assert_array_equal(g[..., :2], 0.0)
    # k and e² are rounded to 12 digits in the published constants: agreement ~1e-10.
    np.testing.assert_allclose(-g[..., 2], _somigliana(lat), rtol=2e-10, atol=0)
