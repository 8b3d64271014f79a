"""The files written from the estimator's settings table: the settings block of
``config/attitude_integrator.yaml`` and the table in docs/settings.md, each between a BEGIN and an
END marker line.  ``python -m gyro_attitude.io.settings_docs [REPO]`` rewrites both;
``test/ros/test_settings_table.py`` fails when they drift from the table.
"""

from __future__ import annotations

import sys
from pathlib import Path

from gyro_attitude.core.attitude.settings import markdown_table, yaml_lines

YAML_FILE = "config/attitude_integrator.yaml"
TABLE_FILE = "docs/settings.md"
YAML_BEGIN = "    # BEGIN estimator settings (from gyro_attitude/core/attitude/settings.py; " \
             "python -m gyro_attitude.io.settings_docs)"
YAML_END = "    # END estimator settings"
TABLE_BEGIN = "<!-- BEGIN estimator settings (from gyro_attitude/core/attitude/settings.py; " \
               "python -m gyro_attitude.io.settings_docs) -->"
TABLE_END = "<!-- END estimator settings -->"


def replace_block(text: str, begin: str, end: str, lines: list[str]) -> str:
    """``text`` with the lines between the ``begin`` and ``end`` marker lines replaced."""
    rows = text.split("\n")
    try:
        i, j = rows.index(begin), rows.index(end)
    except ValueError:
        raise ValueError(f"marker lines {begin!r} / {end!r} not found") from None
    if j < i:
        raise ValueError(f"{end!r} comes before {begin!r}")
    return "\n".join(rows[:i + 1] + lines + rows[j:])


def rendered(repo: Path) -> dict[Path, str]:
    """{file: the text it should have} for the two generated blocks."""
    yaml_path, table_path = repo / YAML_FILE, repo / TABLE_FILE
    return {
        yaml_path: replace_block(yaml_path.read_text(), YAML_BEGIN, YAML_END, yaml_lines()),
        table_path: replace_block(table_path.read_text(), TABLE_BEGIN, TABLE_END,
                                  markdown_table()),
    }


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) > 1 or (argv and argv[0].startswith("-")):
        print("usage: python -m gyro_attitude.io.settings_docs [REPO]  (rewrites the settings "
              "blocks of config/attitude_integrator.yaml and docs/settings.md)", file=sys.stderr)
        return 0 if argv and argv[0] in ("-h", "--help") else 2
    repo = Path(argv[0] if argv else ".")
    try:
        for path, text in rendered(repo).items():
            if path.read_text() != text:
                path.write_text(text)
                print(f"rewrote the settings block of {path}")
    except (OSError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
