"""write_batches' files byte for byte: SHA-256 digests of reference files for several batch
layouts and compressions, and every message read back by the mcap package's reader."""

from __future__ import annotations

import hashlib
import importlib

import numpy as np
import pytest
from mcap.reader import make_reader

import gyro_attitude.io.mcap_writer as mw
from gyro_attitude.io.cdr_arrays import (
    imu_batch,
    joint_state_batch,
    odometry_batch,
    quaternion_stamped_batch,
)

T0 = 1_700_000_000_000_000_000


def _unit_rows(rng, n, k=4):
    q = rng.normal(size=(n, k))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def _one_topic(rng):
    """One Imu topic, many chunks (the single-topic path writes records in place)."""
    n = 3000
    t = T0 + np.arange(n, dtype=np.int64) * 5_000_000
    return 20_000, [("imu", "sensor_msgs/msg/Imu")], [[
        imu_batch("imu", t, rng.normal(size=(n, 3)), rng.normal(size=(n, 3)),
                  _unit_rows(rng, n), frame_id="imu_link")]]


def _round_robin(rng):
    """Two topics with the same log times (a replay's outputs): evenly interleaved."""
    n = 2000
    t = T0 + np.arange(n, dtype=np.int64) * 2_500_000
    q = _unit_rows(rng, n)
    return 16_000, [("attitude", "geometry_msgs/msg/QuaternionStamped"),
                    ("imu/data", "sensor_msgs/msg/Imu")], [[
        quaternion_stamped_batch("attitude", t, q, frame_id="enu",
                                 publish_time_ns=t + 17),
        imu_batch("imu/data", t, rng.normal(size=(n, 3)), rng.normal(size=(n, 3)), q,
                  angular_velocity_covariance=np.diag([1e-6, 2e-6, 3e-6]).ravel())]]


def _irregular(rng):
    """Two topics at irregular, partly equal log times (ties within and across topics)."""
    la = np.sort(rng.integers(0, 600, size=1500)).astype(np.int64) * 1000 + T0
    lb = np.sort(rng.integers(0, 600, size=900)).astype(np.int64) * 1000 + T0
    return 7_000, [("imu", "sensor_msgs/msg/Imu"),
                   ("att", "geometry_msgs/msg/QuaternionStamped")], [[
        imu_batch("imu", la - 3, rng.normal(size=(la.size, 3)), log_time_ns=la,
                  publish_time_ns=np.arange(la.size, dtype=np.int64)),
        quaternion_stamped_batch("att", lb, _unit_rows(rng, lb.size), log_time_ns=lb)]]


def _stable_sort(rng):
    """A batch out of log-time order (sorted stably by the writer), topics with constant
    string/count columns (Odometry, JointState), a per-message record pending before the
    batches and a second write_batches call (sequences continue)."""
    n = 800
    la = rng.integers(0, 200, size=n).astype(np.int64) * 10_000 + T0  # disorder and ties
    lo = T0 + np.arange(300, dtype=np.int64) * 6_000
    lj = T0 + np.arange(250, dtype=np.int64) * 8_000
    first = [
        imu_batch("imu", la, rng.normal(size=(n, 3)), publish_time_ns=np.arange(n) + 5),
        odometry_batch("odom", lo, rng.normal(size=(lo.size, 3)), _unit_rows(rng, lo.size),
                       rng.normal(size=(lo.size, 3)), rng.normal(size=(lo.size, 3))),
        joint_state_batch("joints", lj, ["a", "bb", "ccc"], rng.normal(size=(lj.size, 3)),
                          rng.normal(size=(lj.size, 3)), frame_id="robot"),
    ]
    t2 = T0 + 3 * 10**9 + np.arange(400, dtype=np.int64) * 1_000
    second = [quaternion_stamped_batch("att", t2, _unit_rows(rng, t2.size)),
              imu_batch("imu", t2[::2], rng.normal(size=(200, 3)))]
    return 6_000, [("imu", "sensor_msgs/msg/Imu"), ("odom", "nav_msgs/msg/Odometry"),
                   ("joints", "sensor_msgs/msg/JointState"),
                   ("att", "geometry_msgs/msg/QuaternionStamped")], [first, second]


def _tiny_chunks(rng):
    """chunk_size below one record: one message per chunk."""
    t = T0 + np.arange(60, dtype=np.int64) * 1_000
    return 1, [("a", "geometry_msgs/msg/QuaternionStamped"),
               ("b", "sensor_msgs/msg/Imu")], [[
        quaternion_stamped_batch("a", t, _unit_rows(rng, t.size)),
        imu_batch("b", t[::3] + 1, rng.normal(size=(20, 3)))]]


def _exact_fit(rng):
    """chunk_size a multiple of a record pair: chunks fill up to exactly chunk_size."""
    n = 500
    t = T0 + np.arange(n, dtype=np.int64) * 1_000
    att = quaternion_stamped_batch("a", t, _unit_rows(rng, n))
    imu = imu_batch("b", t, rng.normal(size=(n, 3)))
    pair = att.record_dtype().itemsize + imu.record_dtype().itemsize
    return 7 * pair, [("a", "geometry_msgs/msg/QuaternionStamped"),
                      ("b", "sensor_msgs/msg/Imu")], [[att, imu]]


LAYOUTS = {"one_topic": _one_topic, "round_robin": _round_robin, "irregular": _irregular,
           "stable_sort": _stable_sort, "tiny_chunks": _tiny_chunks, "exact_fit": _exact_fit}

# A std_msgs/String "pending" (serialized CDR), written per message before the batches.
_STRING_CDR = b"\x00\x01\x00\x00\x06\x00\x00\x00hello\x00\x00\x00"


def write_layout(path, layout: str, compression: str):
    """Write one layout; returns the batch lists (for the read-back check)."""
    chunk_size, topics, calls = LAYOUTS[layout](np.random.default_rng(42))
    with mw.Rosbag2McapWriter(path, chunk_size=chunk_size, compression=compression) as wr:
        for topic, type_name in topics:
            wr.add_topic(topic, type_name)
        if layout == "stable_sort":
            wr.add_topic("chatter", "std_msgs/msg/String")
            wr.write("chatter", _STRING_CDR, T0 + 5)
        for batches in calls:
            wr.write_batches(batches)
    return calls


# SHA-256 of the files write_layout writes (file name "ref.mcap", header library string
# "gyro_attitude 0.0.0-ref"), produced by running write_layout with the writer of commit
# b1e756e (before write_batches built chunks in the pool threads) with numpy 2.4.6, PyYAML
# 6.0.3, zstandard 0.25.0 and lz4 4.4.5.  Later versions of the writer must keep these
# files byte-identical.
DIGESTS = {
    ("exact_fit", ""): "318eb6182df4ecbcd7df104c46b3debfde11dd4b62b767880f699b6bebd53911",
    ("exact_fit", "zstd"): "21aba2e7d596bd603c6bea6231a7c07d09cee436b1013adf4b75b9d5120ca0f6",
    ("exact_fit", "lz4"): "f62265eea3fc28350f68d57fb03822b989abbf238b05f8947e5fd7a76000153f",
    ("irregular", ""): "fa31a7a33b7acf5f7bee74108a830bd7de927f1d2717a4e957903709687fc169",
    ("irregular", "zstd"): "4bd0dde7efe2c79cbd87a2af79602ae31f0aaa88f67480e3e526bf10e62de932",
    ("irregular", "lz4"): "1df30acf08c8706bbe56de20aa2aaef9917b79912839c88ba8914e44ff62e065",
    ("one_topic", ""): "089cf2c038c78ce44e532bce00c7a001a12e45833dfa9365142cece7ab5ae3a5",
    ("one_topic", "zstd"): "5bf5620ba85cc9456fcf75288c93cfae0217d2b1d668b3cbe530f112676e9a18",
    ("one_topic", "lz4"): "7fd6b8c1d377ef4d5bc102882509e79fa5315bdc92a8740dc77234e061f8f3a0",
    ("round_robin", ""): "452c307ee18f43ef112ce2671bd0b5a798de8c918550ec154ffb1aa5c95fa1ac",
    ("round_robin", "zstd"): "3d4717fedbc7ca978ac2320760b215d998f619db3cc76d7fa13f9b9e610844a1",
    ("round_robin", "lz4"): "5f8501b5930df20a88d003bca407c6ad81a4358fca056f5c42e559ef5d8571ef",
    ("stable_sort", ""): "f22bc8f5e49971f5f8927e9abf3ce96e2a02fdaae62b4c0fd43de010faf1ca4d",
    ("stable_sort", "zstd"): "fa860be51749b4b12a5381440a8609b6bf9e26d394af5193e4be36879d86e6e6",
    ("stable_sort", "lz4"): "d304379711b5b4e1cf5b1312ec5f574399da3bccc07f9840a9fcfa10f5bf8e3d",
    ("tiny_chunks", ""): "4e7283e5625e3690955189268f4abfdd5ea65a38357362e3a8b6ddf777f9a5d3",
    ("tiny_chunks", "zstd"): "a9726eb6a32b4ffe6e21bbd13a77be600f98d6cc11d4af89ae114bcc9e7691a8",
    ("tiny_chunks", "lz4"): "c27372e2f3823758d58a83c7552b3bbaab09c6dd8978408761738c1172cc1079",
}
# The compressed bytes depend on the compressor library's version (both come with mcap).
REFERENCE_COMPRESSORS = {"zstd": ("zstandard", "0.25.0"), "lz4": ("lz4", "4.4.5")}


@pytest.mark.parametrize("compression", ["", "zstd", "lz4"])
@pytest.mark.parametrize("layout", sorted(LAYOUTS))
def test_write_batches_files_are_byte_identical_to_the_reference(tmp_path, monkeypatch,
                                                                  layout, compression):
    monkeypatch.setattr(mw, "__version__", "0.0.0-ref")
    path = tmp_path / "ref.mcap"
    calls = write_layout(path, layout, compression)
    module, version = REFERENCE_COMPRESSORS.get(compression, (None, None))
    if module is None or importlib.import_module(module).__version__ == version:
        assert hashlib.sha256(path.read_bytes()).hexdigest() == DIGESTS[layout, compression]
    # (another compressor version may compress differently: the "" files still check the
    # records byte for byte, and the read-back below checks the messages)

    # Independent read-back: every message, in the stable log-time merge of each call's
    # batches (stable sort of the concatenation, batch order breaking ties), sequences
    # counting per channel in file order.
    expected = []
    if layout == "stable_sort":
        expected.append(("/chatter", T0 + 5, T0 + 5))
    for batches in calls:
        merged = []
        for b in batches:
            order = np.argsort(b.log_time_ns, kind="stable")
            merged += [("/" + b.topic, int(b.log_time_ns[k]), int(b.publish_time_ns[k]))
                       for k in order]
        merged.sort(key=lambda m: m[1])
        expected += merged
    with open(path, "rb") as f:
        reader = make_reader(f, validate_crcs=True)
        got, seqs = [], {}
        for _, ch, m in reader.iter_messages(log_time_order=False):
            got.append((ch.topic, m.log_time, m.publish_time))
            seqs.setdefault(ch.topic, []).append(m.sequence)
        chunks = reader.get_summary().chunk_indexes
    assert got == expected
    assert all(s == list(range(len(s))) for s in seqs.values())
    assert {c.compression for c in chunks} == {compression}


def test_header_body_offset_follows_the_cdr_layout():
    """The per-message parse's one-expression offset is CdrLayout's for every frame_id
    length (alignment counted from offset 4, after the encapsulation)."""
    from gyro_attitude.io.cdr_arrays import CdrLayout, header_body_offset

    for n in range(0, 40):
        lay = CdrLayout()
        frame = lay.header("x" * n)
        lay.doubles("body", 1)
        assert header_body_offset(len(frame)) == lay.fields[-1][2], n
