"""Shared fixtures: the shipped paper arm and a planar 2R arm. The numerical libraries run on one thread,
as in the command line and the nodes (``tolerance_ros.core.threads``); the compiled kernels are loaded
(or compiled) before the first test, so that no test sees them being prepared in the background
(``test/core/models/test_warmup.py`` does, in child processes)."""
from __future__ import annotations

from tolerance_ros.core.threads import cap_environment

cap_environment()  # before numpy loads where it has not yet; threadpoolctl covers the rest below

import pytest  # noqa: E402
from threadpoolctl import threadpool_limits  # noqa: E402

from tolerance_ros.core.models import DHChain, load_robot, warmup  # noqa: E402

threadpool_limits(limits=1)
warmup.start(background=False)  # the kernels in force from the first test (nodes started here find them ready)


@pytest.fixture(scope="session")
def gao():
    return load_robot("gao2023_7dof")


@pytest.fixture(scope="session")
def planar2r():
    """Planar 2R arm, links 0.4 m and 0.3 m."""
    return DHChain("planar2r", a=[0.4, 0.3], alpha=[0, 0], d=[0, 0], theta=[0, 0])
