"""Starts the accuracy suite of one robot: joint-state source, error-model server, tolerance allocator,
accuracy monitor and (optionally) the simulated tracker, with config/accuracy_suite.yaml. Every topic
is relative, so ``namespace:=arm_left`` puts the whole suite under /arm_left.

    ros2 launch tolerance_ros accuracy_suite.launch.py [namespace:=arm_left] [sim_tracker:=false]
        [joint_source:=false] [params_file:=my.yaml] [keystore:=<dir>]
        [robot:=/path/my_robot.urdf] [tip_link:=tool0] [base_link:=...] [budget:=...] [campaign:=...]

``robot:=`` (a shipped name, a robot YAML or a URDF path) and ``tip_link:=`` (the link the tracker's target is on)
give every node the robot (``services/launch_robot.py``: what belongs to the file's robot, its budget and
campaign, is not carried over to another).

``keystore:=<dir>`` (a keystore from ``tolerance-ros keystore --namespace <namespace>``) runs every node in its
own SROS2 enclave with security enforced (docs/security.md).
"""
import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.conditions import IfCondition
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

from tolerance_ros.nodes.launch_robot import robot_arguments, robot_parameters
from tolerance_ros.nodes.launch_security import enclave_env, keystore_argument, security_actions

NODES = (("joint_state_source", "tolerance_joint_state_source", "joint_source"),
         ("error_model_server", "tolerance_error_model", None),
         ("tolerance_allocator", "tolerance_allocator", None),
         ("accuracy_monitor", "tolerance_accuracy_monitor", None),
         ("simulated_tracker", "tolerance_simulated_tracker", "sim_tracker"))


def generate_launch_description():
    default_params = os.path.join(get_package_share_directory("tolerance_ros"), "config", "accuracy_suite.yaml")
    params, namespace = LaunchConfiguration("params_file"), LaunchConfiguration("namespace")

    def nodes(context):
        robot = robot_parameters(context)
        return [Node(package="tolerance_ros", executable=exe, name=name, namespace=namespace,
                     parameters=[params] + ([robot[name]] if name in robot else []),
                     output="screen", condition=IfCondition(LaunchConfiguration(switch)) if switch else None,
                     additional_env=enclave_env(namespace, name))
                for exe, name, switch in NODES]

    return LaunchDescription([
        DeclareLaunchArgument("namespace", default_value="", description="namespace of the whole suite (one robot)"),
        DeclareLaunchArgument("params_file", default_value=default_params, description="node parameters (YAML)"),
        DeclareLaunchArgument("sim_tracker", default_value="true", description="start the simulated tracker"),
        DeclareLaunchArgument("joint_source", default_value="true",
                              description="start the joint-state source (false when the robot publishes joint_states)"),
        *robot_arguments(), keystore_argument(), *security_actions(namespace), OpaqueFunction(function=nodes)])
