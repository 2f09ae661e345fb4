"""Synthetic campaigns with known truth: a perturbed robot, a known base transform, known noise."""
import numpy as np
import pytest

from tolerance_ros.core.accuracy.evaluate import budget_check, identify, pose_errors
from tolerance_ros.core.accuracy.io import Measurements
from tolerance_ros.core.accuracy.registration import register
from tolerance_ros.core.accuracy.report import evaluate_file
from tolerance_ros.core.accuracy.simulate import as_built_errors, measure
from tolerance_ros.core.accuracy.stream import AccuracyAccumulator
from tolerance_ros.core.budget import Budget
from tolerance_ros.core.campaign import Campaign, TestPose
from tolerance_ros.core.geometry import transform

T_TB = transform([1.5, -0.3, 0.2], [0.05, -0.02, 1.2])


@pytest.fixture(scope="module")
def truth(gao):
    delta = np.r_[np.full(14, 1e-4), np.full(14, 5e-4)]
    dx = as_built_errors(delta, 7)
    q = gao.sample_joints(300, 8)
    T = measure(gao, q, dx, 1e-5, 1e-5, T_TB, seed=9)
    return delta, dx, q, T


def test_identification_recovers_the_injected_errors(gao, truth):
    delta, dx, q, T = truth
    reg = register(gao.fk(q), T)
    ident = identify(gao, q, reg.to_base(T), delta, 1e-5, 1e-5)
    names = list(gao.param_names)
    # The first joint's d and theta move the tool like a base shift/turn: they cannot be separated.
    assert {"d1", "theta1"} <= set(ident.unidentifiable)
    ok = np.array([n not in ident.unidentifiable for n in names])
    err = np.abs(ident.dx - dx)[ok]
    assert np.all(err < 6 * ident.std[ok] + 1e-7)
    assert ident.residual_rms_after < 2e-5 < ident.residual_rms_before


def test_out_of_tolerance_parts_are_named(gao, truth):
    delta, dx, q, T = truth
    tight = delta.copy()
    j = gao.param_index(["theta3"])[0]
    tight[j] = abs(dx[j]) / 3
    reg = register(gao.fk(q), T)
    ident = identify(gao, q, reg.to_base(T), tight, 1e-5, 1e-5)
    assert ident.out_of_tolerance[0]["name"] == "theta3"
    assert ident.out_of_tolerance[0]["ratio"] == pytest.approx(3.0, rel=0.05)


def test_registration_recovers_the_base_transform_up_to_the_robot_errors(gao, truth):
    delta, dx, q, T = truth
    exact = register(gao.fk(q, dx), T)  # with the as-built model the transform is found to noise level
    assert np.allclose(exact.T_tracker_base, T_TB, atol=1e-5)


def test_budget_check_verdicts():
    c = budget_check([0.5, 1.0, 2.0], [1.0, 0.8, 1.5], limit=1.5)
    assert list(c["verdict"]) == ["within", "over bound", "over limit"]
    assert c["margin"] == pytest.approx([0.5, -0.2, -0.5])


def test_streaming_equals_batch_and_iso_per_pose(gao):
    delta = np.r_[np.full(14, 1e-4), np.full(14, 5e-4)]
    dx = as_built_errors(delta, 1)
    qk = gao.sample_joints(5, 2)
    q = np.tile(qk, (30, 1))
    T = measure(gao, q, dx, 1e-5, 1e-5, None, seed=3)
    acc = AccuracyAccumulator(gao, delta, limit=1.4e-3, campaign_joints=qk, campaign_names=[f"P{i}" for i in range(5)])
    for a in range(0, 150, 7):
        acc.add(T[a:a + 7], q[a:a + 7])
    s = acc.summary()
    dp, _ = pose_errors(gao.fk(q), T)
    e = np.linalg.norm(dp, axis=1)
    assert s["position_error_m"]["mean"] == pytest.approx(e.mean()) and s["position_error_m"]["max"] == pytest.approx(e.max())
    assert s["position_error_m"]["std"] == pytest.approx(e.std())
    P0 = T[::5]
    ap = np.linalg.norm(P0[:, :3, 3].mean(axis=0) - gao.fk(qk[:1])[0, :3, 3])
    assert s["test_poses"]["P0"]["n"] == 30 and s["test_poses"]["P0"]["AP_p"] == pytest.approx(ap)
    assert sum(s["verdicts"].values()) == 150


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
