"""Fixtures of the calibration tests: the UR5 of example-robot-data with its tolerance vector, and a calibration of
the paper's arm as built within gao2023_delta2."""
from __future__ import annotations

import numpy as np
import pytest

from helpers import example_urdf
from tolerance_ros.core.accuracy.simulate import as_built_errors, measure
from tolerance_ros.core.budget import load_budget
from tolerance_ros.core.calibration.calibrate import calibrate
from tolerance_ros.core.geometry import transform
from tolerance_ros.core.models import URDFChain

T_TRACKER_BASE = transform([1.5, -0.3, 0.2], [0.05, -0.02, 1.2])


@pytest.fixture(scope="session")
def ur5():
    return URDFChain(example_urdf("ur5_robot.urdf"), tip_link="tool0")


@pytest.fixture(scope="session")
def ur5_delta(ur5):
    """0.1 mm per origin length component and 0.5 mrad per origin angle and zero offset."""
    return np.array([1e-4 if k == "length" else 5e-4 for k in ur5.param_kinds])


@pytest.fixture(scope="module")
def gao_calibration(gao):
    delta = load_budget("gao2023_delta2", gao).vector_for(gao)
    q = np.tile(gao.sample_joints(25, 1), (2, 1))
    T = measure(gao, q, as_built_errors(delta, 2), 1e-5, 1e-5, T_TRACKER_BASE, seed=3)
    return calibrate(gao, q, T, sigma_position=1e-5, sigma_orientation=1e-5, folds=3,
                     sources={"robot": gao.config_path, "measurements": "m.csv"})
