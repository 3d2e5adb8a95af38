"""
Launch the vessel_kinematics navigator with its parameters file.

    ros2 launch vessel_kinematics navigator.launch.py
    ros2 launch vessel_kinematics navigator.launch.py params_file:=/path/to/my.yaml \
        use_sim_time:=true

The default parameters file is the installed ``share/vessel_kinematics/config/navigator.yaml``.
Remap the inputs and outputs in a launch file of your own (``remappings=[('fix', ...)]``) or
push a namespace around this one.
"""

from __future__ import annotations

import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue

PACKAGE = 'vessel_kinematics'
EXECUTABLE = 'navigator'
CONFIG = os.path.join('config', 'navigator.yaml')


def generate_launch_description() -> LaunchDescription:
    """Return the navigator node with ``params_file`` and ``use_sim_time`` arguments."""
    default_params = os.path.join(get_package_share_directory(PACKAGE), CONFIG)
    params_file = LaunchConfiguration('params_file')
    use_sim_time = LaunchConfiguration('use_sim_time')
    return LaunchDescription([
        DeclareLaunchArgument(
            'params_file', default_value=default_params,
            description='ROS 2 parameters file of the navigator'),
        DeclareLaunchArgument(
            'use_sim_time', default_value='false',
            description='true: take time from /clock (e.g. when playing a bag)'),
        Node(
            package=PACKAGE,
            executable=EXECUTABLE,
            name='navigator',
            output='screen',
            emulate_tty=True,
            parameters=[params_file,
                        {'use_sim_time': ParameterValue(use_sim_time, value_type=bool)}],
        ),
    ])
