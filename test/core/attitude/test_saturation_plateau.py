"""A saturated gyro holds the largest value its axis reaches (a plateau of 20 ms or more); a
smooth peak whose quantized top value repeats for a few samples, or a repeated local peak below
the axis's largest, is not a clip (BROAD 05 repeats +4.52 rad/s twice on x, then reaches
-5.69 rad/s)."""

import numpy as np
import pytest

from gyro_attitude.core.attitude.offline import estimate_offline
from gyro_attitude.core.attitude.stream import AttitudeStream, StreamConfig

MS = 1_000_000


def peaks(plateau: int, second_peak: float):
    """One smooth bump on x at 200 Hz, a 5 Hz half sine of 4.52 rad/s quantized in 0.01 rad/s
    steps (its top value held ``plateau`` samples), then a larger excursion to
    ``second_peak``."""
    n = 1200
    t = 10**9 + np.arange(n, dtype=np.int64) * 5 * MS
    s = np.arange(n) * 0.005
    w = np.zeros((n, 3))
    bump = s < 0.1
    w[bump, 0] = np.round(4.52 * np.sin(2 * np.pi * 5.0 * s[bump]) / 0.01) * 0.01
    top = int(np.argmax(w[:400, 0]))
    w[top:top + plateau, 0] = w[top, 0]
    w[700:720, 0] = np.linspace(0.0, second_peak, 20)
    return t, w


def counts(t, w):
    cfg = StreamConfig(gyro_bias="none")
    causal = AttitudeStream(config=cfg).run(t, w, "imu").counts["saturated"]
    offline = estimate_offline(t, w, None, config=cfg).counts["saturated"]
    return causal, offline


@pytest.mark.parametrize("plateau", [2, 4])
def test_a_peak_repeated_for_a_few_samples_is_not_a_clip(plateau):
    # 4 samples at 200 Hz span 15 ms: the largest quantized repeat the BROAD gyros show
    t, w = peaks(plateau=plateau, second_peak=-1.0)
    assert counts(t, w) == (0, 0)


@pytest.mark.parametrize("plateau", [6, 25])
def test_a_plateau_at_the_axis_largest_value_is_a_clip(plateau):
    t, w = peaks(plateau=plateau, second_peak=-1.0)  # 4.52 stays the largest
    causal, offline = counts(t, w)
    # from the sample 20 ms into the plateau on (the 5th at 200 Hz)
    assert causal == offline == plateau - 4


def test_offline_does_not_count_a_plateau_below_the_axis_largest_value():
    # the causal step cannot know the larger value to come; the whole-recording count does
    t, w = peaks(plateau=8, second_peak=-5.69)
    causal, offline = counts(t, w)
    assert causal == 4 and offline == 0
