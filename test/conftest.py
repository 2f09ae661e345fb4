"""Shared fixtures: the shipped paper arm and a planar 2R arm."""
from __future__ import annotations

import pytest

from tolerance_ros.core.models import DHChain, load_robot


@pytest.fixture(scope="session")
def gao():
    return load_robot("gao2023_7dof")


@pytest.fixture(scope="session")
def planar2r():
    """Planar 2R arm, links 0.4 m and 0.3 m."""
    return DHChain("planar2r", a=[0.4, 0.3], alpha=[0, 0], d=[0, 0], theta=[0, 0])
