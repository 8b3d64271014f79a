#!/usr/bin/env bash
# Build tf2_msgs (TFMessage only, interfaces/tf2_msgs) into a pip-only virtual environment
# whose ROS wheels do not ship it, so that the nodes can publish TF (publish_tf).
#   bash interfaces/build_tf2_msgs.sh VENV
# Skipped when VENV's Python imports a tf2_msgs not built here (a system ROS); built again
# when the interface files, this script or requirements.txt change.
# Never fails the set-up: what is missing (a compiler, CMake, Python headers) or a failed
# build is said in one line, and everything but publish_tf works without it.
set -uo pipefail
venv="$(cd "$1" && pwd)"
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
src="$here/tf2_msgs"
py="$venv/bin/python"
say() { echo "[dev.sh] $*" >&2; }
off="TF (publish_tf) stays off; everything else works"

# built again when the interface, this script or the pinned wheels (requirements.txt) change
stamp="$venv/.tf2_msgs-$(cat "$src/package.xml" "$src/CMakeLists.txt" "$src/msg/TFMessage.msg" \
  "$0" "$here/../requirements.txt" | sha256sum | cut -c1-16)"
[ -e "$stamp" ] && exit 0
built_before="$(ls "$venv"/.tf2_msgs-built-* 2>/dev/null | head -1)"
if [ -z "$built_before" ] && (cd / && "$py" -c 'import tf2_msgs.msg' 2>/dev/null); then
  touch "$stamp"  # provided by a system ROS on the path: nothing to build
  exit 0
fi

missing=()
command -v cc >/dev/null 2>&1 || missing+=("a C compiler (apt-get install gcc)")
command -v c++ >/dev/null 2>&1 || missing+=("a C++ compiler (apt-get install g++)")
command -v make >/dev/null 2>&1 || missing+=("make (apt-get install make)")
include="$("$py" -c 'import sysconfig; print(sysconfig.get_paths()["include"])')"
[ -e "$include/Python.h" ] || missing+=("the Python headers $include/Python.h (apt-get install python3-dev)")
cmake_bin="$(command -v cmake || true)"
if [ -z "$cmake_bin" ] && [ ${#missing[@]} -eq 0 ]; then
  # no system CMake: the PyPI wheel of it, into the virtual environment
  "$py" -m pip install --quiet --disable-pip-version-check -r "$here/requirements-cmake.txt" \
    && cmake_bin="$venv/bin/cmake"
  [ -x "$cmake_bin" ] || missing+=("CMake (apt-get install cmake, or pip install cmake)")
fi
if [ ${#missing[@]} -gt 0 ]; then
  say "tf2_msgs not built: missing $(IFS=';'; echo "${missing[*]}" | sed 's/;/, /g'); $off"
  exit 0
fi

say "building tf2_msgs (TFMessage) into $venv (once)"
build="$(mktemp -d)"
log="$venv/.tf2_msgs-build.log"
trap 'rm -rf "$build"' EXIT
export AMENT_PREFIX_PATH="$venv${AMENT_PREFIX_PATH:+:$AMENT_PREFIX_PATH}"
export CMAKE_PREFIX_PATH="$venv${CMAKE_PREFIX_PATH:+:$CMAKE_PREFIX_PATH}"
export PATH="$venv/bin:$PATH"
if "$cmake_bin" -S "$src" -B "$build" -DCMAKE_INSTALL_PREFIX="$venv" -DBUILD_TESTING=OFF \
      -DPython3_EXECUTABLE="$py" -DCMAKE_BUILD_TYPE=Release >"$log" 2>&1 \
    && "$cmake_bin" --build "$build" -j "$(nproc 2>/dev/null || echo 2)" >>"$log" 2>&1 \
    && "$cmake_bin" --install "$build" >>"$log" 2>&1 \
    && (cd / && "$py" -c 'import tf2_msgs.msg') >>"$log" 2>&1; then
  rm -f "$venv"/.tf2_msgs-built-* "$venv"/.tf2_msgs-????????????????  # earlier stamps
  touch "$stamp" "$venv/.tf2_msgs-built-${stamp##*-}"
else
  say "tf2_msgs build failed (see $log); $off"
fi
exit 0
