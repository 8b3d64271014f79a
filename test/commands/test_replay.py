"""``gyro-attitude replay``: offline integration of recorded Imu messages."""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from scipy.spatial.transform import Rotation

from gyro_attitude.cli import main as cli_main
from gyro_attitude.core.attitude import NavFrame, integrate_batch
from gyro_attitude.core.attitude.settings import StreamConfig
from gyro_attitude.io.cdr_arrays import imu_batch, quaternion_stamped_batch
from gyro_attitude.io.imu_fast import read_imu_arrays, read_quaternion_stamped_arrays
from gyro_attitude.io.mcap_writer import Rosbag2McapWriter
from gyro_attitude.offline.replay import replay_file

os.environ.setdefault("AMENT_PREFIX_PATH", sys.prefix)
REPO = Path(__file__).resolve().parents[2]
IMU = "sensor_msgs/msg/Imu"
QS = "geometry_msgs/msg/QuaternionStamped"


def _record(path, t, w, a=None, truth=None, shuffle=None):
    with Rosbag2McapWriter(path, chunk_size=50_000) as wr:
        wr.add_topic("imu/data_raw", IMU)
        idx = np.arange(t.size) if shuffle is None else shuffle
        # shuffled: stamps out of order, log times (receive times) increasing in file order
        log = t[idx] + 1000 if shuffle is None else np.sort(t[idx]) + 1000
        wr.write_imu_array("imu/data_raw", t[idx], w[idx], None if a is None else a[idx],
                           log_time_ns=log)
        if truth is not None:
            wr.add_topic("truth/attitude", QS)
            wr.write_quaternion_stamped_array("truth/attitude", t, truth, frame_id="enu")


def _tumbling(n, rate_hz=400.0, seed=0):
    rng = np.random.default_rng(seed)
    t = 2 * 10**9 + (np.arange(n, dtype=np.int64) * 10**9) // int(rate_hz)
    tt = (t - t[0]) * 1e-9
    w = np.stack([0.3 * np.sin(2.1 * tt), 0.2 * np.cos(1.3 * tt), 0.5 + 0.1 * tt], axis=1)
    return t, w + 1e-3 * rng.normal(size=w.shape)


@pytest.mark.parametrize("algorithm", ["rotvec_cubic", "coning2", "quat_first_order"])
def test_replay_equals_integrate_batch_inertial(tmp_path, algorithm):
    t, w = _tumbling(3001)
    _record(tmp_path / "in.mcap", t, w)
    q0 = np.array([0.1, -0.2, 0.3, 0.9]) / np.linalg.norm([0.1, -0.2, 0.3, 0.9])
    s = replay_file(tmp_path / "in.mcap", tmp_path / "out.mcap", algorithm=algorithm,
                    initial_attitude=q0)
    expected = integrate_batch(t, w, q0=q0, algorithm=algorithm)
    att = read_quaternion_stamped_arrays(tmp_path / "out.mcap", "attitude")
    np.testing.assert_allclose(att.quaternion, expected, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(att.stamp_ns, t)
    np.testing.assert_array_equal(att.log_time_ns, t + 1000)  # input log times kept
    assert att.frame_id == "inertial"
    imu = read_imu_arrays(tmp_path / "out.mcap", "imu/data")
    np.testing.assert_allclose(imu.orientation, expected, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(imu.angular_velocity, w)
    assert s.messages == 3001 and s.fast_path_messages == 3001
    assert s.truth_matched == 0 and s.final_error_rad is None


def test_replay_equals_integrate_batch_enu(tmp_path):
    t, w = _tumbling(2000, seed=1)
    _record(tmp_path / "in.mcap", t, w)
    nav = NavFrame(latitude_rad=np.radians(45.0), height_m=100.0,
                   velocity_enu=np.array([10.0, 5.0, 0.0]))
    replay_file(tmp_path / "in.mcap", tmp_path / "out.mcap", frame="enu", nav=nav,
                algorithm="rotvec_cubic")
    expected = integrate_batch(t, w, nav=nav)
    att = read_quaternion_stamped_arrays(tmp_path / "out.mcap", "attitude")
    np.testing.assert_allclose(att.quaternion, expected, rtol=0, atol=1e-12)
    assert att.frame_id == "enu"


def test_output_is_read_by_mcap_ros2(tmp_path):
    t, w = _tumbling(50)
    _record(tmp_path / "in.mcap", t, w, a=np.tile([0.0, 0.0, 9.8], (50, 1)))
    replay_file(tmp_path / "in.mcap", tmp_path / "out.mcap", algorithm="rotvec_cubic",
                config=StreamConfig(aiding="none"))  # the gyro alone: integrate_batch's
    q = integrate_batch(t, w)
    with open(tmp_path / "out.mcap", "rb") as f:
        reader = make_reader(f, validate_crcs=True, decoder_factories=[DecoderFactory()])
        seen = {"/attitude": 0, "/imu/data": 0}
        for _, ch, m, d in reader.iter_decoded_messages(log_time_order=False):
            k = seen[ch.topic]
            seen[ch.topic] += 1
            qq = d.quaternion if ch.topic == "/attitude" else d.orientation
            np.testing.assert_allclose([qq.x, qq.y, qq.z, qq.w], q[k], atol=1e-15)
            assert m.log_time == t[k] + 1000
            if ch.topic == "/imu/data":
                assert d.linear_acceleration.z == 9.8
                assert d.header.frame_id == "imu_link"
    assert seen == {"/attitude": 50, "/imu/data": 50}


def test_truth_errors_against_closed_form(tmp_path):
    """Constant rate about z: q(t) = [0, 0, sin(ω t/2), cos(ω t/2)] exactly, which every
    algorithm reproduces; a truth offset by a known 0.1 rad about x is reported as 0.1."""
    n, omega = 1001, 0.7
    t = 10**9 + np.arange(n, dtype=np.int64) * 1_000_000
    tt = (t - t[0]) * 1e-9
    w = np.tile([0.0, 0.0, omega], (n, 1))
    exact = np.stack([0 * tt, 0 * tt, np.sin(omega * tt / 2), np.cos(omega * tt / 2)], 1)
    _record(tmp_path / "good.mcap", t, w, truth=exact)
    s = replay_file(tmp_path / "good.mcap", tmp_path / "o1.mcap")
    assert s.truth_matched == n and s.max_error_rad < 1e-9
    # truth = (0.1 rad about the reference x axis) ⊗ exact: the same motion seen from a
    # reference frame tilted by 0.1 rad, so the error angle is 0.1 throughout.
    shifted = (Rotation.from_rotvec([0.1, 0.0, 0.0]) * Rotation.from_quat(exact)).as_quat()
    _record(tmp_path / "off.mcap", t, w, truth=shifted)
    s = replay_file(tmp_path / "off.mcap", tmp_path / "o2.mcap")
    assert abs(s.final_error_rad - 0.1) < 1e-9 and abs(s.max_error_rad - 0.1) < 1e-9
    # 'truth' initial attitude: starts on the (shifted) truth, error back to ~0
    s = replay_file(tmp_path / "off.mcap", tmp_path / "o3.mcap", initial_attitude="truth")
    assert s.max_error_rad < 1e-9


def test_samples_are_never_sorted_out_of_order_ones_skipped_duplicates_counted(tmp_path):
    """File order is the stream order (as a live node receives it): a shuffled recording is
    not re-sorted; samples stamped before the last accepted one are skipped as out of order
    (backward steps under the 1 s time-jump threshold), a repeated stamp as a duplicate."""
    t, w = _tumbling(500, seed=2)
    order = np.arange(500)
    order[[100, 101]] = order[[101, 100]]  # one swapped pair
    order = np.concatenate([order, [499]])  # and a repeated last sample
    _record(tmp_path / "in.mcap", t, w, shuffle=order)
    s = replay_file(tmp_path / "in.mcap", tmp_path / "out.mcap", algorithm="exp_map")
    assert s.skipped["out_of_order"] == 1 and s.skipped["duplicate_stamp"] == 1
    assert s.attitude_messages == 499
    att = read_quaternion_stamped_arrays(tmp_path / "out.mcap", "attitude")
    keep = np.delete(np.arange(500), 100)  # sample 100 came after 101: skipped
    np.testing.assert_array_equal(att.stamp_ns, t[keep])
    np.testing.assert_allclose(att.quaternion, integrate_batch(t[keep], w[keep],
                                                               algorithm="exp_map"),
                               atol=1e-12, rtol=0)


def test_cli_json_plot_and_errors(tmp_path, capsys):
    sample = REPO / "bags" / "coning_200hz.mcap"
    png = tmp_path / "err.png"
    rc = cli_main(["replay", str(sample), "--out", str(tmp_path / "o.mcap"), "--json",
                   "--plot", str(png), "--initial-attitude", "truth", "--algorithm", "coning4"])
    assert rc == 0
    out = json.loads(capsys.readouterr().out)
    assert out["messages"] == 4000 and out["truth_matched"] == 4000
    assert out["messages_per_second"] > 0 and out["wall_seconds"] > 0
    assert 0 <= out["final_error_rad"] <= out["max_error_rad"] < 0.01
    assert png.stat().st_size > 1000
    rc = cli_main(["replay", str(sample), "--out", str(tmp_path / "o2.mcap"), "--imu-topic",
                   "nope"])
    assert rc == 1 and "no Imu topic 'nope'" in capsys.readouterr().err
    rc = cli_main(["replay", str(sample), "--out", str(tmp_path / "o3.mcap"), "--frame", "enu"])
    assert rc == 2 and "--latitude-deg" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        cli_main(["replay", str(sample), "--out", "x.mcap", "--initial-attitude", "1,2"])
    rc = cli_main(["replay", str(sample), "--out", str(tmp_path / "enu.mcap"), "--frame", "enu",
                   "--latitude-deg", "45", "--height-m", "10", "--velocity-enu", "1,2,0",
                   "--algorithm", "rotvec_cubic", "--json"])
    out = json.loads(capsys.readouterr().out)
    assert rc == 0 and out["frame"] == "enu"
    imu = read_imu_arrays(sample)
    nav = NavFrame(latitude_rad=np.radians(45.0), height_m=10.0,
                   velocity_enu=np.array([1.0, 2.0, 0.0]))
    att = read_quaternion_stamped_arrays(tmp_path / "enu.mcap", "attitude")
    np.testing.assert_allclose(att.quaternion, integrate_batch(imu.stamp_ns, imu.angular_velocity,
                                                               nav=nav), atol=1e-12, rtol=0)


def test_damaged_input_replays_what_precedes_the_damage(tmp_path, capsys):
    t, w = _tumbling(1000, seed=4)
    wr = Rosbag2McapWriter(tmp_path / "killed.mcap", chunk_size=10_000)
    wr.add_topic("imu/data_raw", IMU)
    wr.write_imu_array("imu/data_raw", t, w)
    wr.abandon()  # like kill -9: no summary, no footer
    rc = cli_main(["replay", str(tmp_path / "killed.mcap"), "--out", str(tmp_path / "o.mcap")])
    captured = capsys.readouterr()
    assert rc == 0 and "warning: input damaged" in captured.err
    assert "replayed 1000 Imu messages" in captured.out


def _one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


def _listing(d):
    return sorted(p.name for p in d.iterdir())


def test_output_never_overwrites_the_input(tmp_path, capsys):
    t, w = _tumbling(200)
    src = tmp_path / "in.mcap"
    _record(src, t, w)
    before = src.read_bytes()
    bag = tmp_path / "bag"
    bag.mkdir()
    (bag / "bag_0.mcap").write_bytes(before)
    (tmp_path / "link.mcap").symlink_to(src)
    for inp, out in [(src, src), (src, tmp_path / "link.mcap"), (tmp_path / "link.mcap", src),
                     (bag, bag / "bag_0.mcap")]:
        rc = cli_main(["replay", str(inp), "--out", str(out), "--force"])
        assert rc == 1 and "is the input" in _one_line(capsys.readouterr().err)
    assert src.read_bytes() == before and (bag / "bag_0.mcap").read_bytes() == before


def test_existing_output_needs_force(tmp_path, capsys):
    t, w = _tumbling(200)
    _record(tmp_path / "in.mcap", t, w)
    out = tmp_path / "out.mcap"
    out.write_bytes(b"precious")
    rc = cli_main(["replay", str(tmp_path / "in.mcap"), "--out", str(out)])
    assert rc == 1 and "exists (use --force" in _one_line(capsys.readouterr().err)
    assert out.read_bytes() == b"precious"
    assert cli_main(["replay", str(tmp_path / "in.mcap"), "--out", str(out), "--force"]) == 0
    assert len(read_quaternion_stamped_arrays(out, "attitude")) == 200
    assert _listing(tmp_path) == ["in.mcap", "out.mcap"]  # no temporary file left


def test_absurd_rate_is_skipped_counted_and_never_nan(tmp_path, capsys):
    t, w = _tumbling(2000)
    w[100] = [1e155, 1e155, 0.0]  # finite, but it would overflow any attitude update
    _record(tmp_path / "in.mcap", t, w)
    rc = cli_main(["replay", str(tmp_path / "in.mcap"), "--out", str(tmp_path / "o.mcap"),
                   "--json"])
    cap = capsys.readouterr()
    assert rc == 0
    out = json.loads(cap.out)
    assert out["skipped"]["implausible_rate"] == 1 and out["attitude_messages"] == 1999
    warnings = [ln for ln in cap.err.splitlines() if ln.startswith("warning:")]
    assert len(warnings) == 1 and "implausible_rate" in warnings[0]
    att = read_quaternion_stamped_arrays(tmp_path / "o.mcap", "attitude")
    assert len(att) == 1999 and np.isfinite(att.quaternion).all()
    # a recording with no usable sample at all is an error, and writes nothing
    w[:] = np.nan
    _record(tmp_path / "nan.mcap", t, w)
    rc = cli_main(["replay", str(tmp_path / "nan.mcap"), "--out", str(tmp_path / "o2.mcap")])
    line = _one_line(capsys.readouterr().err)
    assert rc == 1 and "no usable sample" in line and "2000 non_finite" in line
    assert not (tmp_path / "o2.mcap").exists()


@pytest.mark.parametrize("content, message", [
    (b"", "empty file"),
    (b"PK\x03\x04 a zip file, not MCAP", "not an MCAP file (bad magic)"),
])
def test_unusable_files_say_what_is_wrong(tmp_path, capsys, content, message):
    (tmp_path / "in.mcap").write_bytes(content)
    rc = cli_main(["replay", str(tmp_path / "in.mcap"), "--out", str(tmp_path / "o.mcap")])
    assert rc == 1 and message in _one_line(capsys.readouterr().err)
    assert _listing(tmp_path) == ["in.mcap"]


def test_file_cut_inside_its_first_chunk_names_the_damage(tmp_path, capsys):
    t, w = _tumbling(2000)
    _record(tmp_path / "full.mcap", t, w)
    raw = (tmp_path / "full.mcap").read_bytes()
    with open(tmp_path / "full.mcap", "rb") as f:
        first = make_reader(f).get_summary().chunk_indexes[0]
    (tmp_path / "in.mcap").write_bytes(raw[:first.chunk_start_offset + 100])
    rc = cli_main(["replay", str(tmp_path / "in.mcap"), "--out", str(tmp_path / "o.mcap")])
    line = _one_line(capsys.readouterr().err)
    assert rc == 1 and "has no messages" in line
    assert f"damaged at byte {first.chunk_start_offset}" in line


def test_output_paths_are_checked_before_the_work(tmp_path, capsys):
    sample = REPO / "bags" / "coning_200hz.mcap"
    out = tmp_path / "o.mcap"
    rc = cli_main(["replay", str(sample), "--out", str(out), "--plot",
                   str(tmp_path / "no_such_dir" / "err.png")])
    assert rc == 1 and "plot directory" in _one_line(capsys.readouterr().err)
    assert not out.exists()
    rc = cli_main(["replay", str(sample), "--out", str(tmp_path / "nodir" / "o.mcap")])
    assert rc == 1 and "does not exist" in _one_line(capsys.readouterr().err)


@pytest.mark.parametrize("extra, flag", [
    (["--truth-topic", "imu/data_raw"], "--truth-topic"),
    (["--truth-topic", "/imu/data_raw"], "--truth-topic"),
    (["--odometry-topic", "truth/attitude", "--frame", "enu", "--latitude-deg", "45"],
     "--odometry-topic"),
    (["--aiding", "magnetometer", "--mag-topic", "imu/data_raw"], "--mag-topic"),
])
def test_one_topic_given_two_roles_is_refused_in_one_line(tmp_path, capsys, extra, flag):
    """The reader keeps one message type per topic: a topic named for the Imu and the truth
    (or odometry, or the field) would be decoded as the wrong one."""
    sample = REPO / "bags" / "coning_200hz.mcap"
    out = tmp_path / "o.mcap"
    rc = cli_main(["replay", str(sample), "--out", str(out), "--imu-topic", "imu/data_raw",
                   *extra])
    line = _one_line(capsys.readouterr().err)
    assert rc == 1 and "each need their own topic" in line and line.startswith(
        f"gyro-attitude replay: error: {flag}:")
    assert not out.exists()


def test_bad_arguments_one_line_exit_2(tmp_path, capsys):
    sample = REPO / "bags" / "coning_200hz.mcap"
    for extra in (["--latitude-deg", "nan", "--frame", "enu"], ["--compression", "gzip"],
                  ["--initial-attitude", "1,2"], ["--velocity-enu", "1,inf,0"]):
        with pytest.raises(SystemExit) as exc:
            cli_main(["replay", str(sample), "--out", str(tmp_path / "o.mcap"), *extra])
        assert exc.value.code == 2
        assert "error:" in _one_line(capsys.readouterr().err)
    assert _listing(tmp_path) == []


def test_interrupt_leaves_no_partial_output(tmp_path, capsys, monkeypatch):
    import gyro_attitude.io.mcap_writer as mw

    sample = REPO / "bags" / "coning_200hz.mcap"
    calls = {"n": 0}
    real = mw.Rosbag2McapWriter._write_chunk

    def interrupted(self, *args, **kwargs):
        calls["n"] += 1
        real(self, *args, **kwargs)
        raise KeyboardInterrupt  # Ctrl-C after the first chunk reached the file

    monkeypatch.setattr(mw.Rosbag2McapWriter, "_write_chunk", interrupted)
    rc = cli_main(["replay", str(sample), "--out", str(tmp_path / "o.mcap"),
                   "--compression", "none"])
    assert rc == 130 and "interrupted" in _one_line(capsys.readouterr().err)
    assert calls["n"] >= 1 and _listing(tmp_path) == []


def test_default_output_is_zstd_in_log_time_order(tmp_path):
    sample = REPO / "bags" / "coning_200hz.mcap"
    out = tmp_path / "o.mcap"
    assert cli_main(["replay", str(sample), "--out", str(out), "--json"]) == 0
    for path in (sample, out):
        with open(path, "rb") as f:
            reader = make_reader(f, validate_crcs=True)
            assert {c.compression for c in reader.get_summary().chunk_indexes} == {"zstd"}
            logs = [m.log_time for _, _, m in reader.iter_messages(log_time_order=False)]
        assert len(logs) == 8000 and all(a <= b for a, b in zip(logs, logs[1:], strict=False))
    assert cli_main(["replay", str(sample), "--out", str(tmp_path / "n.mcap"),
                     "--compression", "none", "--json"]) == 0
    with open(tmp_path / "n.mcap", "rb") as f:
        assert {c.compression for c in make_reader(f).get_summary().chunk_indexes} == {""}


def test_ctrl_c_in_a_real_process(tmp_path):
    """SIGINT while the output is being written: exit 130, one line, nothing left under
    the requested name nor beside it."""
    import signal
    import subprocess
    import time

    n = 300_000
    t = 10**9 + np.arange(n, dtype=np.int64) * 1_000_000
    with Rosbag2McapWriter(tmp_path / "in.mcap", chunk_size=1 << 20) as wr:
        wr.add_topic("imu/data_raw", IMU)
        wr.write_imu_array("imu/data_raw", t, np.tile([0.1, 0.2, 0.3], (n, 1)))
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    proc = subprocess.Popen(
        [sys.executable, "-m", "gyro_attitude.cli", "replay", str(tmp_path / "in.mcap"),
         "--out", str(out_dir / "o.mcap"), "--compression", "none"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    deadline = time.monotonic() + 60
    while not any(out_dir.iterdir()) and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.001)  # wait for the temporary output file: the write has begun
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    if proc.returncode == 0:
        pytest.skip("the replay finished before the signal arrived")
    assert proc.returncode == 130 and "interrupted" in _one_line(err)
    assert _listing(out_dir) == []


@pytest.mark.parametrize("flag, value", [("--max-gap-s", "1e300"), ("--time-jump-threshold-s",
                                                                     "inf"),
                                          ("--max-rate-rad-s", "1e300"), ("--max-gap-s", "-1")])
def test_policy_flags_out_of_range_are_one_line_exit_2(tmp_path, capsys, flag, value):
    sample = REPO / "bags" / "coning_200hz.mcap"
    with pytest.raises(SystemExit) as exc:
        cli_main(["replay", str(sample), "--out", str(tmp_path / "o.mcap"), flag, value])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert flag in err and "Traceback" not in err
    assert not (tmp_path / "o.mcap").exists()


def _rest_turn_rest(seed=0, rate_hz=200.0):
    """Still, a turn about z at 0.8 rad/s, still again: MEMS-like noise and bias, gravity on z."""
    rng = np.random.default_rng(seed)
    n = int(25 * rate_hz)
    t = 2 * 10**9 + (np.arange(n, dtype=np.int64) * 10**9) // int(rate_hz)
    s = (t - t[0]) * 1e-9
    w = np.zeros((n, 3))
    w[(s > 8) & (s < 16), 2] = 0.8
    w += (0.003, -0.002, 0.004) + 2e-3 * rng.normal(size=w.shape)
    a = np.array([0.0, 0.0, 9.81]) + 0.02 * rng.normal(size=(n, 3))
    return t, w, a


def test_replay_estimator_causal_is_the_attitude_stream_and_offline_is_the_default(tmp_path):
    from gyro_attitude.core.attitude.settings import StreamConfig
    from gyro_attitude.core.attitude.stream import AttitudeStream

    t, w, a = _rest_turn_rest()
    _record(tmp_path / "in.mcap", t, w, a)
    causal = replay_file(tmp_path / "in.mcap", tmp_path / "c.mcap", estimator="causal")
    cfg = StreamConfig()
    expected = AttitudeStream(causal.algorithm, config=cfg).run(t, w, "imu_link", None, a)
    assert causal.estimator == "causal"
    np.testing.assert_allclose(causal.q, expected.q, rtol=0, atol=1e-12)
    offline = replay_file(tmp_path / "in.mcap", tmp_path / "o.mcap")
    assert offline.estimator == "offline" and offline.summary()["estimator"] == "offline"
    # the offline estimate takes the bias from both rests and holds the attitude at them: the
    # turn is 6.4 rad about z; its end differs from the truth by noise only
    end = np.degrees(np.abs(2 * np.arctan2(offline.q[-1, 2], offline.q[-1, 3]) - 6.4 % (2 * np.pi)))
    assert min(end, 360 - end) < 0.5


def test_replay_without_accelerometer_is_gyro_only_offline_and_says_so(tmp_path, capsys):
    t, w, _ = _rest_turn_rest(seed=1)
    _record(tmp_path / "in.mcap", t, w)  # no accelerometer: its covariance element 0 is -1
    rc = cli_main(["replay", str(tmp_path / "in.mcap"), "--out", str(tmp_path / "o.mcap"),
                   "--aiding", "gravity", "--json"])
    cap = capsys.readouterr()
    assert rc == 0
    assert "no accelerometer: gyro-only offline estimation" in cap.err
    out = json.loads(cap.out)
    assert out["estimator"] == "offline"
    assert any("no accelerometer" in n for n in out["estimator_notes"])
    with pytest.raises(SystemExit) as exc:
        cli_main(["replay", str(tmp_path / "in.mcap"), "--out", str(tmp_path / "o2.mcap"),
                  "--estimator", "kalman"])
    err = capsys.readouterr().err.strip().splitlines()
    assert exc.value.code == 2 and len(err) == 1 and "--estimator" in err[0]


def test_truth_on_its_own_clock_is_compared_at_its_stamps(tmp_path, capsys):
    """Truth at 120 Hz, offset 1.3 ms from a 200 Hz Imu: no stamp coincides. The error is
    taken at every truth stamp inside the Imu span, against the attitude slerped there.
    Constant rate about z, so the slerp of the exact attitude is exact: a truth tilted by
    0.1 rad gives 0.1 at all of them."""
    n, omega = 2001, 0.7
    t = 10**9 + np.arange(n, dtype=np.int64) * 5_000_000
    w = np.tile([0.0, 0.0, omega], (n, 1))
    tt = 10**9 + 1_300_000 + (np.arange(1300, dtype=np.int64) * 10**9) // 120
    s_rel = (tt - t[0]) * 1e-9
    exact = np.stack([0 * s_rel, 0 * s_rel, np.sin(omega * s_rel / 2),
                      np.cos(omega * s_rel / 2)], 1)
    tilted = (Rotation.from_rotvec([0.1, 0.0, 0.0]) * Rotation.from_quat(exact)).as_quat()
    path = tmp_path / "in.mcap"
    with Rosbag2McapWriter(path, chunk_size=50_000) as wr:
        wr.add_topic("imu/data_raw", IMU)
        wr.add_topic("truth/attitude", QS)
        wr.write_batches([imu_batch("imu/data_raw", t, w),
                          quaternion_stamped_batch("truth/attitude", tt, tilted)])
    s = replay_file(path, tmp_path / "o.mcap", algorithm="rotvec_cubic")
    inside = tt[(tt >= t[0]) & (tt <= t[-1])]
    assert s.truth_matched == inside.size and inside.size > 1150
    np.testing.assert_array_equal(s.error_t_ns, inside)
    assert abs(s.final_error_rad - 0.1) < 1e-9 and abs(s.max_error_rad - 0.1) < 1e-9
    assert abs(s.rms_error_rad - 0.1) < 1e-9 and abs(s.error_rad.min() - 0.1) < 1e-9
    # and the CLI prints the figures instead of "no truth topic"
    assert cli_main(["replay", str(path), "--out", str(tmp_path / "o2.mcap")]) == 0
    out = capsys.readouterr().out
    assert "no truth topic" not in out and f"({inside.size} stamps)" in out


def test_replay_takes_messages_in_log_time_order_as_rosbag2_plays_them(tmp_path):
    """Receive jitter: messages stored in stamp order, log times (receive times) jittered so
    that log-time order differs. The player (and ros2 bag play) deliver in log-time order,
    so the node sees those stamps out of order; replay must see the same sequence: the file
    stored in log-time order gives the identical result."""
    n = 4000
    t, w = _tumbling(n, rate_hz=200.0, seed=5)
    rng = np.random.default_rng(6)
    log = t + rng.integers(0, 12_000_000, n)  # up to 12 ms late: 2.4 samples at 200 Hz
    order = np.argsort(log, kind="stable")
    assert (order != np.arange(n)).sum() > 100
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import Imu

    def data(k):
        m = Imu()
        m.header.stamp.sec, m.header.stamp.nanosec = divmod(int(t[k]), 10**9)
        m.header.frame_id = "imu_link"
        m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z = map(float, w[k])
        return serialize_message(m)

    for name, idx in (("file_order.mcap", np.arange(n)), ("log_order.mcap", order)):
        with Rosbag2McapWriter(tmp_path / name, chunk_size=50_000) as wr:
            wr.add_topic("imu/data_raw", IMU)
            for k in idx:  # one message at a time: the writer keeps the order given
                wr.write("imu/data_raw", data(k), int(log[k]))
    a = replay_file(tmp_path / "file_order.mcap", tmp_path / "a.mcap")
    b = replay_file(tmp_path / "log_order.mcap", tmp_path / "b.mcap")
    assert b.skipped.get("out_of_order", 0) > 50  # what the node rejects, live
    assert a.skipped == b.skipped and a.attitude_messages == b.attitude_messages
    np.testing.assert_array_equal(a.t_ns, b.t_ns)
    np.testing.assert_array_equal(a.q, b.q)


def test_output_is_written_in_bounded_blocks_and_equals_one_block(tmp_path, monkeypatch):
    """The write side builds at most OUTPUT_BLOCK_MESSAGES messages per topic at a time
    (its memory no longer grows with the recording); the file reads back the same, in
    log-time order across both topics."""
    from gyro_attitude.io import mcap_writer
    from gyro_attitude.io.mcap_reader import McapStreamReader
    from gyro_attitude.offline import replay as replay_module

    t, w = _tumbling(5000, seed=9)
    _record(tmp_path / "in.mcap", t, w, a=np.tile([0.0, 0.0, 9.8], (5000, 1)))
    sizes = []
    real = mcap_writer.Rosbag2McapWriter.write_batches

    def spy(self, batches):
        sizes.append([len(b) for b in batches])
        return real(self, batches)

    monkeypatch.setattr(mcap_writer.Rosbag2McapWriter, "write_batches", spy)
    monkeypatch.setattr(replay_module, "OUTPUT_BLOCK_MESSAGES", 1 << 30)
    replay_file(tmp_path / "in.mcap", tmp_path / "one.mcap", algorithm="rotvec_cubic")
    assert sizes == [[5000, 5000]]
    sizes.clear()
    monkeypatch.setattr(replay_module, "OUTPUT_BLOCK_MESSAGES", 1024)
    replay_file(tmp_path / "in.mcap", tmp_path / "blocks.mcap", algorithm="rotvec_cubic")
    assert sizes == [[1024, 1024]] * 4 + [[904, 904]]

    def messages(path):
        return [(m.channel.topic, m.log_time, m.data) for m in
                McapStreamReader(path).iter_messages()]

    one, blocks = messages(tmp_path / "one.mcap"), messages(tmp_path / "blocks.mcap")
    assert one == blocks and len(one) == 10_000
    assert [m[1] for m in blocks] == sorted(m[1] for m in blocks)


@pytest.mark.parametrize("bad_start", ["zero_stamp", "nan_rates"])
def test_truth_start_is_taken_at_the_first_accepted_sample(tmp_path, bad_start):
    # A constant spin about z with the exact truth at every stamp.  The first samples are
    # rejected — a stream starting at stamp 0 (as the scenes did), or 50 NaN rates: the
    # attitude must start from the truth at the first ACCEPTED sample, so rotvec_cubic (exact
    # for constant spin) stays on the truth.  Started from the truth at the rejected sample it
    # would be off by rate × the skipped time (4.5e-3 rad, 0.23 rad).
    n, rate = 2001, 0.9
    t0 = 0 if bad_start == "zero_stamp" else 10**9
    t = t0 + np.arange(n, dtype=np.int64) * 5_000_000
    w = np.tile([0.0, 0.0, rate], (n, 1))
    if bad_start == "nan_rates":
        w[:50] = np.nan
    truth = Rotation.from_rotvec(np.outer((t - t0) * 1e-9 * rate, [0, 0, 1])).as_quat()
    _record(tmp_path / "in.mcap", t, w, truth=truth)
    s = replay_file(tmp_path / "in.mcap", tmp_path / "out.mcap", algorithm="rotvec_cubic",
                    initial_attitude="truth")
    assert s.skipped_before_truth == (1 if bad_start == "zero_stamp" else 50)
    assert s.max_error_rad < 1e-9


def test_odometry_topic_sets_the_transport_rate_as_the_node_does(tmp_path, capsys):
    # aircraft_turn (120 m/s, 3 °/s coordinated turn at 50°N) with an ideal gyro, simulated
    # offline with truth/odom.  Integrated in ENU from the truth, the velocity of truth/odom
    # makes the transport rate follow the turn: the attitude stays on the truth; the scene's
    # initial velocity held constant leaves the transport-rate error of the velocity change.
    import yaml

    from gyro_attitude.io.scene_file import find_scene_file, load_scene

    scene = yaml.safe_load(find_scene_file("aircraft_turn").read_text())
    scene["gyro"].pop("errors", None)
    path = tmp_path / "turn.yaml"
    path.write_text(yaml.safe_dump(scene))
    spec = load_scene(str(path))
    assert cli_main(["simulate", str(path), "--duration", "20", "--out",
                     str(tmp_path / "turn.mcap"), "--quiet"]) == 0
    v0 = np.asarray(spec.motion.velocity(np.zeros(1)))[0]
    common = ["replay", str(tmp_path / "turn.mcap"), "--frame", "enu",
              "--latitude-rad", repr(float(spec.earth.latitude_rad)),
              "--height-m", repr(float(spec.earth.height_m)),
              "--velocity-enu", ",".join(repr(float(x)) for x in v0),
              "--initial-attitude", "truth", "--algorithm", "rotvec_cubic", "--json",
              # the gyro alone (a coordinated turn's specific force is no vertical)
              "--aiding", "none"]
    final = {}
    for name, extra in (("odom", ["--odometry-topic", "truth/odom"]), ("plain", [])):
        capsys.readouterr()
        assert cli_main([*common, "--out", str(tmp_path / f"{name}.mcap"), *extra]) == 0
        final[name] = json.loads(capsys.readouterr().out)["final_error_rad"]
    assert final["odom"] < 1e-6 and final["plain"] > 100 * final["odom"], final
    # the topic must be an Odometry one, and enu is needed (the truth's topic given as the
    # odometry, the truth named elsewhere: one role each)
    rc = cli_main([*common, "--out", str(tmp_path / "x.mcap"), "--odometry-topic",
                   "truth/attitude", "--truth-topic", "truth/elsewhere"])
    assert rc == 1 and "not nav_msgs/msg/Odometry" in _one_line(capsys.readouterr().err)


@pytest.mark.parametrize("command", ["replay", "montecarlo"])
def test_help_of_a_command_with_the_estimator_settings_prints(command, capsys):
    # a setting's help text holds a literal "%" ("0.3-1 %"), which argparse formats
    with pytest.raises(SystemExit) as exc:
        cli_main([command, "--help"])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    assert "--gyro-scale-factor-sigma" in out and "0.3-1 %" in out


@pytest.mark.parametrize("value", ["abc", "nan", "0", "-1", "inf", "1e300"])
def test_a_bad_offline_time_constant_flag_is_one_line_and_exit_2(value, tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        cli_main(["replay", str(tmp_path / "in.mcap"), "--out", str(tmp_path / "o.mcap"),
                  "--offline-mag-tau-s", value])
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert "offline_mag_tau_s must be a" in err and "Traceback" not in err
    assert ("must be a number, got 'abc'" in err) if value == "abc" else "[0.01, 10000]" in err


@pytest.mark.parametrize("estimator", ["offline", "causal"])
def test_replay_with_its_working_arrays_on_disk_gives_the_same_file_and_leaves_no_file(
        tmp_path, monkeypatch, estimator):
    """A long recording's columns go to unlinked files beside the output (io/spool.py): with
    every array spooled (threshold 0) the replay writes the same messages and figures as in
    memory -- messages stored out of log-time order, a NaN sample, an accelerometer and truth
    included -- says how much it kept on disk, and leaves nothing but its output."""
    import gyro_attitude.io.spool as spool

    n = 3000
    t, w = _tumbling(n, seed=4)
    w[700] = np.nan
    rng = np.random.default_rng(7)
    a = np.array([0.0, 0.0, 9.81]) + 0.02 * rng.normal(size=(n, 3))
    truth = np.tile(Rotation.from_rotvec([0.1, 0.2, 0.3]).as_quat(), (n, 1))
    order = np.arange(n)
    order[100:110] = order[100:110][::-1]  # stamps out of order within a stretch
    _record(tmp_path / "in.mcap", t, w, a, truth=truth, shuffle=order)
    mem_dir, disk_dir = tmp_path / "mem", tmp_path / "disk"
    mem_dir.mkdir()
    disk_dir.mkdir()
    kw = {"estimator": estimator}
    r_mem = replay_file(tmp_path / "in.mcap", mem_dir / "out.mcap", **kw)
    monkeypatch.setattr(spool, "SPOOL_MIN_BYTES", 0)
    r_disk = replay_file(tmp_path / "in.mcap", disk_dir / "out.mcap", **kw)
    assert r_mem.working_bytes_on_disk == 0 and r_disk.working_bytes_on_disk > 24 * n
    assert r_disk.skipped == r_mem.skipped and r_disk.skipped.get("non_finite") == 1
    np.testing.assert_array_equal(r_disk.index, r_mem.index)
    np.testing.assert_array_equal(r_disk.q, r_mem.q)
    assert r_disk.rms_error_rad == r_mem.rms_error_rad and r_mem.truth_matched > 0
    got = [read_imu_arrays(d / "out.mcap", "imu/data") for d in (mem_dir, disk_dir)]
    np.testing.assert_array_equal(got[0].orientation, got[1].orientation)
    np.testing.assert_array_equal(got[0].linear_acceleration, got[1].linear_acceleration)
    assert sorted(os.listdir(disk_dir)) == ["out.mcap"]


def test_one_imu_message_with_truth_gives_its_attitude_and_no_error_figures(tmp_path, capsys):
    """One attitude has nothing to slerp the truth between: no error figures, said in one
    line, exit 0 -- not an IndexError after the output was written."""
    t = np.array([2 * 10**9], dtype=np.int64)
    _record(tmp_path / "in.mcap", t, np.zeros((1, 3)), truth=np.array([[0.0, 0.0, 0.0, 1.0]]))
    assert cli_main(["replay", str(tmp_path / "in.mcap"), "--out", str(tmp_path / "o.mcap"),
                     "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert "no error figures" in out and "Traceback" not in out
    assert read_quaternion_stamped_arrays(tmp_path / "o.mcap", "attitude").stamp_ns.tolist() \
        == t.tolist()
