"""Two arms in one graph: the accuracy suite twice, under /arm_left and /arm_right, with their own
parameters (config/two_arms.yaml: the same arm model, different budgets). Nothing crosses between the
namespaces; /diagnostics is shared, with the namespace in each status name.

    ros2 launch tolerance_ros two_arms.launch.py [keystore:=<dir>] [robot:=/path/arm.urdf] [tip_link:=tool0]

``robot:=``, ``tip_link:=``, ``base_link:=``, ``budget:=``, ``campaign:=`` go to both suites (two arms of one type).

``keystore:=<dir>``: a keystore made with ``tolerance-ros keystore --namespace /arm_left --namespace /arm_right``.
"""
import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import IncludeLaunchDescription
from launch.launch_description_sources import PythonLaunchDescriptionSource
from launch.substitutions import LaunchConfiguration

from tolerance_ros.nodes.launch_robot import robot_arguments
from tolerance_ros.nodes.launch_security import keystore_argument
from tolerance_ros.services.launch_robot import LAUNCH_ARGUMENTS


def generate_launch_description():
    share = get_package_share_directory("tolerance_ros")
    suite = os.path.join(share, "launch", "accuracy_suite.launch.py")
    params = os.path.join(share, "config", "two_arms.yaml")
    keystore = LaunchConfiguration("keystore")
    robot = {name: LaunchConfiguration(name) for name in LAUNCH_ARGUMENTS}
    return LaunchDescription([keystore_argument(), *robot_arguments()] + [
        IncludeLaunchDescription(PythonLaunchDescriptionSource(suite),  # one source per include
                                 launch_arguments={"namespace": ns, "params_file": params, "keystore": keystore,
                                                   **robot}.items())
        for ns in ("arm_left", "arm_right")])
