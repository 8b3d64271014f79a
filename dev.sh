#!/usr/bin/env bash
# One entry point for a fresh machine (only Python 3.11 and the OS needed):
#   bash dev.sh demo   create/reuse .venv, install pinned Jazzy wheels + package, run the demo
#   bash dev.sh test   same set-up, then lint (ruff, import-linter) and the full test suite
# Any other arguments after the subcommand are passed on (gyro-attitude / pytest).
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
cd "$here"
venv="${GYRO_VENV:-$here/.venv}"
py="${PYTHON:-python3.11}"
command -v "$py" >/dev/null 2>&1 || py=python3

what="${1:-demo}"
shift || true

if [ ! -x "$venv/bin/python" ]; then
  echo "[dev.sh] creating virtual environment $venv" >&2
  "$py" -m venv "$venv"
fi
req=requirements.txt
[ "$what" = "test" ] && req=requirements-test.txt
stamp="$venv/.installed-$(cat requirements.txt "$req" | sha256sum | cut -c1-16)"
if [ ! -e "$stamp" ]; then
  echo "[dev.sh] installing pinned dependencies ($req)" >&2
  "$venv/bin/python" -m pip install --quiet --disable-pip-version-check --upgrade pip
  "$venv/bin/python" -m pip install --quiet --disable-pip-version-check -r "$req"
  touch "$stamp"
fi
# tf2_msgs (TF) from its interface definition, once, where nothing provides it; a machine
# without a compiler gets one line saying so, and everything but publish_tf still works
bash interfaces/build_tf2_msgs.sh "$venv"
echo "[dev.sh] installing gyro_attitude into $venv" >&2
# build/lib is setuptools' copy of the package: a module deleted from the source stays there
# and would be installed again, so the copy starts afresh
rm -rf build/ros_launchers build/lib
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check \
  --no-deps --no-build-isolation --force-reinstall .

# The per-sample kernels (numba) compiled once into their caches, so that no node or test waits
# for the compiler: the installed copy (what the commands and nodes run), and for the tests the
# source tree too (their subprocesses import it).
warm='from gyro_attitude.core.attitude.stream import compile_kernels; compile_kernels()'
echo "[dev.sh] compiling the per-sample kernels (cached after the first time)" >&2
# (the just-in-time loop too, where a precompiled one would be taken: it is the fallback)
(cd / && GYRO_ATTITUDE_PRECOMPILED=0 "$venv/bin/python" -c "$warm")
[ "$what" = "test" ] && GYRO_ATTITUDE_PRECOMPILED=0 "$venv/bin/python" -c "$warm"
# the recording loops (replay --estimator causal's, the offline estimator's rest and validation
# loops) compiled ahead of time (a fresh replay then needs no numba); without a C compiler one
# line says so and the loops are compiled just in time
echo "[dev.sh] compiling the recording loops ahead of time" >&2
(cd / && "$venv/bin/python" -m gyro_attitude.io.precompile) || true
if [ "$what" = "test" ]; then "$venv/bin/python" -m gyro_attitude.io.precompile || true; fi

# The ament index (package lookup of `ros2 run`, message .msg/.json files) lives in the venv.
export AMENT_PREFIX_PATH="$venv${AMENT_PREFIX_PATH:+:$AMENT_PREFIX_PATH}"
export PATH="$venv/bin:$PATH"
# Stay on loopback unless the user's own environment says otherwise.
export ROS_AUTOMATIC_DISCOVERY_RANGE="${ROS_AUTOMATIC_DISCOVERY_RANGE:-LOCALHOST}"
export MPLBACKEND="${MPLBACKEND:-Agg}"

case "$what" in
  demo)
    exec "$venv/bin/gyro-attitude" demo "$@" ;;
  test)
    "$venv/bin/ruff" check gyro_attitude test setup.py
    # the layering (core < io < ros | offline < commands), no import circles: .importlinter
    "$venv/bin/lint-imports" --no-cache --no-logo
    # pytest exits 5 when it collected no test: that is a failure here, as any nonzero.
    exec "$venv/bin/pytest" "$@" ;;
  *)
    exec "$venv/bin/gyro-attitude" "$what" "$@" ;;
esac
