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


def test_streaming_a_large_file_gives_the_numbers_of_the_whole_file(gao, tmp_path):
    """stream_file (two constant-memory passes, small chunks) against evaluate_file on the same CSV."""
    from tolerance_ros.core.accuracy.evaluation import stream_file
    from tolerance_ros.core.accuracy.io import read_csv, write_csv
    delta = np.r_[np.full(14, 1e-4), np.full(14, 5e-4)]
    q = gao.sample_joints(500, 6)
    T = measure(gao, q, as_built_errors(delta, 3), 1e-5, 1e-5, T_TB, seed=5)
    path = write_csv(tmp_path / "m.csv", Measurements(np.arange(500.0), T, q, gao.joint_names,
                                                      np.array([""] * 500, dtype=object), np.full(500, -1)))
    budget = Budget.from_vector(gao, delta, limit_position=1.4e-3)
    whole = evaluate_file(gao, read_csv(path), budget, registration="base")
    streamed = stream_file(gao, path, budget, chunk_rows=64, registration="base")
    assert streamed["measurements"] == 500 and streamed["summary"]["verdicts"] == whole["summary"]["verdicts"]
    for k in ("mean", "std", "max"):
        assert streamed["summary"]["position_error_m"][k] == pytest.approx(whole["summary"]["position_error_m"][k],
                                                                          rel=1e-6)
    np.testing.assert_allclose(streamed["T_tracker_base"], whole["registration"]["T_tracker_base"], atol=1e-9)
    assert streamed["summary"]["identification"]["method"] == "linearised"
