"""Starts the accuracy suite: joint-state source, error-model server, tolerance allocator, accuracy
monitor and (optionally) the simulated tracker, with config/accuracy_suite.yaml.

    ros2 launch tolerance_ros accuracy_suite.launch.py [sim_tracker:=false] [params_file:=my.yaml]
"""
import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.conditions import IfCondition
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node


def generate_launch_description():
    default_params = os.path.join(get_package_share_directory("tolerance_ros"), "config", "accuracy_suite.yaml")
    params = LaunchConfiguration("params_file")
    nodes = [Node(package="tolerance_ros", executable=exe, name=name, parameters=[params], output="screen")
             for exe, name in (("joint_state_source", "tolerance_joint_state_source"),
                               ("error_model_server", "tolerance_error_model"),
                               ("tolerance_allocator", "tolerance_allocator"),
                               ("accuracy_monitor", "tolerance_accuracy_monitor"))]
    tracker = Node(package="tolerance_ros", executable="simulated_tracker", name="tolerance_simulated_tracker",
                   parameters=[params], output="screen", condition=IfCondition(LaunchConfiguration("sim_tracker")))
    return LaunchDescription([
        DeclareLaunchArgument("params_file", default_value=default_params, description="node parameters (YAML)"),
        DeclareLaunchArgument("sim_tracker", default_value="true", description="start the simulated tracker"),
        *nodes, tracker])
