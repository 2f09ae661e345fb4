"""The whole accuracy loop on the graph, with a simulated as-built robot: the joint-state source plays a
campaign through the trajectory compensator (a stand-in for a controller executing compensated motion),
the simulated tracker measures the robot, the accuracy monitor logs and reports, the error model serves.
Calibrate from the monitor's log, and the compensator, the monitor and the error model switch to the
calibration; the monitor's report then carries the errors before beside the errors after:

    ros2 launch tolerance_ros accuracy_loop.launch.py [campaign:=gao2023_iso_cube] [namespace:=arm] [keystore:=<dir>]
        [robot:=/path/my_robot.urdf] [tip_link:=tool0] [base_link:=...] [budget:=...]
    ros2 topic pub --once tolerance/calibrate/request std_msgs/msg/String \\
        "{data: '{\\"id\\": \\"k1\\", \\"log\\": \\"current\\", \\"registration\\": \\"base\\"}'}"
    ros2 topic echo tolerance/accuracy_report std_msgs/msg/String

``keystore:=<dir>`` runs every node in its own SROS2 enclave with security enforced (docs/security.md); the
calibrate request then comes from the operator's enclave (``ROS_SECURITY_ENCLAVE_OVERRIDE=/<ns>/tolerance_operator``).
"""
import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

from tolerance_ros.nodes.launch_robot import robot_arguments, robot_parameters
from tolerance_ros.nodes.launch_security import enclave_env, keystore_argument, security_actions

TRACKER_TO_BASE = [1.5, 0.2, 0.0, 0.0, 0.0, 0.5]
CAMPAIGN = "gao2023_calibration_30"   # played on the parameters file's robot when no campaign:= is given


def generate_launch_description():
    params = os.path.join(get_package_share_directory("tolerance_ros"), "config", "accuracy_suite.yaml")
    ns = LaunchConfiguration("namespace")

    def nodes(context):
        robot = robot_parameters(context, suite_campaign=CAMPAIGN)

        def node(exe, name, **overrides):
            return Node(package="tolerance_ros", executable=exe, name=name, namespace=ns, output="screen",
                        parameters=[params] + ([robot[name]] if name in robot else []) + [overrides],
                        additional_env=enclave_env(ns, name))
        return [
            node("joint_state_source", "tolerance_joint_state_source", dwell=0.25, loop=True, compensated=True),
            node("trajectory_compensator", "tolerance_trajectory_compensator"),
            node("simulated_tracker", "tolerance_simulated_tracker", tracker_to_base=TRACKER_TO_BASE, measure_every=3),
            node("accuracy_monitor", "tolerance_accuracy_monitor", tracker_to_base=TRACKER_TO_BASE, budget="",
                 campaign=""),
            node("error_model_server", "tolerance_error_model"),
        ]

    return LaunchDescription([
        DeclareLaunchArgument("namespace", default_value="", description="namespace of the loop (one robot)"),
        *robot_arguments(), keystore_argument(), *security_actions(ns), OpaqueFunction(function=nodes)])
