"""Angle wrapping (core/angles.py): ranges and their closed ends, floats and arrays agree."""

import math

import numpy as np
import pytest

from gyro_attitude.core.angles import wrap_2pi, wrap_pi, wrap_pi_closed

ANGLES = [0.0, 1.0, -1.0, math.pi, -math.pi, 2 * math.pi, -2 * math.pi, 3 * math.pi - 0.25,
          -7.5, 1e6, -1e6, 0.5 * math.pi]


@pytest.mark.parametrize("fn, lo, hi, lo_closed", [(wrap_2pi, 0.0, 2 * math.pi, True),
                                                   (wrap_pi, -math.pi, math.pi, True),
                                                   (wrap_pi_closed, -math.pi, math.pi, False)])
def test_each_wrap_lands_in_its_range_on_the_same_angle(fn, lo, hi, lo_closed):
    for a in ANGLES:
        x = fn(a)
        assert (lo <= x < hi) if lo_closed else (lo < x <= hi), (a, x)
        # the same direction: a whole number of turns away
        turns = (a - x) / (2 * math.pi)
        assert abs(turns - round(turns)) < 1e-9 * max(1.0, abs(a))


def test_the_ends_of_the_ranges():
    assert wrap_pi(math.pi) == -math.pi and wrap_pi(-math.pi) == -math.pi
    assert wrap_pi_closed(-math.pi) == math.pi and wrap_pi_closed(math.pi) == math.pi
    assert wrap_2pi(2 * math.pi) == 0.0 and wrap_2pi(-0.5) == pytest.approx(2 * math.pi - 0.5)
    # a heading difference across north: 359° and 1° are 2° apart
    assert math.degrees(wrap_pi(math.radians(1.0) - math.radians(359.0))) == pytest.approx(2.0)


def test_floats_and_arrays_give_the_same_numbers():
    a = np.array(ANGLES)
    for fn in (wrap_2pi, wrap_pi, wrap_pi_closed):
        assert isinstance(fn(1.0), float)
        np.testing.assert_array_equal(fn(a), [fn(x) for x in ANGLES])
