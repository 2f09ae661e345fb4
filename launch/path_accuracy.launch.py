"""Accuracy in motion on the graph: the joint-state source drives a joint trajectory (an ISO 9283 test path of
``tolerance-ros plan-campaign --path``), the simulated tracker streams the as-built robot's tool during the
motion at its own rate and latency, and the accuracy monitor publishes the path figures of each run
(``tolerance/path_report``, JSON in SI) and their status on /diagnostics:

    tolerance-ros plan-campaign --robot gao2023_7dof --path rectangle --cycles 3 --out rectangle.yaml
    ros2 launch tolerance_ros path_accuracy.launch.py trajectory:=$PWD/rectangle.yaml [rate:=250.0] \\
        [latency:=0.008] [namespace:=arm] [keystore:=<dir>] [robot:=/path/my_robot.urdf] [tip_link:=tool0]
    ros2 topic echo tolerance/path_report std_msgs/msg/String

``rate`` is the tracker's rate (Hz), ``latency`` how late it stamps its readings (s); the monitor estimates
that latency from the two streams.
"""
import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue

from tolerance_ros.nodes.launch_robot import robot_arguments, robot_parameters
from tolerance_ros.nodes.launch_security import enclave_env, keystore_argument, security_actions

TRACKER_TO_BASE = [1.5, 0.2, 0.0, 0.0, 0.0, 0.5]


def generate_launch_description():
    params = os.path.join(get_package_share_directory("tolerance_ros"), "config", "accuracy_suite.yaml")
    ns = LaunchConfiguration("namespace")
    rate = ParameterValue(LaunchConfiguration("rate"), value_type=float)
    latency = ParameterValue(LaunchConfiguration("latency"), value_type=float)

    def nodes(context):
        robot = robot_parameters(context)

        def node(exe, name, **overrides):
            return Node(package="tolerance_ros", executable=exe, name=name, namespace=ns, output="screen",
                        parameters=[params] + ([robot[name]] if name in robot else []) + [overrides],
                        additional_env=enclave_env(ns, name))
        return [
            node("joint_state_source", "tolerance_joint_state_source", mode="trajectory",
                 trajectory=LaunchConfiguration("trajectory"), campaign="", rate=250.0, loop=False),
            node("simulated_tracker", "tolerance_simulated_tracker", tracker_to_base=TRACKER_TO_BASE, measure_every=1,
                 rate=rate, latency=latency),
            node("accuracy_monitor", "tolerance_accuracy_monitor", tracker_to_base=TRACKER_TO_BASE, budget="",
                 campaign=""),
        ]

    return LaunchDescription([
        DeclareLaunchArgument("namespace", default_value="", description="namespace of the suite (one robot)"),
        DeclareLaunchArgument("trajectory", description="joint trajectory file (plan-campaign --path ... --out FILE)"),
        DeclareLaunchArgument("rate", default_value="250.0", description="the simulated tracker's rate, Hz"),
        DeclareLaunchArgument("latency", default_value="0.008",
                              description="how late the simulated tracker stamps its readings, s"),
        *robot_arguments(), keystore_argument(), *security_actions(ns), OpaqueFunction(function=nodes)])
