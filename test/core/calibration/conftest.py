"""Fixtures of the calibration tests: the UR5 of example-robot-data with its tolerance vector."""
from __future__ import annotations

import numpy as np
import pytest

from helpers import example_urdf
from tolerance_ros.core.models import URDFChain


@pytest.fixture(scope="session")
def ur5():
    return URDFChain(example_urdf("ur5_robot.urdf"), tip_link="tool0")


@pytest.fixture(scope="session")
def ur5_delta(ur5):
    """0.1 mm per origin length component and 0.5 mrad per origin angle and zero offset."""
    return np.array([1e-4 if k == "length" else 5e-4 for k in ur5.param_kinds])
