"""The replay pipeline as a library: ReplayResult, the integration step and its mask."""

from __future__ import annotations

import json
import os
import sys

import numpy as np

import gyro_attitude.offline.replay as replay
from gyro_attitude.core.attitude import integrate_batch
from gyro_attitude.io.imu_fast import read_imu_arrays, read_quaternion_stamped_arrays
from gyro_attitude.io.mcap_writer import Rosbag2McapWriter
from gyro_attitude.offline.replay import AttitudeSeries, ReplayResult, replay_file

os.environ.setdefault("AMENT_PREFIX_PATH", sys.prefix)


def _input(path, n=300):
    t = 5 * 10**9 + np.arange(n, dtype=np.int64) * 2_000_000
    tt = (t - t[0]) * 1e-9
    w = np.stack([0.2 * np.sin(tt), 0.1 + 0 * tt, 0.3 * np.cos(2 * tt)], axis=1)
    with Rosbag2McapWriter(path) as wr:
        wr.add_topic("imu/data_raw", "sensor_msgs/msg/Imu")
        wr.write_imu_array("imu/data_raw", t, w)
    return t, w


def test_result_is_a_dataclass_with_a_json_summary(tmp_path):
    t, w = _input(tmp_path / "in.mcap")
    r = replay_file(tmp_path / "in.mcap", tmp_path / "out.mcap")
    assert isinstance(r, ReplayResult)
    s = r.summary()
    assert not [k for k in s if k.startswith("_")]
    assert not {"t_ns", "q", "valid", "error_t_ns", "error_rad"} & set(s)
    json.dumps(s)  # plain JSON types only
    assert s["messages"] == s["attitude_messages"] == 300 and s["compression"] == "zstd"
    np.testing.assert_array_equal(r.t_ns, t)
    np.testing.assert_allclose(r.q, integrate_batch(t, w), rtol=0, atol=1e-15)
    assert r.valid.all() and r.error_rad.size == 0


def test_integration_step_is_integrate_batch_with_a_full_mask():
    t = np.arange(50, dtype=np.int64) * 10**7
    w = np.tile([0.0, 0.0, 1.0], (50, 1))
    a = replay.integrate_attitude(t, w, (0, 0, 0, 1.0), "rotvec_cubic", None)
    tt = t * 1e-9
    exact = np.stack([0 * tt, 0 * tt, np.sin(tt / 2), np.cos(tt / 2)], axis=1)
    np.testing.assert_allclose(a.q, exact, rtol=0, atol=1e-12)  # constant rate: exact
    assert a.valid.dtype == bool and a.valid.all()


def test_samples_without_attitude_are_not_written(tmp_path, monkeypatch):
    """The mask of the integration step decides what is written (the stream policy's
    hook): masked samples, even NaN, never reach the output."""
    t, w = _input(tmp_path / "in.mcap")
    real = replay.integrate_attitude

    def policy(t_ns, omega, q0, algorithm, nav):
        a = real(t_ns, omega, q0, algorithm, nav)
        valid = np.ones(len(t_ns), dtype=bool)
        valid[10:20] = False
        q = a.q.copy()
        q[10:20] = np.nan
        return AttitudeSeries(q=q, valid=valid)

    monkeypatch.setattr(replay, "integrate_attitude", policy)
    r = replay_file(tmp_path / "in.mcap", tmp_path / "out.mcap")
    assert r.messages == 300 and r.attitude_messages == 290
    att = read_quaternion_stamped_arrays(tmp_path / "out.mcap", "attitude")
    imu = read_imu_arrays(tmp_path / "out.mcap", "imu/data")
    keep = np.r_[0:10, 20:300]
    np.testing.assert_array_equal(att.stamp_ns, t[keep])
    np.testing.assert_array_equal(imu.stamp_ns, t[keep])
    assert np.isfinite(att.quaternion).all()
