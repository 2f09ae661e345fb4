"""From measured errors to a calibrated model (ROS-free, SI): ``calibrate`` (fit and hold-out validation),
``calibration_file`` (the calibration file, and its checks when loaded), ``calibrated_robot`` (calibrated D-H
YAML and URDF), ``compensate`` (joints for the
calibrated robot, batched damped least squares), ``planning`` (observability indices, pose selection)."""
from .calibrate import Calibration, calibrate, calibrate_measurements, calibrated_mechanism
from .compensate import Compensation, compensate
from .calibrated_robot import write_calibrated_robot
from .calibration_file import load_calibrated_model, load_calibration, save_calibration
from .planning import Plan, plan

__all__ = ["Calibration", "Compensation", "Plan", "calibrate", "calibrate_measurements", "calibrated_mechanism",
           "compensate", "load_calibrated_model", "load_calibration", "plan", "save_calibration",
           "write_calibrated_robot"]
