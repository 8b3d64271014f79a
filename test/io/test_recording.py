"""A full disk while recording or writing an output: one line naming the file and the free
space, the recording so far finished and readable under its name, nothing hidden left."""

from __future__ import annotations

import numpy as np
import pytest
from mcap.reader import make_reader

from gyro_attitude.cli import main as cli_main
from gyro_attitude.io.mcap_reader import McapStreamReader
from gyro_attitude.io.recording import SafeRecording
from gyro_attitude.io.safe_output import OutputWriteError


def _fill(rec: SafeRecording, topic: str, rng) -> int:
    """Write incompressible 1 kB messages until the disk is full; returns those written."""
    n = 0
    with pytest.raises(OutputWriteError) as info:
        while n < 10_000:
            rec.write(topic, rng.bytes(1000), 1_000_000 + n * 1000)
            n += 1
    rec.failure = str(info.value)
    return n


@pytest.mark.parametrize("bag_directory", [False, True])
def test_full_disk_keeps_the_recording_so_far_readable_under_its_name(small_disk, bag_directory):
    out = small_disk / ("rec" if bag_directory else "rec.mcap")
    rec = SafeRecording(out, compression="", chunk_size=16 * 1024, bag_directory=bag_directory)
    rec.add_topic("/raw", "std_msgs/msg/String")
    written = _fill(rec, "/raw", np.random.default_rng(1))
    line = rec.failure
    assert len(line.splitlines()) == 1
    assert line.startswith(f"{out}: No space left on device (")
    assert " free in " in line and f"finished and readable at {out}" in line
    kept = rec.message_count
    assert 100 < kept < written
    rec.close()  # idempotent after the failure
    assert [p.name for p in small_disk.iterdir()] == [out.name]  # no hidden .partial left
    mcap = next(out.glob("*.mcap")) if bag_directory else out
    # valid MCAP for an independent reader (Data End + Footer, no summary), all kept messages
    with open(mcap, "rb") as f:
        assert sum(1 for _ in make_reader(f).iter_messages()) == kept
    reader = McapStreamReader(mcap)
    assert sum(1 for _ in reader.iter_messages()) == kept
    assert not reader.damages


def test_a_writer_error_that_is_not_a_full_disk_is_not_disguised(tmp_path):
    rec = SafeRecording(tmp_path / "r.mcap")
    rec.add_topic("/raw", "std_msgs/msg/String")
    rec.writer._file.close()  # any other OSError (here: a closed file) stays what it is
    rec.write("/raw", b"\0" * 8, 1)
    with pytest.raises(ValueError, match="closed file"):
        rec.close()


def test_simulate_onto_a_full_disk_names_the_file(small_disk, capsys):
    out = small_disk / "sim.mcap"
    assert cli_main(["simulate", "lab_bench", "--duration", "60", "--rate", "1000",
                     "--out", str(out), "--quiet"]) == 1
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1, err
    assert err.startswith(
        f"gyro-attitude simulate: error: {out}: No space left on device (")
    assert "nothing written under that name" in err
    assert list(small_disk.iterdir()) == []


def _imu_recording(path, n: int = 20_000, rates=None):
    """An MCAP of ``n`` Imu messages at 1 kHz (random rates unless given)."""
    from gyro_attitude.io.mcap_writer import Rosbag2McapWriter

    with Rosbag2McapWriter(path) as wr:
        wr.add_topic("imu/data_raw", "sensor_msgs/msg/Imu")
        wr.write_imu_array("imu/data_raw", 10**9 + np.arange(n, dtype=np.int64) * 10**6,
                           np.random.default_rng(2).normal(size=(n, 3)) if rates is None
                           else rates)
    return path


def test_replay_onto_a_full_disk_names_the_file(small_disk, tmp_path, capsys):
    src = _imu_recording(tmp_path / "in.mcap")
    out = small_disk / "out.mcap"
    assert cli_main(["replay", str(src), "--out", str(out), "--compression", "none",
                     "--no-progress"]) == 1
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1, err
    assert f"{out}: No space left on device (" in err and "nothing written" in err
    assert list(small_disk.iterdir()) == []


def test_replay_whose_working_arrays_do_not_fit_beside_the_output_keeps_them_in_memory(
        small_disk, tmp_path, capsys, monkeypatch):
    """A long recording's columns go to unlinked files beside the output (io/spool.py), their
    space reserved up front (never a SIGBUS from a sparse file filling up). Where there is no
    room for them the replay keeps them in memory, as before the spool, and says so: a replay
    whose output fits still succeeds, and nothing but the output is left on the disk."""
    import json

    import gyro_attitude.io.spool as spool

    monkeypatch.setattr(spool, "SPOOL_MIN_BYTES", 0)
    n = 2000  # a steady turn: the output (~130 kB) fits, the working arrays do not
    src = _imu_recording(tmp_path / "in.mcap", n=n, rates=np.tile([0.0, 0.0, 0.1], (n, 1)))
    out = small_disk / "out.mcap"
    assert cli_main(["replay", str(src), "--out", str(out), "--no-progress", "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    notes = " ".join(got["estimator_notes"])
    assert "kept in memory: no room for them beside the output" in notes
    assert got["attitude_messages"] == n and got["working_bytes_on_disk"] < n * 200
    assert [p.name for p in small_disk.iterdir()] == ["out.mcap"]
