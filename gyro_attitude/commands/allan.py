"""``gyro-attitude allan IN.mcap``: Allan deviation and IEEE 952 noise terms of a static Imu recording."""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

from gyro_attitude.commands import error_line
from gyro_attitude.commands.usage_errors import figure_file, output_file
from gyro_attitude.core.units import format_si
from gyro_attitude.io.safe_output import SafeOutput, check_output_path, plot_format
from gyro_attitude.io.scene_file import validate_scene_text
from gyro_attitude.io.strict_yaml import dump_yaml
from gyro_attitude.offline.allan import AXES, MIN_REST_S, analyse_mcap, plot

PROG = "gyro-attitude allan"

_GYRO_UNITS = (("random_walk", "N (ARW)", "angle random walk"),
               ("bias_instability", "B (bias inst.)", "angular rate"),
               ("rate_random_walk", "K (RRW)", "rate random walk"))
_ACCEL_UNITS = (("random_walk", "VRW", "velocity random walk"),
                ("bias_instability", "B (bias inst.)", "acceleration"),
                ("rate_random_walk", "AccRW", "acceleration random walk"))


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("input", metavar="IN.mcap", help="recording of an IMU at rest (where "
                        "it moves, the longest rest is analysed and the rests are listed)")
    parser.add_argument("--imu-topic", default="imu/data_raw", help="sensor_msgs/Imu topic")
    parser.add_argument("--json", metavar="PATH", type=output_file, help="write deviation and terms as JSON")
    parser.add_argument("--plot", metavar="PNG", type=figure_file(),
                        help="log-log plot with the fitted terms (format from the suffix: .png, "
                        ".pdf, .svg, ...)")
    parser.add_argument("--scene-out", metavar="YAML", type=output_file,
                        help="write a scene whose errors are the fitted terms")
    parser.add_argument("--kalibr-out", metavar="YAML", type=output_file,
                        help="write the fitted terms as a Kalibr / VIO imu.yaml (continuous-"
                             "time noise densities and random walks; a scene takes the same "
                             "file with kalibr_imu:)")
    parser.add_argument("--whole-record", action="store_true",
                        help="analyse every sample even where the IMU moves (the terms then "
                        f"include the motion); default: the longest rest of at least "
                        f"{MIN_REST_S:g} s")
    parser.add_argument("--force", action="store_true", help="overwrite existing outputs")


def _scene_yaml(result, source: str) -> str:
    errors = result.scene_errors()
    scene = {
        "description": f"IMU at rest with the noise fitted by gyro-attitude allan from {source}",
        "seed": 1,
        "rate_hz": round(1.0 / result.dt_s, 6),
        "duration_s": round(result.samples * result.dt_s, 3),
        # Allan analysis cannot see the site: set the latitude for the Earth rate you want.
        "earth": {"latitude_deg": 0.0},
        "motion": {"type": "stationary"},
        "gyro": {"model": "ideal", "errors": errors["gyro"]},
    }
    if "accelerometer" in errors:
        scene["accelerometer"] = {"gravity": True, "errors": errors["accelerometer"]}
    head = ("# Written by gyro-attitude allan: noise terms per axis (x, y, z) fitted to the\n"
            "# recording's Allan deviation. Bias, scale factor and misalignment are not\n"
            "# observable from it; add them if known. Set earth.latitude_deg to your site.\n")
    return head + dump_yaml(scene, allow_unicode=True)


_KALIBR_COMMENTS = {
    "accelerometer_noise_density": "white noise, continuous time [m/s^2/sqrt(Hz)]",
    "accelerometer_random_walk": "bias random walk, continuous time [m/s^3/sqrt(Hz)]",
    "gyroscope_noise_density": "white noise, continuous time [rad/s/sqrt(Hz)]",
    "gyroscope_random_walk": "bias random walk, continuous time [rad/s^2/sqrt(Hz)]",
    "rostopic": "the Imu topic analysed",
    "update_rate": "Hz: the rate these densities are discretized at",
}


def _kalibr_yaml(result, source: str) -> str:
    """Kalibr's imu.yaml with the units and the sampling-rate convention stated."""
    values, notes = result.kalibr()
    lines = [
        f"# Kalibr / VIO IMU noise model, fitted by gyro-attitude allan from {source}",
        "# (IEEE 952 Allan terms; the largest of the x, y, z axes; no inflation applied).",
        "# Continuous-time values: per sample at update_rate f, the white noise has",
        "#   sigma_d = noise_density * sqrt(f)   and the bias steps by",
        "#   sigma_bd = random_walk / sqrt(f)    (Kalibr's discretization).",
        "# noise_density is the Allan N (ARW / VRW: rad/sqrt(s) = rad/s/sqrt(Hz));",
        "# random_walk is the Allan K (RRW / AccRW), read on the +1/2 slope at tau = 3 s.",
    ]
    lines += [f"# note: {n}" for n in notes]
    for key, value in values.items():
        text = f"{value:.6e}" if isinstance(value, float) and key != "update_rate" else (
            f"{value}" if key != "rostopic" else f"'{value}'")
        lines.append(f"{key + ':':<30}{text:<16}# {_KALIBR_COMMENTS[key]}")
    return "\n".join(lines) + "\n"


def _check_scene(text: str, name: str) -> None:
    """The scene as ``simulate`` would load it: ValueError with its reason when refused."""
    validate_scene_text(text, Path(name))


def _check_kalibr(text: str, has_accel: bool, name: str) -> None:
    """The imu.yaml as a scene's ``kalibr_imu:`` would read it (the same checks and limits
    ``simulate`` applies): ValueError with the reason when refused."""
    scene = {"description": "check", "seed": 1, "rate_hz": 100.0, "duration_s": 1.0,
             "earth": {"latitude_deg": 0.0}, "motion": {"type": "stationary"}, "gyro": {"model": "ideal"},
             "kalibr_imu": "imu.yaml"}
    if has_accel:
        scene["accelerometer"] = {"gravity": True}
    with tempfile.TemporaryDirectory(prefix="gyro-attitude-allan-") as tmp:
        (Path(tmp) / "imu.yaml").write_text(text, encoding="utf-8")
        try:
            validate_scene_text(dump_yaml(scene), Path(tmp) / "check.yaml")
        except ValueError as exc:
            reason = str(exc).removeprefix("check.yaml: ")
            raise ValueError(f"{name} as a scene's kalibr_imu: {reason}") from None


def _write_text(path: str, text: str, force: bool) -> None:

    with SafeOutput(path, force=force) as tmp:
        tmp.write_text(text, encoding="utf-8")


def run(args: argparse.Namespace) -> int:

    outs = [(p, what) for p, what in ((args.json, "JSON"), (args.plot, "plot"),
                                      (args.scene_out, "scene"),
                                      (args.kalibr_out, "Kalibr")) if p]
    try:
        # Before any work: never the input (also through a symlink), never an existing
        # file without --force, never one output twice.
        for i, (p, what) in enumerate(outs):
            check_output_path(p, inputs=[args.input, *(q for q, _ in outs[:i])],
                              force=args.force, what=f"{what} output")
        if args.plot:
            plot_format(args.plot)
        result = analyse_mcap(args.input, args.imu_topic, whole_record=args.whole_record)
    except (ValueError, OSError) as exc:
        error_line("allan", exc)
        return 1
    span = "" if result.analysed_s is None else \
        f" (the rest {result.analysed_s[0]:g}–{result.analysed_s[1]:g} s)"
    print(f"[allan] {args.input} {result.topic}: {result.samples} samples every "
          f"{result.dt_s * 1e3:g} ms{span}, τ from {result.tau_s[0]:g} s to "
          f"{result.tau_s[-1]:g} s")
    for name, axes, units in (("gyro", result.gyro, _GYRO_UNITS),
                              ("accelerometer", result.accel, _ACCEL_UNITS)):
        if axes is None:
            continue
        print(f"[allan] {name}:")
        for axis in AXES:
            t = axes[axis].terms
            cells = [f"{label} " + ("not visible" if getattr(t, term) is None
                                    else format_si(getattr(t, term), kind))
                     for term, label, kind in units]
            print(f"  {axis}: " + ";  ".join(cells))
    for note in result.notes:
        print(f"[allan] note: {note}")
    if result.moving:
        print(f"{PROG}: warning: the IMU moves in {Path(args.input).name}: "
              + ("the terms are those of the longest rest (see the note)"
                 if result.analysed_s is not None else
                 "the terms include the motion (--whole-record)"), file=sys.stderr)
    source = Path(args.input).name
    texts = {}
    try:
        # every file checked before the first is written: a scene or imu.yaml that simulate
        # would refuse is never written (nor the others beside it)
        if args.scene_out:
            texts["scene"] = _scene_yaml(result, source)
            _check_scene(texts["scene"], Path(args.scene_out).name)
        if args.kalibr_out:
            texts["kalibr"] = _kalibr_yaml(result, source)
            _check_kalibr(texts["kalibr"], result.accel is not None,
                          Path(args.kalibr_out).name)
    except ValueError as exc:
        print(f"{PROG}: error: the fitted terms make no scene simulate accepts ({exc}); "
              "nothing written", file=sys.stderr)
        return 1
    try:
        if args.json:
            _write_text(args.json, json.dumps(result.to_json(), indent=1), args.force)
            print(f"[allan] JSON -> {args.json}")
        if args.scene_out:
            _write_text(args.scene_out, texts["scene"], args.force)
            print(f"[allan] scene -> {args.scene_out}")
        if args.kalibr_out:
            _write_text(args.kalibr_out, texts["kalibr"], args.force)
            print(f"[allan] Kalibr imu.yaml -> {args.kalibr_out}")
        if args.plot:
            with SafeOutput(args.plot, force=args.force) as tmp:
                # matplotlib picks the format from the name: keep the requested suffix
                plot(result, tmp, title=f"{Path(args.input).name} {result.topic}")
            print(f"[allan] plot -> {args.plot}")
    except (ValueError, OSError) as exc:
        error_line("allan", f"cannot write output: {exc}")
        return 1
    return 0
