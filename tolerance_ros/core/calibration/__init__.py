"""From measured errors to a calibrated model (ROS-free, SI): ``calibrate`` (fit and hold-out validation),
``writers`` (the calibration file, calibrated D-H YAML and URDF), ``compensate`` (joints for the
calibrated robot, batched damped least squares), ``planning`` (observability indices, pose selection)."""
from .calibrate import Calibration, calibrate, calibrate_measurements, calibrated_mechanism
from .compensate import Compensation, compensate
from .planning import Plan, plan
from .writers import load_calibrated_model, load_calibration, save_calibration, write_calibrated_robot

__all__ = ["Calibration", "Compensation", "Plan", "calibrate", "calibrate_measurements", "calibrated_mechanism",
           "compensate", "load_calibrated_model", "load_calibration", "plan", "save_calibration",
           "write_calibrated_robot"]
