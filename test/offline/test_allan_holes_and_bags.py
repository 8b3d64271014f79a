"""allan on what real recordings look like: a few missing samples, a noise-free gyro, a bag
directory, a split bag (two .mcap + metadata.yaml) -- the last also for replay and player."""

from __future__ import annotations

import numpy as np
import pytest

from gyro_attitude.cli import main as cli_main
from gyro_attitude.io.mcap_writer import Rosbag2McapWriter
from gyro_attitude.io.strict_yaml import dump_yaml
from gyro_attitude.offline.allan import allan_deviation, analyse_mcap
from gyro_attitude.offline.replay import replay_file

IMU = "sensor_msgs/msg/Imu"
N, DT_NS, DENS = 120_000, 10_000_000, 1e-3


def _white(n=N, seed=5):
    rng = np.random.default_rng(seed)
    t = np.arange(n, dtype=np.int64) * DT_NS + 10**9
    return t, rng.normal(scale=DENS / np.sqrt(DT_NS * 1e-9), size=(n, 3))


def _write(path, t, w):
    with Rosbag2McapWriter(path) as wr:
        wr.add_topic("imu/data_raw", IMU)
        wr.write_imu_array("imu/data_raw", t, w)


def _split_bag(directory, t, w, parts=2):
    """A rosbag2 split bag: ``<name>_k.mcap`` files listed in metadata.yaml."""
    directory.mkdir()
    names = []
    for k, idx in enumerate(np.array_split(np.arange(t.size), parts)):
        name = f"{directory.name}_{k}.mcap"
        _write(directory / name, t[idx], w[idx])
        names.append(name)
    meta = {"rosbag2_bagfile_information": {
        "version": 9, "storage_identifier": "mcap", "relative_file_paths": names,
        "message_count": int(t.size)}}
    (directory / "metadata.yaml").write_text(dump_yaml(meta), encoding="utf-8")


def test_a_few_missing_samples_are_accepted_counted_and_left_out_of_the_clusters(tmp_path):
    t, w = _white()
    holes = [30_000, 70_001, 70_002, 100_000]  # one sample, two in a row, one
    keep = np.setdiff1d(np.arange(N), holes)
    _write(tmp_path / "holes.mcap", t[keep], w[keep])
    r = analyse_mcap(tmp_path / "holes.mcap")
    assert r.samples == keep.size
    [note] = [n for n in r.notes if "missing" in n]
    assert note.startswith("4 samples missing in 3 holes (first 300 s after the start)")
    # oracle: the overlapping Allan variance over every cluster pair that spans no hole,
    # from the gap-free stretches (allantools on each), weighted by their term counts
    m = np.rint(r.tau_s / (DT_NS * 1e-9)).astype(int)
    stretches = [w[:30_000], w[30_001:70_001], w[70_003:100_000], w[100_001:]]
    for axis, i in (("x", 0), ("z", 2)):
        num = np.zeros(m.size)
        den = np.zeros(m.size)
        for s in stretches:
            terms = s.shape[0] - 2 * m + 1
            ok = terms > 0
            num[ok] += allan_deviation(s[:, i], DT_NS * 1e-9, m[ok]) ** 2 * terms[ok]
            den[ok] += terms[ok]
        np.testing.assert_allclose(r.gyro[axis].adev, np.sqrt(num / den), rtol=1e-12)
        assert r.gyro[axis].terms.random_walk == pytest.approx(DENS, rel=0.03)


def test_many_missing_samples_are_refused_saying_how_many_and_where(tmp_path, capsys):
    t, w = _white(20_000)
    keep = np.ones(t.size, bool)
    keep[5_000:5_400:2] = False  # 200 single holes: 1 % of the record
    _write(tmp_path / "lossy.mcap", t[keep], w[keep])
    assert cli_main(["allan", str(tmp_path / "lossy.mcap")]) == 1
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1
    assert "200 samples missing in 200 holes (first 50 s after the start)" in err
    assert "at most" in err


def test_a_noise_free_gyro_is_one_line(tmp_path, capsys):
    t = np.arange(6000, dtype=np.int64) * 20_000_000 + 10**9
    w = np.tile([5.156e-5, 0.0, 5.156e-5], (t.size, 1))  # the Earth rate, exactly
    _write(tmp_path / "ideal.mcap", t, w)
    assert cli_main(["allan", str(tmp_path / "ideal.mcap")]) == 1
    out, err = capsys.readouterr()
    assert err.strip().endswith("gyro x, y, z: every one of the 6000 samples is the same: "
                                "no noise to fit")
    assert len(err.splitlines()) == 1 and "Warning" not in err


def test_bag_directory_with_one_mcap_and_split_bags(tmp_path, capsys):
    t, w = _white(40_000)
    one = tmp_path / "one_bag"
    one.mkdir()
    _write(one / "one_bag_0.mcap", t, w)
    whole = analyse_mcap(one)
    assert whole.samples == t.size
    _split_bag(tmp_path / "split", t, w, parts=3)
    split = analyse_mcap(tmp_path / "split")
    assert split.samples == t.size
    np.testing.assert_array_equal(split.gyro["y"].adev, whole.gyro["y"].adev)
    assert cli_main(["allan", str(tmp_path / "split")]) == 0
    r = replay_file(tmp_path / "split", tmp_path / "out.mcap", algorithm="rotvec_cubic")
    assert r.messages == t.size and r.attitude_messages == t.size
    r1 = replay_file(one, tmp_path / "out1.mcap", algorithm="rotvec_cubic")
    np.testing.assert_array_equal(r.q, r1.q)


def test_split_bag_with_a_listed_file_missing_is_one_line(tmp_path, capsys):
    t, w = _white(1000)
    _split_bag(tmp_path / "split", t, w)
    (tmp_path / "split" / "split_1.mcap").unlink()
    assert cli_main(["allan", str(tmp_path / "split")]) == 1
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and "split_1.mcap" in err and "metadata.yaml" in err
