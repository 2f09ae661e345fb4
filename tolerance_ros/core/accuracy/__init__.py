"""Measured against nominal: ISO 9283 characteristics, registration, budget checks, identification."""
from .iso9283 import PoseCharacteristics, iso_cube_points, pose_characteristics, wrap

__all__ = ["PoseCharacteristics", "iso_cube_points", "pose_characteristics", "wrap"]
