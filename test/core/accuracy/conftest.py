"""The shared simulated path run (``path_runs``)."""
import pytest

from path_runs import run


@pytest.fixture(scope="session")
def rect_run(gao):
    return gao, run(gao, "rectangle")
