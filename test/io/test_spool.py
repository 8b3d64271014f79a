"""Spool: arrays of a recording's length in unlinked files, not in the process's memory."""

from __future__ import annotations

import errno
import mmap
import os

import numpy as np
import pytest

from gyro_attitude.io.spool import Spool, SpoolSpaceError


def _mapped_base(a: np.ndarray):
    b = a
    while isinstance(b, np.ndarray):
        b = b.base
    return b.obj if isinstance(b, memoryview) else b


def test_large_arrays_live_in_an_unlinked_file_and_small_ones_in_memory(tmp_path):
    spool = Spool(tmp_path, min_bytes=4096)
    big = spool.empty((1000, 3), np.float64)
    small = spool.empty(100, np.int64)
    assert isinstance(_mapped_base(big), mmap.mmap)
    assert not isinstance(_mapped_base(small), mmap.mmap)
    big[:] = np.arange(3000.0).reshape(1000, 3)
    assert big.shape == (1000, 3) and big.dtype == np.float64 and big.flags.writeable
    assert big[999, 2] == 2999.0 and big.sum() == sum(range(3000))
    assert spool.spooled_arrays == 1 and spool.spooled_bytes == 24_000
    assert os.listdir(tmp_path) == []  # unlinked at once: nothing to clean up, even after kill -9


def test_a_full_disk_is_one_line_at_allocation_not_a_crash_while_writing(tmp_path, monkeypatch):
    def full(fd, offset, length):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(os, "posix_fallocate", full)
    spool = Spool(tmp_path, min_bytes=0)
    with pytest.raises(SpoolSpaceError) as got:
        spool.empty((1_000_000, 3))
    text = str(got.value)
    assert "\n" not in text and str(tmp_path) in text and "24.0 MB" in text and "free" in text
    assert "reserved there so far" in text
    assert got.value.errno == errno.ENOSPC and isinstance(got.value, OSError)
    assert os.listdir(tmp_path) == []
    # replay's choice: no room keeps the array in memory (counted), as before the spool
    keep = Spool(tmp_path, min_bytes=0, when_full="memory")
    a = keep.empty((1000, 3))
    assert not isinstance(_mapped_base(a), mmap.mmap) and keep.full_fallbacks == 1
    assert keep.spooled_bytes == 0 and os.listdir(tmp_path) == []


def test_a_file_system_that_cannot_reserve_space_keeps_the_array_in_memory(tmp_path,
                                                                           monkeypatch):
    def unsupported(fd, offset, length):
        raise OSError(errno.EOPNOTSUPP, "Operation not supported")

    monkeypatch.setattr(os, "posix_fallocate", unsupported)
    spool = Spool(tmp_path, min_bytes=0)
    a = spool.empty((1000, 4))
    assert not isinstance(_mapped_base(a), mmap.mmap) and a.shape == (1000, 4)
    assert spool.fallbacks == 1 and spool.spooled_bytes == 0 and os.listdir(tmp_path) == []


@pytest.mark.parametrize("bad", [-1, 1.5, True, "16M"])
def test_a_threshold_that_is_not_a_byte_count_is_refused(tmp_path, bad):
    with pytest.raises(ValueError, match="min_bytes"):
        Spool(tmp_path, min_bytes=bad)
    with pytest.raises(ValueError, match="when_full"):
        Spool(tmp_path, when_full="ignore")


def test_a_topic_reordered_into_log_time_order_on_disk_equals_the_one_in_memory(tmp_path):
    from gyro_attitude.io.imu_fast import QuaternionArrays

    rng = np.random.default_rng(1)
    n = 5000
    stamp = np.arange(n, dtype=np.int64) * 1000
    log = stamp + rng.integers(0, 5000, n)  # receive jitter: not in log-time order
    arrays = QuaternionArrays(topic="q", stamp_ns=stamp, log_time_ns=log, publish_time_ns=log,
                              frame_id="f", frame_ids={"f"}, fast_messages=n,
                              fallback_messages=0, damage=None,
                              quaternion=rng.normal(size=(n, 4)))
    spool = Spool(tmp_path, min_bytes=0)
    mem, disk = arrays.in_log_time_order(), arrays.in_log_time_order(spool.empty)
    for name in ("stamp_ns", "log_time_ns", "publish_time_ns", "quaternion"):
        np.testing.assert_array_equal(getattr(disk, name), getattr(mem, name))
    assert (np.diff(disk.log_time_ns) >= 0).all() and disk.publish_time_ns is disk.log_time_ns
    assert isinstance(_mapped_base(disk.quaternion), mmap.mmap) and spool.spooled_arrays == 3


def test_a_declared_count_without_room_is_read_as_the_chunks_come(tmp_path):
    """The reader sizes its columns from the summary's message count; when the allocator has
    no room for that (a forged or a true count), the chunks are read as parts and joined for
    what they hold: the same arrays as an ordinary read."""
    from gyro_attitude.io.imu_fast import read_imu_arrays, read_topic_arrays
    from gyro_attitude.io.mcap_writer import Rosbag2McapWriter

    n = 3000
    t = 10**9 + np.arange(n, dtype=np.int64) * 10**6
    w = np.random.default_rng(3).normal(size=(n, 3))
    with Rosbag2McapWriter(tmp_path / "in.mcap", chunk_size=20_000) as wr:
        wr.add_topic("imu/data_raw", "sensor_msgs/msg/Imu")
        wr.write_imu_array("imu/data_raw", t, w)
    calls = []

    def no_room_at_first(shape, dtype=np.float64):
        calls.append(shape)
        if len(calls) == 1:
            raise SpoolSpaceError(errno.ENOSPC, "no room")
        return np.empty(shape, dtype)

    got = read_topic_arrays(tmp_path / "in.mcap", {"imu/data_raw": "sensor_msgs/msg/Imu"},
                            empty=no_room_at_first)["imu/data_raw"]
    plain = read_imu_arrays(tmp_path / "in.mcap")
    assert calls[0] == n and len(calls) > 1  # the preallocation was tried first
    np.testing.assert_array_equal(got.stamp_ns, plain.stamp_ns)
    np.testing.assert_array_equal(got.angular_velocity, plain.angular_velocity)
    np.testing.assert_array_equal(got.angular_velocity, w)


def test_room_kept_free_for_others_is_not_taken(tmp_path):
    """keep_free: an array that would leave less than that on the file system finds no room
    (replay keeps room for its output so)."""
    import shutil

    free = shutil.disk_usage(tmp_path).free
    keep = Spool(tmp_path, min_bytes=0, when_full="memory", keep_free=free)
    a = keep.empty((1000, 3))
    assert not isinstance(_mapped_base(a), mmap.mmap) and keep.full_fallbacks == 1
    with pytest.raises(SpoolSpaceError, match="free for others"):
        Spool(tmp_path, min_bytes=0, keep_free=free).empty((1000, 3))
    roomy = Spool(tmp_path, min_bytes=0, keep_free=1 << 20)
    assert isinstance(_mapped_base(roomy.empty((1000, 3))), mmap.mmap)
