"""The shared parameter checks: numbers only (no bool, no string), finite, and the sign asked."""

import math

import numpy as np
import pytest

from gyro_attitude.core.validators import check_finite, check_nonnegative, check_positive


@pytest.mark.parametrize("bad, match", [(True, "must be a number"), ("1.5", "must be a number"),
                                        (None, "must be a number"), ([1.0], "must be a number"),
                                        (math.nan, "must be finite"), (math.inf, "must be finite"),
                                        (-1e300 * 1e10, "must be finite")])
def test_non_numbers_and_non_finite_are_refused_naming_the_parameter(bad, match):
    for check in (check_finite, check_positive, check_nonnegative):
        with pytest.raises(ValueError, match=rf"^spin_rate {match}"):
            check(bad, "spin_rate")


def test_signs_and_accepted_values():
    assert check_positive(np.float32(2.5), "x") == 2.5 and check_nonnegative(0, "x") == 0.0
    assert check_finite(np.array(-3.0), "x") == -3.0
    with pytest.raises(ValueError, match=r"^x must be > 0"):
        check_positive(0.0, "x")
    with pytest.raises(ValueError, match=r"^x must be >= 0"):
        check_nonnegative(-1e-300, "x")
