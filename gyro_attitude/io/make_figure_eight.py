"""Write the shipped trajectory example ``config/trajectories/figure_eight.tum`` deterministically.

``python -m gyro_attitude.io.make_figure_eight [OUT.tum] [--seconds 30] [--rate-hz 120]``

The closed-form figure-eight of :mod:`gyro_attitude.core.figure_eight` (a walk with a
hand-held IMU) sampled as a motion-capture system records it: 120 Hz, stamps from 1 s,
with mocap-like noise of 1 mm per position axis and 0.1° per attitude axis (seeded, so the
same arguments give the same bytes). The scene ``figure_eight_walk`` moves a MEMS IMU
along it with ``position_sigma_m: 0.001`` and ``attitude_sigma_rad: 0.00175``.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

from gyro_attitude.core.figure_eight import FigureEight
from gyro_attitude.core.rotation import quat_from_rotvec, quat_multiply
from gyro_attitude.io.safe_output import SafeOutput, check_output_path

START_S = 1.0
POSITION_NOISE_M = 1e-3
ATTITUDE_NOISE_RAD = math.radians(0.1)
SEED = 2024


def default_output() -> Path:
    return Path(__file__).resolve().parents[2] / "config" / "trajectories" / "figure_eight.tum"


def figure_eight_poses(seconds: float = 30.0, rate_hz: float = 120.0, noise: bool = True):
    """``(t (n,) s, p (n,3), q (n,4))`` of the figure-eight sampled from ``START_S``."""
    k = np.arange(int(round(seconds * rate_hz)) + 1)
    t_rel = k / rate_hz
    p, q = FigureEight().poses(t_rel)
    if noise:
        rng = np.random.default_rng(SEED)
        p = p + POSITION_NOISE_M * rng.standard_normal(p.shape)
        q = quat_multiply(q, quat_from_rotvec(ATTITUDE_NOISE_RAD
                                              * rng.standard_normal((k.size, 3))))
    return START_S + t_rel, p, q


def write_tum(out, t, p, q, header: str = "", force: bool = True) -> Path:
    """TUM lines ``timestamp tx ty tz qx qy qz qw`` (9 decimals), written atomically."""
    out = check_output_path(out, force=force)
    rows = np.column_stack((t, p, q))
    with SafeOutput(out, force=force) as tmp:
        with open(tmp, "w", encoding="utf-8") as f:
            for line in header.splitlines():
                f.write(f"# {line}\n")
            f.write("# timestamp tx ty tz qx qy qz qw\n")
            np.savetxt(f, rows, fmt="%.9f")
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", nargs="?", default=str(default_output()))
    parser.add_argument("--seconds", type=float, default=30.0)
    parser.add_argument("--rate-hz", type=float, default=120.0)
    args = parser.parse_args(argv)
    try:
        t, p, q = figure_eight_poses(args.seconds, args.rate_hz)
        out = write_tum(args.out, t, p, q, header=(
            "figure-eight walked with a hand-held IMU (gyro_attitude.core.figure_eight), "
            f"{args.rate_hz:g} Hz, noise {POSITION_NOISE_M * 1e3:g} mm / 0.1 deg, seed {SEED}\n"
            "written by python -m gyro_attitude.io.make_figure_eight"))
    except (ValueError, OSError) as exc:
        print(f"make_figure_eight: error: {exc}", file=sys.stderr)
        return 1
    print(f"[make_figure_eight] {t.size} poses -> {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
