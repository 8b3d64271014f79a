"""ament_python package gyro_attitude: builds with colcon (ROS users) and with pip (venv)."""

import os
import stat
import sys
from glob import glob

from setuptools import find_packages, setup

package_name = "gyro_attitude"

# Executables `ros2 run gyro_attitude <name>` finds, plus the `gyro-attitude` console command.
EXECUTABLES = {
    "gyro-attitude": "gyro_attitude.cli:main",
    "gyro_sim": "gyro_attitude.ros.gyro_sim_node:main",
    "attitude_integrator": "gyro_attitude.ros.attitude_integrator_node:main",
    "mcap_recorder": "gyro_attitude.ros.mcap_recorder_node:main",
    "mcap_player": "gyro_attitude.ros.mcap_player_node:main",
}


def _wheel_launchers():
    """Launchers at PREFIX/lib/gyro_attitude/<exe> for pip (wheel) installs.

    colcon honours setup.cfg and installs console scripts into lib/<pkg>, where `ros2 run`
    looks. pip ignores setup.cfg's [install] section and writes console scripts to
    PREFIX/bin, so a wheel also carries small launchers in lib/<pkg> that exec the
    PREFIX/bin script (which has the right interpreter in its shebang).
    """
    if not any(cmd in sys.argv for cmd in ("bdist_wheel", "editable_wheel")):
        return []
    out_dir = os.path.join("build", "ros_launchers")
    os.makedirs(out_dir, exist_ok=True)
    files = []
    for name in EXECUTABLES:
        path = os.path.join(out_dir, name)
        with open(path, "w", encoding="utf-8") as f:
            f.write(
                "#!/bin/sh\n"
                f"# ros2 run launcher: PREFIX/lib/{package_name}/{name} -> PREFIX/bin/{name}\n"
                f'exec "$(dirname "$0")/../../bin/{name}" "$@"\n'
            )
        os.chmod(path, os.stat(path).st_mode | stat.S_IXUSR | stat.S_IXGRP | stat.S_IXOTH)
        files.append(path)
    return [(os.path.join("lib", package_name), files)]


setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test", "test.*"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/config", glob("config/*.yaml")),
        ("share/" + package_name + "/config/scenes", glob("config/scenes/*.yaml")),
        # pose files the shipped trajectory scenes name (relative to the scene directory)
        ("share/" + package_name + "/config/trajectories", glob("config/trajectories/*.tum")),
        # `ros2 launch gyro_attitude demo.launch.py` finds launch files here
        ("share/" + package_name + "/launch", glob("launch/*.launch.py")),
        # The shipped sample only: demo and recorder output (bags/demo_*, bags/recording_*)
        # lands in the same folder and must not be installed.
        ("share/" + package_name + "/bags", sorted(
            p for p in glob("bags/*.mcap") if not os.path.basename(p).startswith(("demo_", "recording_")))),
    ]
    + _wheel_launchers(),
    package_data={package_name: ["py.typed"]},
    install_requires=["setuptools", "numpy", "scipy", "mcap", "pyyaml", "tqdm", "matplotlib",
                      "allantools", "wmm-calculator"],
    zip_safe=True,
    maintainer="gyro_attitude developers",
    maintainer_email="gyro-attitude@example.org",
    description="Gyroscope mechanics and attitude: gimballed-gyro simulator, quaternion "
    "attitude integrators, rosbag2-compatible MCAP recording and fast replay.",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [f"{name} = {target}" for name, target in EXECUTABLES.items()],
    },
)
