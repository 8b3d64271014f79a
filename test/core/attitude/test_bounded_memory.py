"""The causal chain's array form works on long recordings in bounded chunks (covariance, rest
statistics, the sums of a rest, saturation counts): any chunk size gives the same numbers bit for
bit, because each chunk carries its state into the next as one sample carries it into the next."""

import numpy as np
import pytest
from test_stream_real import MODES, hostile_rest_motion_rest

import gyro_attitude.core.attitude.gyro_bias as gb
import gyro_attitude.core.attitude.rest as rest
import gyro_attitude.core.attitude.stream_batch as sb
from gyro_attitude.core.attitude.stream import AttitudeStream


@pytest.mark.parametrize("mode", ["auto_noise", "level", "auto_enu", "parameter"])
def test_small_chunks_give_the_same_bits(mode, monkeypatch):
    t, g, a, cov = hostile_rest_motion_rest()
    g = g.copy()
    g[300:303, 2] = 40.0  # a pinned (saturated) stretch across a chunk boundary
    whole = AttitudeStream("rotvec_cubic", config=MODES[mode]).run(t, g, "imu", cov, a)
    for module, name in ((sb, "COVARIANCE_CHUNK"), (gb, "_REST_CHUNK"), (rest, "_STATS_CHUNK")):
        monkeypatch.setattr(module, name, 97)  # a prime: boundaries inside rests and motion
    parts = AttitudeStream("rotvec_cubic", config=MODES[mode]).run(t, g, "imu", cov, a)
    assert np.array_equal(whole.q, parts.q) and np.array_equal(whole.index, parts.index)
    assert np.array_equal(whole.variance, parts.variance)
    assert whole.counts == parts.counts and whole.counts["saturated"] >= 2
    assert np.array_equal(whole.bias.bias, parts.bias.bias)
