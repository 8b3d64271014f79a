"""The shipped sample recording: small, deterministic, and physically the coning of docs/equations.md."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from gyro_attitude.io.imu_fast import read_imu_arrays, read_quaternion_stamped_arrays
from gyro_attitude.io.make_sample_bag import SAMPLE_NAME, make_sample_bag

REPO = Path(__file__).resolve().parents[2]
SAMPLE = REPO / "bags" / SAMPLE_NAME


def test_regeneration_is_deterministic(tmp_path):
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    a, b = tmp_path / "a" / "s.mcap", tmp_path / "b" / "s.mcap"  # same name: it is recorded
    counts = make_sample_bag(a, seconds=2.0)
    make_sample_bag(b, seconds=2.0)
    assert counts == {"/imu/data_raw": 400, "/truth/attitude": 400}
    assert a.read_bytes() == b.read_bytes()


def test_shipped_sample_is_small_and_is_classical_coning():
    assert SAMPLE.stat().st_size < 2 * 1024 * 1024
    imu = read_imu_arrays(SAMPLE)
    truth = read_quaternion_stamped_arrays(SAMPLE)
    assert len(imu) == len(truth) == 4000  # 20 s at 200 Hz
    np.testing.assert_array_equal(np.diff(imu.stamp_ns), 5_000_000)
    np.testing.assert_array_equal(imu.stamp_ns, truth.stamp_ns)
    # docs/equations.md closed form, half-angle 1 deg at 10 Hz (config/scenes/coning.yaml), ideal gyro
    a, om = np.radians(1.0), 2 * np.pi * 10.0
    t = (imu.stamp_ns - imu.stamp_ns[0]) * 1e-9
    w = np.stack([np.full_like(t, -2 * om * np.sin(a / 2) ** 2), -om * np.sin(a) * np.sin(om * t),
                  om * np.sin(a) * np.cos(om * t)], 1)
    q = np.stack([0 * t, np.sin(a / 2) * np.cos(om * t), np.sin(a / 2) * np.sin(om * t),
                  np.full_like(t, np.cos(a / 2))], 1)
    np.testing.assert_allclose(imu.angular_velocity, w, atol=1e-9)
    dots = np.abs(np.sum(truth.quaternion * q, axis=1))  # sign-immune
    np.testing.assert_allclose(dots, 1.0, atol=1e-12)


def test_shipped_sample_is_in_log_time_order_across_topics():
    """What `mcap doctor --strict-message-order` checks, with the mcap package's reader."""
    from mcap.reader import make_reader

    with open(SAMPLE, "rb") as f:
        logs = [(ch.topic, m.log_time)
                for _, ch, m in make_reader(f, validate_crcs=True).iter_messages(
                    log_time_order=False)]
    assert len(logs) == 8000
    assert all(a[1] <= b[1] for a, b in zip(logs, logs[1:], strict=False))
    assert {t for t, _ in logs[:2]} == {"/imu/data_raw", "/truth/attitude"}  # interleaved
