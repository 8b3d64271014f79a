"""Offline replay: integrate every Imu message of an MCAP recording into attitude and write
``attitude`` and ``imu/data`` to a new MCAP file (no ROS graph).

Pipeline (:func:`replay_file`): read the Imu (and truth) topic array-wide
(:mod:`gyro_attitude.io.imu_fast`), run the samples in log-time order -- the order a live
node receives them from ``ros2 bag play`` or ``mcap_player`` -- through the attitude-stream
policy the ``attitude_integrator`` node applies
(:class:`gyro_attitude.core.attitude.stream.AttitudeStream`: bad samples skipped and counted by
reason, no integration across gaps, reset on backward time jumps, orientation variance), write
the samples that got an attitude through a temporary file renamed into place
(:mod:`gyro_attitude.io.safe_output`) with both topics merged by log time, and compare with the
truth at its own stamps (the attitude slerped there).  Samples are never re-sorted by stamp.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from gyro_attitude.core.attitude import DEFAULT_ALGORITHM, DEFAULT_OFFLINE_ALGORITHM, NavFrame
from gyro_attitude.core.attitude import validation as iv
from gyro_attitude.core.attitude.accel_units import check_accel_scale
from gyro_attitude.core.attitude.input_topics import shared_topic, shared_topic_message
from gyro_attitude.core.attitude.inputs import first_step_back
from gyro_attitude.core.attitude.modes import Aiding, Estimator, InitialAttitudeSource, parse_mode
from gyro_attitude.core.attitude.nav_frame import velocity_series
from gyro_attitude.core.attitude.offline import estimate_offline
from gyro_attitude.core.attitude.sample_alignment import field_clock_offset, latest_at
from gyro_attitude.core.attitude.stream import (
    INVALID_MAG,
    MAG_DISTURBED,
    MAG_MISSING,
    AttitudeStream,
    StreamConfig,
    aiding_note,
    bias_summary,
    nav_rows,
    rows,
)
from gyro_attitude.core.attitude.truth import (
    default_max_interval_ns,
    initial_attitude_from_truth,
    span_words,
    tilt_and_heading_error,
    truth_at_stamps,
)
from gyro_attitude.core.attitude.world_frame import frame_id_of, from_enu
from gyro_attitude.core.earth import STANDARD_GRAVITY
from gyro_attitude.core.rotation import quat_angle_between
from gyro_attitude.io.cdr_arrays import (
    IMU_TYPE,
    MAGNETIC_FIELD_TYPE,
    QUATERNION_STAMPED_TYPE,
    imu_batch,
    quaternion_stamped_batch,
)
from gyro_attitude.io.copy_topics import TopicCopy
from gyro_attitude.io.imu_fast import QuaternionArrays, read_topic_arrays
from gyro_attitude.io.mcap_reader import bag_files, match_topic, recorded_topics
from gyro_attitude.io.mcap_writer import DEFAULT_COMPRESSION, Rosbag2McapWriter
from gyro_attitude.io.odometry_file import read_odometry_velocities
from gyro_attitude.io.safe_output import SafeOutput, check_output_path, plot_format
from gyro_attitude.io.spool import Spool
from gyro_attitude.io.trajectory_file import POSE_TYPES, read_pose_topic

__all__ = [
    "DEFAULT_IMU_TOPIC",
    "TRUTH_TOPIC",
    "ReplayResult",
    "replay_file",
    "write_error_plot",
]

DEFAULT_IMU_TOPIC = "imu/data_raw"
DEFAULT_MAG_TOPIC = "imu/mag"
TRUTH_TOPIC = "truth/attitude"
OUTPUT_CHUNK_SIZE = 4 * 1024 * 1024
# Output messages built and written per write_batches call (bounds the write side's memory).
OUTPUT_BLOCK_MESSAGES = 1 << 17
# Room the working files leave beside the output for it: this plus 4x the input's size (the
# output holds two messages per Imu message, and compresses unlike the input)
OUTPUT_ROOM_BYTES = 64 << 20
# Truth stamps compared per block (bounds the error figures' temporaries: _truth_figures).
TRUTH_BLOCK = 1 << 15


@dataclass
class ReplayResult:
    """What a replay did.  :meth:`summary` gives the scalar fields (the ``--json`` output);
    the arrays are ``index`` (positions, in log-time order, of the samples that got an attitude),
    their stamps ``t_ns`` and attitudes ``q`` (log-time order), and the error series
    ``error_t_ns``/``error_rad`` (empty without truth).  ``skipped`` counts skipped samples by
    reason; ``gaps`` and ``time_jump_resets`` count the policy's other events; ``details``
    holds the first log line per reason."""

    input: str
    output: str
    imu_topic: str
    estimator: str
    algorithm: str
    frame: str
    compression: str
    messages: int
    attitude_messages: int
    fast_path_messages: int
    fallback_messages: int
    frame_ids: list[str]
    skipped: dict[str, int]
    gaps: int
    time_jump_resets: int
    invalid_covariances: int
    integrator_errors: int
    missing_samples: int
    saturated: int
    rate_fit_fallbacks: int
    details: dict[str, str]
    skipped_before_truth: int
    gyro_bias: str
    gyro_bias_rad_s: list[float]
    alignment: dict | None
    duration_s: float
    wall_seconds: float
    read_seconds: float
    integrate_seconds: float
    write_seconds: float
    messages_per_second: float
    input_damage: str | None
    estimator_notes: list[str] = field(default_factory=list)
    magnetometer: dict | None = None
    working_bytes_on_disk: int = 0  # the recording-length arrays kept in unlinked files
    truth_topic: str | None = None
    truth_matched: int = 0
    final_error_rad: float | None = None
    max_error_rad: float | None = None
    rms_error_rad: float | None = None
    # the error apart (rad): tilt (final, max, RMS, at the first compared stamp), signed
    # heading (final, first) and, when the start was not taken from the truth, the final
    # heading error less the first (the start's heading offset removed)
    final_tilt_error_rad: float | None = None
    max_tilt_error_rad: float | None = None
    rms_tilt_error_rad: float | None = None
    initial_tilt_error_rad: float | None = None
    final_heading_error_rad: float | None = None
    initial_heading_error_rad: float | None = None
    final_heading_error_from_start_rad: float | None = None
    truth_overlap: dict | None = None  # spans (s) of truth, output and their overlap; a note
    accel_problem: str | None = None  # why the accelerometer was not used (not in m/s²)
    truth_found: bool = False  # the truth topic is in the input, with messages
    accel_note: str | None = None  # an accelerometer in m/s² too far off g for the rest test
    index: np.ndarray = field(default=None, repr=False)
    t_ns: np.ndarray = field(default=None, repr=False)
    q: np.ndarray = field(default=None, repr=False)
    error_t_ns: np.ndarray = field(default=None, repr=False)
    error_rad: np.ndarray = field(default=None, repr=False)

    _ARRAYS = ("index", "t_ns", "q", "error_t_ns", "error_rad")

    def summary(self) -> dict:
        # field by field: asdict() would deep-copy the arrays too (64 bytes a message)
        return {f.name: copy.deepcopy(getattr(self, f.name)) for f in dataclasses.fields(self)
                if f.name not in self._ARRAYS}


def _with_overrides(config: StreamConfig, frame, initial_attitude) -> StreamConfig:
    """``config`` with the keyword arguments ``frame`` / ``initial_attitude`` of
    :func:`replay_file` applied (each a setting of the table; None: as in ``config``)."""
    changes = {}
    if frame is not None:
        changes["frame"] = frame
    if isinstance(initial_attitude, str):
        changes["initial_attitude_source"] = initial_attitude
    elif initial_attitude is not None:
        changes.update(initial_attitude=initial_attitude,
                       initial_attitude_source=InitialAttitudeSource.PARAMETER)
    return config.replace(**changes) if changes else config


def _check_inputs(frame: str, nav) -> None:
    if nav is not None and not isinstance(nav, NavFrame):
        raise ValueError(f"nav must be a NavFrame or None, got {type(nav).__name__}")
    if (frame == "enu") != (nav is not None):
        raise ValueError("frame 'enu' needs a NavFrame (latitude); 'inertial' takes none")


def _check_distinct_topics(imu: str, truth: str, odometry: str | None, mag: str | None) -> None:
    """One role per topic (:mod:`.input_topics`); "imu/x" names "/imu/x" in a bag."""
    roles = [("--imu-topic", imu), ("--truth-topic", truth), ("--odometry-topic", odometry),
             ("--mag-topic", mag)]
    shared = shared_topic((flag, t.lstrip("/")) for flag, t in roles if t)
    if shared is not None:
        raise ValueError(shared_topic_message(*shared))


def _alignment_summary(a) -> dict:
    return {"roll_deg": math.degrees(a.roll), "pitch_deg": math.degrees(a.pitch),
            "heading_deg": math.degrees(a.heading), "heading_source": a.heading_source,
            "level_error_expected_deg": math.degrees(a.level_error_expected),
            "heading_error_expected_deg": (None if math.isnan(a.heading_error_expected)
                                           else math.degrees(a.heading_error_expected)),
            "rest_s": (a.rest_end_ns - a.rest_start_ns) * 1e-9}


def _spool_notes(spool: Spool) -> list[str]:
    """What the summary says of working arrays that stayed in memory, and why."""
    return [f"{n} working array(s) of the recording's length kept in memory: {why}"
            for n, why in ((spool.fallbacks, "the output's file system cannot reserve space "
                                              "for them"),
                           (spool.full_fallbacks, "no room for them beside the output")) if n]


def _input_bytes(path) -> int:
    """The size of a recording (a bag directory: its .mcap files), 0 when it cannot be had."""
    try:
        return sum(f.stat().st_size for f in bag_files(path))
    except (OSError, ValueError):
        return 0


def _block(a: np.ndarray | None, lo: int, hi: int) -> np.ndarray | None:
    return None if a is None else a[lo:hi]


def _output_batches(imu, rows, t_ns: np.ndarray, q: np.ndarray, variance, variance_known,
                    frame: str) -> list:
    """``attitude`` and ``imu/data`` for the input messages ``rows`` (a slice or indices)
    that got the attitudes ``q`` at ``t_ns``."""
    log, pub = imu.log_time_ns[rows], imu.publish_time_ns[rows]
    orientation_cov = np.zeros(9)
    if variance is not None:
        # the diagonal of the published 3x3 orientation covariance; zeros (unknown) on rows
        # before the first input with a gyro covariance, as the node publishes them
        orientation_cov = np.zeros((t_ns.size, 9))
        orientation_cov[:, [0, 4, 8]] = np.where(variance_known[:, None], variance, 0.0)
        orientation_cov = _constant_rows(orientation_cov)
    return [
        quaternion_stamped_batch("attitude", t_ns, q, frame_id=frame, log_time_ns=log,
                                 publish_time_ns=pub),
        imu_batch("imu/data", t_ns, imu.angular_velocity[rows], imu.linear_acceleration[rows],
                  q, frame_id=imu.frame_id, orientation_covariance=orientation_cov,
                  angular_velocity_covariance=_constant_rows(
                      imu.angular_velocity_covariance[rows]),
                  linear_acceleration_covariance=_constant_rows(
                      imu.linear_acceleration_covariance[rows]),
                  log_time_ns=log, publish_time_ns=pub),
    ]


def _constant_rows(a: np.ndarray) -> np.ndarray:
    """``a`` (N, w), or its first row when every row equals it (covariances usually are
    constant: the writer then sets them once per buffer instead of per message)."""
    if len(a) and (a.strides[0] == 0 or (a == a[0]).all()):  # stride 0: one row repeated
        return a[0]
    return a


@dataclass
class Estimate:
    """What :func:`estimate_recording` gives: the estimator's result over the samples from
    ``first`` on, the algorithm that ran, and the estimator's notes."""

    result: object
    first: int
    algorithm: str
    notes: list[str]
    aiding: object = None  # the causal aiding stage or the offline FieldReference (counts, reference)
    estimator: Estimator = Estimator.OFFLINE  # the one that ran


def estimate_recording(t_ns, omega, accel, gyro_covariance, frame_id, *, config: StreamConfig,
                       nav: NavFrame | None, algorithm: str | None,
                       estimator: Estimator | str = Estimator.OFFLINE,
                       truth: tuple[np.ndarray, np.ndarray] | None = None,
                       mag: np.ndarray | None = None, empty=np.empty) -> Estimate:
    """The one way a recording is estimated (replay, montecarlo, fleet replay): the truth
    start at the first sample the estimator accepts (``initial_attitude_source`` truth: the
    samples before it are left out), then the whole-recording estimator (``offline``) or the
    node's chain (``causal``: the offline default algorithm where its array form runs, the
    node's causal default where the chain runs per sample and no algorithm was named).
    ``nav`` may hold time series over all N samples; ``truth`` is (stamps, quaternions);
    ``mag`` (N, 3) the magnetic field at the samples (aiding magnetometer) or None;
    ``empty(shape, dtype)`` allocates the estimators' arrays of the recording's length
    (e.g. :meth:`gyro_attitude.io.spool.Spool.empty`; the per-sample form ignores it)."""
    estimator = parse_mode(Estimator, estimator, "estimator")
    n = t_ns.shape[0]
    first = 0
    q0 = None  # the settings' start (initial_attitude, or the first accelerometer sample)
    if config.initial_attitude_source is InitialAttitudeSource.TRUTH:
        if truth is None:
            raise ValueError("initial attitude 'truth' needs the truth")
        # at the first sample the estimator accepts (a zero stamp or a NaN rate before it is
        # skipped, and the truth at its stamp would be the wrong start)
        q0, first, _ = initial_attitude_from_truth(
            t_ns, truth[0], truth[1],
            usable=lambda k: iv.sample_problem(t_ns[k], omega[k], config.max_rate_rad_s) is None)
    if first:
        nav = nav_rows(nav, np.arange(first, n), n)
        t_ns, omega, gyro_covariance = t_ns[first:], omega[first:], gyro_covariance[first:]
        accel = None if accel is None else accel[first:]
        mag = None if mag is None else mag[first:]
    if estimator is Estimator.OFFLINE:
        # aiding auto | tilt | magnetometer: the offline chain's tilt from gravity, and with
        # magnetometer its heading from the field (core/attitude/offline.py, steps 4 and 6)
        algorithm = algorithm or DEFAULT_OFFLINE_ALGORITHM
        res = estimate_offline(t_ns, omega, accel, config=config, q0=q0, nav=nav,
                               frame_id=frame_id, angular_velocity_covariance=gyro_covariance,
                               algorithm=algorithm, mag=mag, empty=empty)
        return Estimate(res, first, algorithm, config.notes() + list(res.notes),
                        res.field_reference, Estimator.OFFLINE)
    stream = AttitudeStream(algorithm or DEFAULT_ALGORITHM, q0=q0, nav=nav, config=config)
    res = stream.run(t_ns, omega, frame_id, gyro_covariance, accel, mag, empty=empty)
    notes = config.notes() + [stream.aiding_note] + [n for n in (stream.start_note,) if n]
    return Estimate(res, first, stream.algorithm, notes, stream.aiding, Estimator.CAUSAL)


def replay_file(input_path, output_path, *, imu_topic: str = DEFAULT_IMU_TOPIC,
                algorithm: str | None = None, frame: str | None = None,
                nav: NavFrame | None = None, initial_attitude=None,
                truth_topic: str = TRUTH_TOPIC, compression: str = DEFAULT_COMPRESSION,
                chunk_size: int = OUTPUT_CHUNK_SIZE, force: bool = False,
                progress: Callable[[int, int], None] | None = None,
                on_damage: str = "warn", config: StreamConfig | None = None,
                odometry_topic: str | None = None,
                estimator: Estimator | str = Estimator.OFFLINE,
                mag_topic: str = DEFAULT_MAG_TOPIC,
                truth_child_frame: str | None = None) -> ReplayResult:
    """Integrate every Imu message of ``input_path`` and write ``output_path``.

    ``estimator`` ``offline``: the whole-recording estimator
    (:func:`gyro_attitude.core.attitude.offline.estimate_offline`: every attitude may use the
    samples after it); ``causal``: :class:`AttitudeStream`, the live node's attitudes sample
    for sample.
    ``config`` the estimator settings (:class:`StreamConfig`: frame, initial attitude, bias,
    aiding, ...; default: the node's defaults).  ``frame``, ``initial_attitude`` (4 numbers,
    ``"truth"`` or ``"level"``) and ``nav`` (a :class:`NavFrame`, e.g. a time series; default
    the one of ``config``) override those settings when given.  ``initial_attitude_source``
    ``truth``: the truth interpolated at the first Imu stamp it covers (earlier samples are
    skipped and counted); ``level``: roll and pitch from the specific force over the initial
    rest, heading from ``config``.  ``algorithm``
    None: the offline default, or the node's causal default when a sequential filter of
    ``config`` acts on the recording (levelling, aiding, auto bias with a rest).  ``config``
    ``odometry_topic``: a ``nav_msgs/Odometry`` topic of the recording whose velocity sets the
    transport rate (frame enu), time-aligned to the Imu stamps as the node applies it (each
    sample takes the newest message stamped at or before it).  The output must not be the
    input and must not exist unless ``force``; it appears only complete.
    With ``aiding`` magnetometer the ``sensor_msgs/MagneticField`` topic ``mag_topic`` is read
    and matched to the Imu stamps as the node matches it (the latest field sample at or before
    each stamp, at most ``mag_max_age_s`` old: :mod:`.sample_alignment`).
    The truth ``truth_topic`` is a ``geometry_msgs/QuaternionStamped`` or the orientation of
    a pose topic as motion-capture systems publish it (``PoseStamped``, ``Odometry``, or the
    transforms of a ``TFMessage`` whose child frame is ``truth_child_frame``).
    ``progress(bytes_done, bytes_total)`` is called while reading.  Raises ValueError (bad
    arguments, unusable input, nothing to write) and OSError.
    """
    for name, value in (("input_path", input_path), ("output_path", output_path)):
        if not isinstance(value, str | os.PathLike):
            raise ValueError(f"{name} must be a path, got {type(value).__name__}")
    for name, value in (("imu_topic", imu_topic), ("truth_topic", truth_topic),
                        ("mag_topic", mag_topic)):
        if not isinstance(value, str) or not value:
            raise ValueError(f"{name} must be a topic name, got {value!r}")
    if truth_child_frame is not None and (not isinstance(truth_child_frame, str)
                                          or not truth_child_frame):
        raise ValueError(f"truth_child_frame must be a frame name or None, got "
                         f"{truth_child_frame!r}")
    if odometry_topic is not None and not isinstance(odometry_topic, str):
        raise ValueError(f"odometry_topic must be a topic name or None, got {odometry_topic!r}")
    if config is not None and not isinstance(config, StreamConfig):
        raise ValueError(f"config must be a StreamConfig, got {type(config).__name__}")
    estimator = parse_mode(Estimator, estimator, "estimator")
    config = _with_overrides(config or StreamConfig(), frame, initial_attitude)
    _check_distinct_topics(imu_topic, truth_topic, odometry_topic,
                           mag_topic if config.aiding is Aiding.MAGNETOMETER else None)
    frame = config.frame.value
    if nav is None:
        nav = config.nav_frame()
    if isinstance(chunk_size, bool) or not isinstance(chunk_size, int) or \
            not 1024 <= chunk_size <= 1 << 30:
        raise ValueError(f"chunk_size must be an int from 1 KiB to 1 GiB, got {chunk_size!r}")
    _check_inputs(frame, nav)
    check_output_path(output_path, inputs=[input_path], force=force)
    t_start = time.perf_counter()
    use_mag = config.aiding is Aiding.MAGNETOMETER
    # the truth as a QuaternionStamped (read with the Imu) or as the poses of a motion-capture
    # topic (PoseStamped, Odometry, TFMessage: the trajectory input's reader)
    known = recorded_topics(input_path)  # None: the files have no summary to say
    truth_name = None if known is None else match_topic(list(known), truth_topic)
    truth_type = QUATERNION_STAMPED_TYPE if truth_name is None else known[truth_name]
    topics = {imu_topic: IMU_TYPE}
    if truth_type == QUATERNION_STAMPED_TYPE:
        topics[truth_topic] = QUATERNION_STAMPED_TYPE
    elif truth_type not in POSE_TYPES:
        raise ValueError(f"{input_path}: truth topic {truth_name} holds {truth_type or '?'}; "
                         f"truth is read from {QUATERNION_STAMPED_TYPE}, "
                         f"{', '.join(POSE_TYPES)} (--truth-topic)")
    if use_mag:
        topics[mag_topic] = MAGNETIC_FIELD_TYPE
    # the columns of the recording's length in files beside the output (io/spool.py): the
    # process's memory does not grow with the recording (where there is no room, they stay
    # in memory as before, and the notes say so)
    spool = Spool(Path(os.path.abspath(output_path)).parent, when_full="memory",
                  keep_free=OUTPUT_ROOM_BYTES + 4 * _input_bytes(input_path))
    arrays = read_topic_arrays(input_path, topics, empty=spool.empty,
                               on_damage=on_damage, progress=progress, required=False,
                               fields={imu_topic: ("angular_velocity", "linear_acceleration",
                                                   "angular_velocity_covariance",
                                                   "linear_acceleration_covariance")})
    damage = next((a.damage for a in arrays.values() if a.damage), None)
    if imu_topic not in arrays:
        known = recorded_topics(input_path, scan=True) if known is None else known
        have = sorted(t for t, ty in known.items() if ty == IMU_TYPE)
        raise ValueError(f"{input_path}: no Imu topic {imu_topic!r}; its Imu topics: "
                         f"{', '.join(have) or 'none'} (use --imu-topic)"
                         + (f"; {damage}" if damage else ""))
    # in log-time order, as ros2 bag play and mcap_player deliver them to the node (a file
    # written with receive jitter is not stored in that order)
    imu = arrays.pop(imu_topic).in_log_time_order(spool.empty)  # the file order is not kept
    if len(imu) == 0:
        raise ValueError(f"{input_path}: topic {imu.topic} has no messages"
                         + (f"; {damage}" if damage else ""))
    mag_rows = mag_offset = None
    if use_mag:
        mag = arrays.get(mag_topic)
        if mag is None or len(mag) == 0:
            raise ValueError(f"{input_path}: aiding magnetometer needs the "
                             f"sensor_msgs/MagneticField topic {mag_topic!r} (use --mag-topic)"
                             + ("" if mag is None else ": it has no messages"))
        mag_rows = latest_at(imu.stamp_ns, mag.stamp_ns, mag.magnetic_field,
                             int(round(config.mag_max_age_s * 1e9)))
        mag_offset = field_clock_offset(imu.stamp_ns, imu.angular_velocity, mag_rows)
        mag_info = (mag.topic, len(mag))
        del mag  # the field at the Imu stamps is what the estimator takes
    t_read = time.perf_counter()

    truth = arrays.pop(truth_topic, None)
    if truth is not None:  # its stamps and quaternions are used, its MCAP times never
        truth = dataclasses.replace(truth, log_time_ns=None, publish_time_ns=None)
    elif truth_type in POSE_TYPES:
        truth = _pose_truth(input_path, truth_name, truth_type, truth_child_frame)
    truth_notes = []
    if truth is not None and len(truth):
        # one truth for the start and the figures: a repeated stamp or a NaN quaternion (a
        # tracker that lost the markers) is left out of both, and said
        ts, tq = _usable_truth(truth.stamp_ns, truth.quaternion, spool.empty)
        if ts.size < len(truth):
            truth_notes.append(f"truth: {len(truth) - ts.size} of {len(truth)} samples left out "
                               "(not finite, zero, or a stamp not after the one before)")
            truth = dataclasses.replace(truth, stamp_ns=ts, quaternion=tq)
    del arrays
    t_all = imu.stamp_ns
    if odometry_topic:
        if nav is None:
            raise ValueError("--odometry-topic needs --frame enu (the transport rate of the "
                             "nav frame)")
        odo = read_odometry_velocities(input_path, odometry_topic)
        nav = dataclasses.replace(nav, velocity_enu=velocity_series(
            t_all, odo.stamp_ns, odo.velocity, np.broadcast_to(nav.velocity_enu, (3,))))
    if config.initial_attitude_source is InitialAttitudeSource.TRUTH and (
            truth is None or len(truth) == 0):
        raise ValueError(f"initial attitude 'truth': no {truth_topic} messages in the input")
    # the accelerometer feeds rest detection, levelling and aiding, when the Imu has one
    # (every message must carry one, REP-145: one that says it has none makes the
    # accelerometer unknown for the recording)
    has_accel = bool(len(imu)) and not iv.no_estimate(imu.linear_acceleration_covariance).any()
    accel_problem = accel_note = None
    if has_accel:
        # a field in g, mg, cm/s² or all zero is no specific force in m/s²: taken as one it
        # finds no rest or false ones and aids the tilt toward garbage (core/attitude/accel_units)
        scale = check_accel_scale(imu.linear_acceleration, imu.angular_velocity)
        if not scale.ok:
            if config.levelling:
                raise ValueError(f"{input_path}: {scale.problem}: initial attitude 'level' "
                                 "needs the accelerometer in m/s²")
            has_accel = False
            accel_problem = (f"{scale.problem}: the accelerometer is not used (no rests from "
                             "it, no levelling, no aiding)")
        elif scale.basis.startswith("still") and abs(
                scale.median_norm - STANDARD_GRAVITY) > config.rest_accel_norm_tol:
            # in m/s², but too far off g for the rest test's norm tolerance: no window passes
            accel_note = (f"the accelerometer reads |f| {scale.median_norm:.3f} m/s² when "
                          f"still, {abs(scale.median_norm - STANDARD_GRAVITY):.2f} m/s² from g: "
                          f"beyond rest_accel_norm_tol ({config.rest_accel_norm_tol:g} m/s²), "
                          "no rest passes the accelerometer test (calibrate its scale, or "
                          "raise --rest-accel-norm-tol)")
    # One frame per decoded message is not kept by the array reader: the first frame stands
    # for all (the node would also reject samples whose frame_id changes: see frame_ids).
    est = estimate_recording(
        t_all, imu.angular_velocity, imu.linear_acceleration if has_accel else None,
        imu.angular_velocity_covariance, imu.frame_id, config=config, nav=nav,
        algorithm=algorithm, estimator=estimator,
        truth=None if truth is None else (truth.stamp_ns, truth.quaternion), mag=mag_rows,
        empty=spool.empty)
    res, first, algorithm, notes = est.result, est.first, est.algorithm, est.notes
    if accel_problem:  # the estimator saw no accelerometer: say why there is none
        gyro_only = aiding_note(config, False)
        notes = [aiding_note(config, False, "its accelerometer is not in m/s² (said above)")
                 if n == gyro_only else n for n in notes]
    estimator = est.estimator
    t = t_all[first:]
    if res.index.size == 0:
        reasons = ", ".join(f"{n} {r}" for r, n in res.counts.items() if n and r != iv.GAP)
        raise ValueError(f"{input_path}: no usable sample on {imu.topic}: all {len(t)} "
                         f"skipped ({reasons})")
    t_int = time.perf_counter()

    keep = res.index + first if first else res.index
    every = keep.size == len(imu)
    t = t_all

    def kept(a):
        """Only the samples that got an attitude (no copy when all did)."""
        return a if every else a[keep]

    tv, qv = kept(t), res.q
    q_out = from_enu(qv, config.world_frame)  # the published frame (errors: in ENU, as truth)
    out_frame = frame_id_of(config.frame, config.world_frame)
    # the error figures before the output is written: nothing they need (working arrays, an
    # interrupt) can fail after the output is in place
    figures = _truth_figures(
        truth, tv, qv, spool.empty,
        start_from_truth=config.initial_attitude_source is InitialAttitudeSource.TRUTH) \
        if truth is not None and len(truth) else None
    passed = TopicCopy(input_path, on_damage=on_damage)  # /tf, /tf_static as recorded
    with SafeOutput(output_path, force=force) as tmp:
        with Rosbag2McapWriter(tmp, compression=compression, chunk_size=chunk_size) as w:
            w.add_topic("attitude", QUATERNION_STAMPED_TYPE)
            w.add_topic("imu/data", IMU_TYPE)
            # Block by block: what the write side builds (columns, covariance rows, the
            # chunk plan) is bounded by a block, not by the recording. The input is in
            # log-time order, so consecutive blocks keep the file in log-time order.
            for lo in range(0, keep.size, OUTPUT_BLOCK_MESSAGES):
                hi = min(lo + OUTPUT_BLOCK_MESSAGES, keep.size)
                rows = slice(keep[lo], keep[hi - 1] + 1) if every else keep[lo:hi]
                passed.write_until(w, int(imu.log_time_ns[keep[hi - 1]]))
                w.write_batches(_output_batches(imu, rows, tv[lo:hi], q_out[lo:hi],
                                                _block(res.variance, lo, hi),
                                                _block(res.variance_known, lo, hi), out_frame))
            passed.write_rest(w)
    t_end = time.perf_counter()

    result = ReplayResult(
        input=str(input_path), output=str(output_path), imu_topic=imu.topic,
        estimator=estimator.value, algorithm=algorithm, frame=frame, compression=compression,
        messages=len(imu),
        attitude_messages=int(keep.size), fast_path_messages=int(imu.fast_messages),
        fallback_messages=int(imu.fallback_messages), frame_ids=sorted(imu.frame_ids),
        skipped={r: n for r, n in res.counts.items() if r in iv.REJECT_REASONS and r != iv.GAP},
        gaps=res.counts[iv.GAP], time_jump_resets=res.time_jump_resets,
        invalid_covariances=res.counts["invalid_covariance"],
        integrator_errors=res.counts["integrator_error"],
        missing_samples=res.counts[iv.MISSING_SAMPLES], saturated=res.counts["saturated"],
        rate_fit_fallbacks=res.counts.get("rate_fit_fallback", 0), details=res.details,
        skipped_before_truth=first, gyro_bias=bias_summary(res.bias),
        gyro_bias_rad_s=np.asarray(res.bias.bias, float).tolist(),
        alignment=None if res.alignment is None else _alignment_summary(res.alignment),
        duration_s=float((tv.max() - tv.min()) * 1e-9),
        wall_seconds=t_end - t_start, read_seconds=t_read - t_start,
        integrate_seconds=t_int - t_read, write_seconds=t_end - t_int,
        messages_per_second=len(imu) / max(t_end - t_start, 1e-12), input_damage=damage,
        estimator_notes=notes + truth_notes + _spool_notes(spool), accel_problem=accel_problem,
        accel_note=accel_note,
        working_bytes_on_disk=spool.spooled_bytes,
        index=keep, t_ns=tv, q=q_out, error_t_ns=np.zeros(0, np.int64), error_rad=np.zeros(0))
    if use_mag and est.aiding is not None:
        aid = est.aiding
        result.magnetometer = {
            "topic": mag_info[0], "messages": mag_info[1],
            **{k: res.counts[k] for k in (MAG_MISSING, INVALID_MAG, MAG_DISTURBED)},
            "reference_changes": aid.mag_reference_changes,
            "reference_norm_t": aid.mag_ref_norm,
            "reference_dip_deg": None if aid.mag_ref_dip is None else math.degrees(
                aid.mag_ref_dip),
            "hard_iron_t": list(aid.hard_iron), "accel_rejected": aid.accel_rejected,
            "clock_offset_s": mag_offset}
    if figures is not None:
        for name, value in figures.items():
            setattr(result, name, value)
    result.truth_found = truth is not None and len(truth) > 0
    if not result.truth_found:
        result.truth_topic = truth_topic  # asked for, not in the input (the summary says so)
    return result


def _pose_truth(path, topic: str, type_name: str, child_frame: str | None) -> QuaternionArrays:
    """The orientations of a pose topic as truth (the trajectory input's reader)."""
    if type_name == POSE_TYPES[2] and not child_frame:
        raise ValueError(f"{path}: truth topic {topic} is a TFMessage: say which transform is "
                         "the IMU's (--truth-child-frame)")
    poses = read_pose_topic(path, topic, child_frame)
    return QuaternionArrays(topic=topic, stamp_ns=poses.t_ns, log_time_ns=None,
                            publish_time_ns=None, frame_id="", frame_ids=set(),
                            fast_messages=0, fallback_messages=len(poses.t_ns), damage=None,
                            quaternion=poses.q)


def _truth_figures(truth, t_ns: np.ndarray, q: np.ndarray, empty=np.empty,
                   start_from_truth: bool = False) -> dict | None:
    """Error figures at every truth stamp inside the output's span: the truth runs on its
    own clock (a tracker at 120 Hz beside a 200 Hz Imu shares no stamp), so the attitude is
    slerped there between the two output samples around it (exact at a coinciding stamp;
    none across a gap in the output, as truth_at_stamps decides). The dense series is the
    one interpolated: slerping a 10 Hz truth across a coning motion would measure the
    interpolation, not the estimate.

    Truth and output are compared where they overlap (``truth_overlap`` says over which
    span, and what each covers); truth that does not overlap the output at all gives no
    figures and a ``note`` naming both spans.  Besides the error angle: the tilt error and the
    signed heading error (about up) apart, and, unless the start was taken from the truth
    (``start_from_truth``), the heading error less its value at the first compared stamp
    (the start's heading offset removed: an identity start facing another way is no drift).

    Computed TRUTH_BLOCK truth stamps at a time: the slerp's and the error angle's (M, 4)
    temporaries are bounded by a block, not by the recording. Every step is row-local (the
    interval limit is taken once over the whole output), so the figures are those of one
    whole-recording pass, bit for bit.  The per-stamp arrays come from ``empty`` (replay's
    spool: the error series is an output of the recording's length)."""
    est_t, est_q = _strictly_increasing(t_ns, q)  # the output may jump back in time
    if est_t.size < 2:  # one attitude: nothing to slerp between
        return None
    ts, tq = _usable_truth(truth.stamp_ns, truth.quaternion, empty)
    if ts.size == 0:
        return None
    # where the truth and the output overlap: the truth stamps outside the output's span have
    # no attitude around them (a block of them gave truth_at_stamps one output sample)
    t0, t1 = int(est_t[0]), int(est_t[-1])
    s0, s1 = int(ts[0]), int(ts[-1])
    i0, i1 = int(np.searchsorted(ts, t0, side="left")), int(np.searchsorted(ts, t1,
                                                                              side="right"))
    spans = {"truth_span_s": [s0 * 1e-9, s1 * 1e-9], "output_span_s": [t0 * 1e-9, t1 * 1e-9],
             "overlap_s": max(min(s1, t1) - max(s0, t0), 0) * 1e-9}
    if i1 <= i0:
        return {"truth_topic": truth.topic, "truth_overlap": {
            **spans, "note": (
                f"the truth {truth.topic} {span_words(s0, s1)} does not "
                f"overlap the Imu output {span_words(t0, t1)} (another clock?): no error "
                "figures")}}
    if i0 or i1 < ts.size:
        ts, tq = ts[i0:i1], tq[i0:i1]
    limit = default_max_interval_ns(est_t)  # what truth_at_stamps takes over the whole output
    covered = empty(ts.size, bool)
    err = empty(ts.size, np.float64)
    n = 0
    tilt_sq = 0.0
    tilt_max = 0.0
    first = last = None  # (tilt, heading) at the first and last compared stamps
    for lo in range(0, ts.size, TRUTH_BLOCK):
        hi = min(lo + TRUTH_BLOCK, ts.size)
        s = ts[lo:hi]
        # the output samples around this block's stamps, one more on each side: the
        # neighbours a slerp needs (and the span's edges) are the ones of the whole output
        a = max(int(np.searchsorted(est_t, s[0], side="left")) - 1, 0)
        b = min(int(np.searchsorted(est_t, s[-1], side="right")) + 1, est_t.size)
        qe, cov = truth_at_stamps(est_t[a:b], est_q[a:b], s, max_interval_ns=limit)
        covered[lo:hi] = cov
        m = int(cov.sum())
        if m == 0:
            continue
        qt = tq[lo:hi][cov]
        err[n:n + m] = quat_angle_between(qe, qt)
        tilt, heading = tilt_and_heading_error(qe, qt)
        tilt_sq += float(np.dot(tilt, tilt))
        tilt_max = max(tilt_max, float(tilt.max()))
        if first is None:
            first = (float(tilt[0]), float(heading[0]))
        last = (float(tilt[-1]), float(heading[-1]))
        n += m
    if n == 0:
        return None
    err = err[:n]  # a view: no copy of the recording's length
    square = empty(n, np.float64)  # (the squares where the error series is: from ``empty``)
    np.multiply(err, err, out=square)
    return {"truth_topic": truth.topic, "truth_matched": n, "final_error_rad": float(err[-1]),
            "max_error_rad": float(err.max()),
            "rms_error_rad": float(np.sqrt(np.mean(square))),
            "final_tilt_error_rad": last[0], "max_tilt_error_rad": tilt_max,
            "rms_tilt_error_rad": math.sqrt(tilt_sq / n),
            "initial_tilt_error_rad": first[0],
            "final_heading_error_rad": last[1], "initial_heading_error_rad": first[1],
            "final_heading_error_from_start_rad": None if start_from_truth else float(
                (last[1] - first[1] + math.pi) % (2 * math.pi) - math.pi),
            "truth_overlap": spans,
            "error_t_ns": ts if n == ts.size else rows(ts, np.flatnonzero(covered), empty),
            "error_rad": err}


def _usable_truth(ts: np.ndarray, tq: np.ndarray, empty=np.empty) -> tuple[np.ndarray,
                                                                           np.ndarray]:
    """The truth samples that can be compared with: finite non-zero quaternions, sorted by
    stamp, the first of a repeated stamp (``ts``, ``tq`` themselves when all are)."""
    usable = empty(ts.size, bool)
    for lo in range(0, ts.size, TRUTH_BLOCK):
        b = tq[lo:lo + TRUTH_BLOCK]
        usable[lo:lo + TRUTH_BLOCK] = np.isfinite(b).all(axis=1) & (
            np.linalg.norm(b, axis=1) > 1e-9)
    if not usable.all():
        ts, tq = ts[usable], tq[usable]
    del usable
    return _strictly_increasing(ts, tq)


def _strictly_increasing(t: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Samples sorted by stamp, the first recorded of a repeated stamp kept (``t``, ``q``
    themselves, no copy, when they already are)."""
    if first_step_back(t, TRUTH_BLOCK) is None:
        return t, q
    order = np.argsort(t, kind="stable")
    t, q = t[order], q[order]
    first = np.r_[True, np.diff(t) > 0] if t.size else np.zeros(0, bool)
    return t[first], q[first]


def write_error_plot(result: ReplayResult, png, *, force: bool = True) -> None:
    """A plot (its format from the suffix) of the error against truth over time (or,
    without truth, the rotation from the initial attitude), written through a temporary
    file renamed into place."""
    # matplotlib is imported here: it costs ~0.5 s of start-up that a replay without
    # --plot does not need.
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    check_output_path(png, inputs=[result.input, result.output], force=force, what="plot")
    fig, ax = plt.subplots(figsize=(8, 4), constrained_layout=True)
    t0 = result.t_ns[0]
    if result.error_rad.size:
        t = (result.error_t_ns - t0) * 1e-9
        ax.semilogy(t, np.maximum(np.degrees(result.error_rad), 1e-16), lw=1)
        ax.set_ylabel("attitude error vs truth [deg]")
    else:
        q = result.q
        t = (result.t_ns - t0) * 1e-9
        ax.plot(t, np.degrees(quat_angle_between(q, q[0])), lw=1)
        ax.set_ylabel("rotation from the initial attitude [deg] (no truth in file)")
    ax.set_xlabel("time since first Imu stamp [s]")
    ax.set_title(f"replay {Path(result.input).name}: {result.estimator} {result.algorithm}, "
                 f"{result.frame}, "
                 f"{result.messages} msgs")
    ax.grid(True, which="both", alpha=0.3)
    try:
        with SafeOutput(png, force=force) as tmp:
            fig.savefig(tmp, dpi=110, format=plot_format(png))
    finally:
        plt.close(fig)
