"""Verdicts of measurements against the predicted bound and the design limits."""
import pytest

from tolerance_ros.core.accuracy.verdicts import budget_check


def test_budget_check_verdicts():
    c = budget_check([0.5, 1.0, 2.0], [1.0, 0.8, 1.5], limit=1.5)
    assert list(c["verdict"]) == ["within", "over bound", "over limit"]
    assert c["margin"] == pytest.approx([0.5, -0.2, -0.5])
