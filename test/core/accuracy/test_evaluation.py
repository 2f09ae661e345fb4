"""Evaluation of a measurement set with campaign labels."""
import numpy as np
import pytest

from tolerance_ros.core.accuracy.evaluation import evaluate_file
from tolerance_ros.core.accuracy.io import Measurements
from tolerance_ros.core.accuracy.simulate import as_built_errors, measure
from tolerance_ros.core.budget import Budget
from tolerance_ros.core.campaign import Campaign, TestPose
from tolerance_ros.core.geometry import transform

T_TB = transform([1.5, -0.3, 0.2], [0.05, -0.02, 1.2])


def test_evaluate_file_with_campaign_labels_only(gao):
    delta = np.r_[np.full(14, 1e-4), np.full(14, 5e-4)]
    qk = gao.sample_joints(4, 5)
    camp = Campaign("c", [TestPose(f"P{i + 1}", joints=qk[i]) for i in range(4)], cycles=10)
    q = np.tile(qk, (10, 1))
    T = measure(gao, q, as_built_errors(delta, 2), 1e-5, 0, T_TB, seed=4)
    labels = np.array([f"P{i % 4 + 1}" for i in range(40)], dtype=object)
    meas = Measurements(np.arange(40.0), T, None, (), labels, np.arange(40) // 4)
    budget = Budget.from_vector(gao, delta, limit_position=1.4e-3)
    res = evaluate_file(gao, meas, budget, camp)
    assert set(res["per_pose"]) == {"P1", "P2", "P3", "P4"} and res["per_pose"]["P1"]["n"] == 10
    assert res["summary"]["measurements"] == 40 and len(res["rows"]["error"]) == 40
    with pytest.raises(ValueError, match="carry no joints"):
        evaluate_file(gao, meas, budget, None)
