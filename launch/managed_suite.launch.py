"""Starts the accuracy suite of one robot as managed (lifecycle) nodes, with config/accuracy_suite.yaml, and
drives them: each is configured at start (robots, kernels, files loaded), then activated once it is
inactive (serving). ``ros2 lifecycle set /tolerance_error_model deactivate`` stops one without losing its
state; ``activate`` resumes it.

    ros2 launch tolerance_ros managed_suite.launch.py [namespace:=arm_left] [autostart:=false] [keystore:=<dir>]
        [robot:=/path/my_robot.urdf] [tip_link:=tool0] [base_link:=...] [budget:=...] [campaign:=...]

``keystore:=<dir>`` runs every node in its own SROS2 enclave with security enforced, and this launch (which
drives their lifecycles) in ``/<namespace>/tolerance_launch`` (docs/security.md).
"""
import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, EmitEvent, OpaqueFunction, RegisterEventHandler
from launch.conditions import IfCondition
from launch.events import matches_action
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import LifecycleNode
from launch_ros.event_handlers import OnStateTransition
from launch_ros.events.lifecycle import ChangeState
from lifecycle_msgs.msg import Transition

from tolerance_ros.nodes.launch_robot import robot_arguments, robot_parameters
from tolerance_ros.nodes.launch_security import enclave_env, keystore_argument, security_actions

NODES = (("joint_state_source", "tolerance_joint_state_source"), ("error_model_server", "tolerance_error_model"),
         ("tolerance_allocator", "tolerance_allocator"), ("accuracy_monitor", "tolerance_accuracy_monitor"),
         ("simulated_tracker", "tolerance_simulated_tracker"), ("trajectory_compensator",
                                                                "tolerance_trajectory_compensator"))


def generate_launch_description():
    default_params = os.path.join(get_package_share_directory("tolerance_ros"), "config", "accuracy_suite.yaml")
    params, namespace = LaunchConfiguration("params_file"), LaunchConfiguration("namespace")
    autostart = IfCondition(LaunchConfiguration("autostart"))

    def nodes(context):
        robot = robot_parameters(context)
        actions = []
        for exe, name in NODES:
            node = LifecycleNode(package="tolerance_ros", executable=exe, name=name, namespace=namespace,
                                 parameters=[params] + ([robot[name]] if name in robot else []),
                                 arguments=["--managed"], output="screen", additional_env=enclave_env(namespace, name))
            actions += [
                node,
                EmitEvent(event=ChangeState(lifecycle_node_matcher=matches_action(node),
                                            transition_id=Transition.TRANSITION_CONFIGURE), condition=autostart),
                RegisterEventHandler(OnStateTransition(
                    target_lifecycle_node=node, start_state="configuring", goal_state="inactive",
                    entities=[EmitEvent(event=ChangeState(lifecycle_node_matcher=matches_action(node),
                                                          transition_id=Transition.TRANSITION_ACTIVATE))]),
                    condition=autostart)]
        return actions

    return LaunchDescription([
        DeclareLaunchArgument("namespace", default_value="", description="namespace of the whole suite (one robot)"),
        DeclareLaunchArgument("params_file", default_value=default_params, description="node parameters (YAML)"),
        DeclareLaunchArgument("autostart", default_value="true",
                              description="configure and activate every node at start (false: drive them by hand)"),
        *robot_arguments(), keystore_argument(), *security_actions(namespace), OpaqueFunction(function=nodes)])
