"""``gyro-attitude scenes [NAME] [--check]``: list the shipped scenes, or validate one and print its YAML."""

from __future__ import annotations

import argparse
import sys

from gyro_attitude.commands import error_line
from gyro_attitude.io.scene_file import (
    find_scene_file,
    list_scenes,
    load_scene,
    read_scene_text,
    validate_scene_text,
)


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("name", nargs="?",
                        help="scene name or path: validate it and print its YAML")
    parser.add_argument("--check", action="store_true",
                        help="also validate every listed scene and report errors (exit 1 on any)")


def run(args: argparse.Namespace) -> int:
    if args.name:
        # Only a valid scene is printed: a path to any other file gets one line and exit 1.
        try:
            path = find_scene_file(args.name)
            text = read_scene_text(path)
            validate_scene_text(text, path)
        except ValueError as exc:
            error_line("scenes", exc)
            return 1
        sys.stdout.write(text)
        return 0
    scenes = list_scenes()
    if not scenes:
        print("no scenes found", file=sys.stderr)
        return 1
    width = max(len(name) for name, _ in scenes)
    status = 0
    for name, description in scenes:
        print(f"{name:<{width}}  {description}")
        if args.check:
            try:
                load_scene(name)
            except ValueError as exc:
                print(f"{'':<{width}}  error: {exc}")
                status = 1
    return status
