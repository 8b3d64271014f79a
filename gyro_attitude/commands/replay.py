"""``gyro-attitude replay IN.mcap --out OUT.mcap``: arguments and printing of the offline
replay (the pipeline is :func:`gyro_attitude.offline.replay.replay_file`).

Exit status: 0 done, 1 unusable input or output, 2 bad arguments, 130 interrupted; every
failure is one line on stderr, and no partial output is left under the requested names.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from gyro_attitude.commands import error_line
from gyro_attitude.commands.estimator_flags import (
    add_estimator_flags,
    config_from_args,
    given_settings,
)
from gyro_attitude.commands.replay_fleet import add_fleet_flags, run_fleet
from gyro_attitude.core.attitude import ALGORITHMS, DEFAULT_OFFLINE_ALGORITHM
from gyro_attitude.core.attitude import validation as iv
from gyro_attitude.core.attitude.modes import Estimator, Frame
from gyro_attitude.core.attitude.sample_alignment import field_clock_warning
from gyro_attitude.core.attitude.settings import StreamConfig
from gyro_attitude.io.mcap_writer import COMPRESSIONS, DEFAULT_COMPRESSION
from gyro_attitude.io.safe_output import check_output_path, plot_format
from gyro_attitude.offline.replay import (
    DEFAULT_IMU_TOPIC,
    DEFAULT_MAG_TOPIC,
    TRUTH_TOPIC,
    replay_file,
    write_error_plot,
)

__all__ = ["configure", "run", "replay_file"]

_PROGRESS_MIN_BYTES = 50 * 1024 * 1024  # show a progress bar from this file size on


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("input", metavar="IN.mcap", nargs="+",
                        help="recording (file or bag directory); several, or a glob, with "
                        "--out-dir (fleet replay)")
    parser.add_argument("--out", metavar="OUT.mcap",
                        help="output MCAP file (never the input; written to a temporary "
                        "file and renamed when complete)")
    add_fleet_flags(parser)
    parser.add_argument("--force", action="store_true",
                        help="overwrite an existing OUT (and --plot file)")
    parser.add_argument("--imu-topic", default=DEFAULT_IMU_TOPIC,
                        help=f"sensor_msgs/Imu topic to integrate (default {DEFAULT_IMU_TOPIC})")
    parser.add_argument("--algorithm", default=None,
                        choices=sorted(ALGORITHMS),
                        help=f"attitude update algorithm (default {DEFAULT_OFFLINE_ALGORITHM}, "
                        "which uses samples after each interval; with --estimator causal the "
                        "node's causal default rotvec_cubic when a per-sample filter acts on "
                        "the recording: levelling, aiding, or auto gyro bias with a rest)")
    parser.add_argument("--estimator", default=Estimator.OFFLINE.value,
                        choices=[m.value for m in Estimator],
                        help="offline (default): the whole recording at once, every attitude "
                        "using the samples before and after it (rests, bias per rest, tilt "
                        "from gravity zero-phase); causal: the live node's attitudes, sample "
                        "for sample")
    add_estimator_flags(parser)  # the attitude_integrator node's settings, same names
    parser.add_argument("--mag-topic", default=DEFAULT_MAG_TOPIC,
                        help="sensor_msgs/MagneticField topic for --aiding magnetometer "
                        f"(default {DEFAULT_MAG_TOPIC}; matched to the Imu stamps as the node "
                        "does)")
    parser.add_argument("--odometry-topic", default=None, metavar="TOPIC",
                        help="nav_msgs/Odometry topic of the recording whose velocity sets the "
                        "transport rate (--frame enu), time-aligned to the Imu stamps as the "
                        "node's odometry_topic")
    parser.add_argument("--truth-topic", default=TRUTH_TOPIC,
                        help="truth to compare with: geometry_msgs/QuaternionStamped, or the "
                        "orientation of a PoseStamped, Odometry or TFMessage topic (a "
                        f"motion-capture system's) (default {TRUTH_TOPIC})")
    parser.add_argument("--truth-child-frame", default=None, metavar="FRAME",
                        help="with a TFMessage truth topic: the child frame of the transforms "
                        "that are the IMU's pose")
    parser.add_argument("--compression", choices=COMPRESSIONS, default=DEFAULT_COMPRESSION,
                        type=lambda s: "" if s == "none" else s, metavar="{zstd,lz4,none}",
                        help=f"chunk compression of OUT (default {DEFAULT_COMPRESSION})")
    parser.add_argument("--json", action="store_true", help="print the summary as JSON")
    parser.add_argument("--plot", metavar="IMAGE", default=None,
                        help="write an error plot (.png, .pdf, .svg or .jpg, by its suffix)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def _progress_bar(args):
    in_path = Path(args.input)
    size = in_path.stat().st_size if in_path.is_file() else 0
    if args.no_progress or args.json or size < _PROGRESS_MIN_BYTES or not sys.stderr.isatty():
        return None, None
    from tqdm import tqdm  # only for large files on a terminal

    bar = tqdm(total=100, unit="%", desc="read", file=sys.stderr, leave=False)

    def update(done, total):
        bar.n = int(100 * done / max(total, 1))
        bar.refresh()

    return bar, update


# warning words per policy event (the rest are skipped samples, named by their reason)
_EVENT_WORDS = {
    iv.GAP: "gap(s) not integrated across, attitude held",
    "time_jump": "backward time jump(s): attitude reset",
    "invalid_covariance": "invalid angular_velocity_covariance(s) treated as unknown",
    "integrator_error": "non-finite update(s): last good attitude restored",
    "mag_missing": "Imu sample(s) with no magnetic field within mag_max_age_s: heading gyro-only",
    "invalid_mag": "magnetic field sample(s) not finite, absurd or zero: not used",
    "mag_disturbed": "magnetic field sample(s) disturbed (norm or dip off the reference): "
                     "heading gyro-only",
    "saturated": "gyro sample(s) pinned at a repeated extreme (saturated: attitude unreliable)",
    "rate_fit_fallback": "interval(s) whose rate fit could not be trusted (the samples alias "
                         "the motion): integrated toward the exponential map, attitude "
                         "unreliable there",
    iv.MISSING_SAMPLES: "sample(s) missing inside accepted intervals (integrated across; "
                        "longer holes are gaps: --max-missing-samples)",
}


def truth_lines(out: dict) -> list[str]:
    """The summary's lines on the error against the truth: the angle, the tilt and the
    heading apart, the heading less the start's offset when the start was not the truth's,
    and the span compared when truth and output only partly overlap."""
    if not out["truth_matched"]:
        if not out["truth_found"]:
            return [f"  no error figures: no truth topic {out['truth_topic']!r} with messages "
                    "in the input (--truth-topic)"]
        if (out["truth_overlap"] or {}).get("note"):
            return ["  no error figures: the truth does not overlap the output (see the "
                    "warning)"]
        return ["  no error figures: no truth stamp inside the span of two attitudes"]
    d = np.degrees
    lines = [f"  vs {out['truth_topic']} ({out['truth_matched']} stamps): final error "
             f"{d(out['final_error_rad']):.3g}° (tilt {d(out['final_tilt_error_rad']):.3g}°, "
             f"heading {d(out['final_heading_error_rad']):+.3g}°), max "
             f"{d(out['max_error_rad']):.3g}°, RMS {d(out['rms_error_rad']):.3g}°; tilt RMS "
             f"{d(out['rms_tilt_error_rad']):.3g}°, max {d(out['max_tilt_error_rad']):.3g}°"]
    if out["final_heading_error_from_start_rad"] is not None:
        lines.append(
            f"  the start was not taken from the truth: heading error at the first truth "
            f"stamp {d(out['initial_heading_error_rad']):+.3g}°, tilt "
            f"{d(out['initial_tilt_error_rad']):.3g}°; final heading error less that offset "
            f"{d(out['final_heading_error_from_start_rad']):+.3g}°"
            + (" (a wrong start: --initial-attitude level or truth)"
               if out["initial_tilt_error_rad"] > np.radians(10.0) else ""))
    ov = out["truth_overlap"]
    out_s = ov["output_span_s"][1] - ov["output_span_s"][0]
    truth_s = ov["truth_span_s"][1] - ov["truth_span_s"][0]
    if ov["overlap_s"] < 0.99 * out_s or ov["overlap_s"] < 0.99 * truth_s:
        lines.append(f"  compared over the {ov['overlap_s']:.3f} s where truth and output "
                     f"overlap: {100 * ov['overlap_s'] / max(out_s, 1e-9):.0f} % of the "
                     f"output's {out_s:.3f} s, {100 * ov['overlap_s'] / max(truth_s, 1e-9):.0f} "
                     f"% of the truth's {truth_s:.3f} s")
    return lines


def _stream_config(args) -> StreamConfig:
    given = given_settings(args)
    if given.get("frame") is Frame.ENU and "latitude_rad" not in given:
        raise ValueError("--frame enu needs --latitude-deg (or --latitude-rad)")
    return config_from_args(args)


def run(args) -> int:
    try:
        config = _stream_config(args)
    except ValueError as exc:
        error_line("replay", exc)
        return 2
    if args.out_dir is not None or len(args.input) > 1:
        return run_fleet(args, config)
    if args.out is None:
        error_line("replay", "give --out OUT.mcap (or --out-dir DIR for several inputs)")
        return 2
    args.input = args.input[0]
    from gyro_attitude.io.mcap_reader import UnorderedBagError
    from gyro_attitude.offline.fleet import separate_recordings_hint

    bar = None
    try:
        # Every output path is checked before the work (the plot is written last).
        check_output_path(args.out, inputs=[args.input], force=args.force)
        if args.plot:
            check_output_path(args.plot, inputs=[args.input, args.out], force=args.force,
                              what="plot")
            plot_format(args.plot)
        bar, update = _progress_bar(args)
        result = replay_file(
            args.input, args.out, imu_topic=args.imu_topic, algorithm=args.algorithm,
            truth_topic=args.truth_topic, odometry_topic=args.odometry_topic,
            compression=args.compression, force=args.force,
            progress=update, config=config, estimator=args.estimator,
            mag_topic=args.mag_topic, truth_child_frame=args.truth_child_frame)
        if bar is not None:
            bar.close()
            bar = None
        if args.plot:
            write_error_plot(result, args.plot, force=True)  # checked above
    except UnorderedBagError as exc:
        error_line("replay", f"{exc}{separate_recordings_hint(exc)}")
        return 1
    except (ValueError, OSError) as exc:
        error_line("replay", exc)
        return 1
    except KeyboardInterrupt:
        print("interrupted: no output written", file=sys.stderr)
        return 130
    finally:
        if bar is not None:
            bar.close()
    out = result.summary()
    if out["input_damage"]:
        print(f"warning: input damaged, replayed everything readable: {out['input_damage']}",
              file=sys.stderr)
    # once per reason: how many, and the first case in words
    events = {**out["skipped"], iv.GAP: out["gaps"], "time_jump": out["time_jump_resets"],
              "invalid_covariance": out["invalid_covariances"],
              "integrator_error": out["integrator_errors"],
              iv.MISSING_SAMPLES: out["missing_samples"], "saturated": out["saturated"],
              "rate_fit_fallback": out["rate_fit_fallbacks"],
              **{k: v for k, v in (out["magnetometer"] or {}).items()
                 if k in ("mag_missing", "invalid_mag", "mag_disturbed")}}
    for reason, n in events.items():
        if n:
            what = _EVENT_WORDS.get(reason, f"sample(s) skipped ({reason})")
            print(f"warning: {n} {what}; first: {out['details'].get(reason, '')}",
                  file=sys.stderr)
    offset_warning = field_clock_warning((out["magnetometer"] or {}).get("clock_offset_s"))
    if offset_warning:
        print(f"warning: {offset_warning}", file=sys.stderr)
    for key in ("accel_problem", "accel_note"):
        if out[key]:
            print(f"warning: {out[key]}", file=sys.stderr)
    note = (out["truth_overlap"] or {}).get("note")
    if note:
        print(f"warning: {note}", file=sys.stderr)
    if "gyro_noise_unknown" in out["details"]:
        print(f"note: {out['details']['gyro_noise_unknown']}", file=sys.stderr)
    if len(out["frame_ids"]) > 1:
        print(f"warning: frame_id changes inside {out['imu_topic']} ({out['frame_ids']}): "
              "integrated as one frame", file=sys.stderr)
    for note in out["estimator_notes"]:
        if note.startswith("no accelerometer") and not out["accel_problem"]:
            print(f"note: {note}", file=sys.stderr)
    if args.json:
        print(json.dumps(out, indent=2))
        return 0
    print(f"replayed {out['messages']} Imu messages from {out['imu_topic']} "
          f"({out['duration_s']:.3f} s of data), {out['estimator']} estimator, "
          f"{out['algorithm']}, {out['frame']} frame")
    if out["estimator_notes"]:
        print(f"  {'; '.join(out['estimator_notes'])}")
    skipped = sum(out["skipped"].values())
    print(f"  {out['attitude_messages']} attitudes; skipped {skipped}"
          + (f" ({', '.join(f'{n} {r}' for r, n in out['skipped'].items() if n)})"
             if skipped else "")
          + f"; gaps {out['gaps']}; time-jump resets {out['time_jump_resets']}"
          + (f"; {out['skipped_before_truth']} before the truth starts"
             if out["skipped_before_truth"] else ""))
    print(f"  {out['gyro_bias']}")
    if out["magnetometer"]:
        m = out["magnetometer"]
        ref = ("not learned" if m["reference_norm_t"] is None else
               f"|B| {m['reference_norm_t'] * 1e6:.1f} µT, dip {m['reference_dip_deg']:.1f}°")
        print(f"  magnetometer {m['topic']}: {m['messages']} samples, reference {ref}, "
              f"{m['mag_disturbed']} disturbed, {m['invalid_mag']} invalid, "
              f"{m['mag_missing']} Imu samples without a field")
    if out["alignment"]:
        a = out["alignment"]
        print(f"  levelled over {a['rest_s']:.1f} s of rest: roll {a['roll_deg']:.3f}°, pitch "
              f"{a['pitch_deg']:.3f}° (expected error {a['level_error_expected_deg']:.3f}°), "
              f"heading {a['heading_deg']:.2f}° ({a['heading_source']})")
    print(f"  wall {out['wall_seconds']:.3f} s ({out['messages_per_second']:.0f} msg/s): "
          f"read {out['read_seconds']:.3f} s, integrate {out['integrate_seconds']:.3f} s, "
          f"write {out['write_seconds']:.3f} s")
    if out["working_bytes_on_disk"]:
        print(f"  {out['working_bytes_on_disk'] / 1e6:.0f} MB of working arrays kept "
              "in files beside the output (unlinked, gone when the replay ends)")
    for line in truth_lines(out):
        print(line)
    print(f"  wrote {out['output']} (attitude, imu/data; compression "
          f"{out['compression'] or 'none'})" + (f", plot {args.plot}" if args.plot else ""))
    return 0
