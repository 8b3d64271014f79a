"""NavFrame time series and their validation."""

import numpy as np
import pytest
from attitude_truth import nav_rate_written_out

from gyro_attitude.core.attitude import NavFrame


@pytest.mark.parametrize("which", ["latitude_rad", "height_m", "velocity_enu"])
def test_any_single_series_makes_a_series_frame(which):
    n = 5
    lat, h, v = 0.6, 200.0, np.array([30.0, -10.0, 1.0])
    series = {"latitude_rad": np.linspace(0.5, 0.7, n), "height_m": np.linspace(0, 900, n),
              "velocity_enu": v + np.arange(n)[:, None]}
    kw = {"latitude_rad": lat, "height_m": h, "velocity_enu": v, which: series[which]}
    nav = NavFrame(**kw)
    assert nav.series_length() == n
    expected = nav_rate_written_out(np.broadcast_to(kw["latitude_rad"], (n,)),
                                    np.broadcast_to(kw["height_m"], (n,)),
                                    np.broadcast_to(kw["velocity_enu"], (n, 3)))
    np.testing.assert_allclose(nav.rate_enu(n), expected, rtol=1e-12, atol=0)
    with pytest.raises(ValueError, match="sample count is needed"):
        nav.rate_enu()
    with pytest.raises(ValueError, match=rf"NavFrame\.{which} has {n} samples, expected 7"):
        nav.rate_enu(7)


def test_constant_frame_is_not_a_series():
    nav = NavFrame(0.6, height_m=10.0, velocity_enu=(1.0, 2.0, 3.0))
    assert nav.series_length() is None
    assert nav.rate_enu().shape == (3,)


@pytest.mark.parametrize("kw", [{"height_m": np.nan}, {"velocity_enu": (0.0, np.inf, 0.0)}])
def test_non_finite_height_or_velocity_is_refused(kw):
    with pytest.raises(ValueError, match="non-finite"):
        NavFrame(0.6, **kw).rate_enu()
