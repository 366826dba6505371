"""Launch the simulator and the alignment node together (real ROS 2 installs).

    ros2 launch sins_align_ros alignment.launch.py scenario:=ship_sway

Arguments: ``scenario`` (a simulator preset), ``use_sim`` (start the simulator,
default true), ``params`` (alignment YAML in share/sins_align_ros/config).
"""
import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.conditions import IfCondition
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node


def generate_launch_description():
    """Start the simulator (optional) and the alignment node with a parameter file."""
    share = get_package_share_directory('sins_align_ros')
    default_params = os.path.join(share, 'config', 'alignment_stationary.yaml')
    return LaunchDescription([
        DeclareLaunchArgument('scenario', default_value='static_navigation'),
        DeclareLaunchArgument('use_sim', default_value='true'),
        DeclareLaunchArgument('params', default_value=default_params),
        Node(package='sins_align_ros', executable='simulator_node', name='simulator_node',
             parameters=[{'scenario': LaunchConfiguration('scenario')}],
             condition=IfCondition(LaunchConfiguration('use_sim')), output='screen'),
        Node(package='sins_align_ros', executable='alignment_node', name='alignment_node',
             parameters=[LaunchConfiguration('params')], output='screen'),
    ])
