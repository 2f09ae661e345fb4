"""tolerance_ros: kinematic error models, precision analysis and tolerance allocation for robot arms.

Layers, each importing only from those below it:
- ``tolerance_ros.core``: the math, ROS-free (SI units): geometry, mechanism models and their error
  Jacobians, error bounds, analysis, synthesis, accuracy evaluation, calibration (identification,
  calibrated models, compensation, pose planning), budgets, campaigns, ingestion;
- ``tolerance_ros.services``: what the ROS nodes run, ROS-free (JSON contracts, service logic, robots
  from robot_description, monitor and its RViz markers, compensation);
- ``tolerance_ros.render``: text tables, plots, the written accuracy and calibration reports, for people;
- ``tolerance_ros.papers``: the reproductions of the two source papers;
- ``tolerance_ros.cli``: the command line; ``tolerance_ros.nodes``: the ROS 2 adapters (the only rclpy
  imports).
"""
__version__ = "0.1.0"
