"""Sensor-error cases: the Gauss–Markov Allan-variance
series branch, and the exact variance of successive rate-random-walk samples."""

from decimal import Decimal, localcontext

import numpy as np
import pytest

from gyro_attitude.core.sensor_errors import (
    SensorErrorModel,
    SensorErrorParams,
    gauss_markov_allan_variance,
)


def _allan_mp(sigma, tau_c, tau):
    # σ²/x² (2x − 3 + 4e^{−x} − e^{−2x}) in 60-digit decimal: no cancellation left to fear.
    with localcontext() as ctx:
        ctx.prec = 60
        x = Decimal(tau) / Decimal(tau_c)
        return float(Decimal(sigma) ** 2 / x**2 * (2 * x - 3 + 4 * (-x).exp() - (-2 * x).exp()))


@pytest.mark.parametrize("x", [1e-6, 1e-4, 1e-3, 5e-3, 0.0099, 0.0101, 0.05, 3.0, 100.0])
def test_gauss_markov_allan_variance_against_high_precision(x):
    got = gauss_markov_allan_variance(2.0, 10.0, 10.0 * x)
    # series truncation and rounding of the closed form both stay below 1e-9 relative
    assert float(got) == pytest.approx(_allan_mp(2.0, 10.0, 10.0 * x), rel=1e-9, abs=0)


def test_rate_random_walk_successive_difference_variance():
    # Interval averages of a Wiener process K·W: Var(y_{k+1} − y_k) = K² dt (1/4 + 1/4 +
    # 2/12) = 2/3 K² dt exactly.  6e5 differences: standard error ~0.2 %, tolerance 1 %.
    k, dt = 1e-4, 0.01
    y = SensorErrorModel(SensorErrorParams(rate_random_walk=k), dt, seed=11).apply(
        np.zeros((200_001, 3)))
    assert np.diff(y, axis=0).var() == pytest.approx(k * k * dt * 2.0 / 3.0, rel=0.01)
