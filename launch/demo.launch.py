"""gyro_sim + attitude_integrator (+ mcap_recorder with record:=true) on one scene.

    ros2 launch gyro_attitude demo.launch.py scene:=ship rate_hz:=200.0 algorithm:=exp_map \
        frame:=enu record:=true

Node parameters start from the installed config/<node>.yaml files; the launch arguments
override the ones they name. rate_hz 0.0 = the scene's own rate.
"""

import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.conditions import IfCondition
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue

PACKAGE = "gyro_attitude"


def generate_launch_description():
    config = os.path.join(get_package_share_directory(PACKAGE), "config")
    scene = LaunchConfiguration("scene")
    rate_hz = LaunchConfiguration("rate_hz")
    algorithm = LaunchConfiguration("algorithm")
    frame = LaunchConfiguration("frame")
    record = LaunchConfiguration("record")
    return LaunchDescription([
        DeclareLaunchArgument("scene", default_value="coning",
                              description="scene name (config/scenes/<name>.yaml) or path"),
        DeclareLaunchArgument("rate_hz", default_value="0.0",
                              description="Imu rate [Hz]; 0.0 = the scene's own rate"),
        DeclareLaunchArgument("algorithm", default_value="rotvec_cubic",
                              description="attitude algorithm of attitude_integrator"),
        DeclareLaunchArgument("frame", default_value="inertial",
                              description="inertial (q_ib) or enu (q_nb)"),
        DeclareLaunchArgument("record", default_value="false",
                              description="also record the topics with mcap_recorder"),
        Node(
            package=PACKAGE, executable="gyro_sim", name="gyro_sim", output="screen",
            parameters=[os.path.join(config, "gyro_sim.yaml"), {
                "scene": scene,
                # typed explicitly: a bare "500" would arrive as an integer
                "rate_hz": ParameterValue(rate_hz, value_type=float),
            }],
        ),
        Node(
            package=PACKAGE, executable="attitude_integrator", name="attitude_integrator",
            output="screen",
            parameters=[os.path.join(config, "attitude_integrator.yaml"), {
                "algorithm": algorithm,
                "frame": frame,
            }],
        ),
        Node(
            package=PACKAGE, executable="mcap_recorder", name="mcap_recorder", output="screen",
            parameters=[os.path.join(config, "mcap_recorder.yaml")],
            condition=IfCondition(record),
        ),
    ])
