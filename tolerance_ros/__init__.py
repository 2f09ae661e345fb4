"""tolerance_ros: kinematic error models, precision analysis and tolerance allocation for robot arms.

The math lives in ``tolerance_ros.core`` (no ROS); ``tolerance_ros.nodes`` holds the ROS 2 adapters and
``tolerance_ros.cli`` the command line.
"""
__version__ = "0.1.0"
