"""The robot of a launch file from its arguments (``launch`` imports: the ROS side of
``services.launch_robot``): ``robot_arguments`` declares ``robot``, ``tip_link``, ``base_link``, ``budget`` and
``campaign``; ``robot_parameters`` reads them at launch time and returns each node's overrides, the robot
loaded first, so that a wrong path or link stops the launch with one message before any node starts."""
from __future__ import annotations

from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration

from ..services.launch_robot import LAUNCH_ARGUMENTS, robot_overrides


def robot_arguments(**defaults) -> list:
    """The launch arguments of ``services.launch_robot.LAUNCH_ARGUMENTS`` (default empty, or ``defaults``)."""
    return [DeclareLaunchArgument(name, default_value=str(defaults.get(name, "")), description=text)
            for name, text in LAUNCH_ARGUMENTS.items()]


def robot_parameters(context, suite_campaign: str = "") -> dict:
    """{node name: overrides} of the launch arguments' values (``robot_overrides`` with the robot checked;
    ``suite_campaign`` played on the parameters file's robot when no campaign is given)."""
    values = {name: LaunchConfiguration(name).perform(context) for name in LAUNCH_ARGUMENTS}
    return robot_overrides(**values, check=True, suite_campaign=suite_campaign)
