"""The correction envelope (core/calibration/envelope.py): a calibration of a robot built within its budget
passes the default bounds, one with a 50 mrad joint error does not, and the reason names the joint and mm."""
import copy

import numpy as np
import pytest

from tolerance_ros.core.accuracy.simulate import as_built_errors, measure
from tolerance_ros.core.budget import load_budget
from tolerance_ros.core.calibration.calibrate import calibrate
from tolerance_ros.core.calibration.compensate import compensate
from tolerance_ros.core.models.ik import joint_jacobian
from tolerance_ros.core.calibration.envelope import (CONDITIONED, MAX_JOINT_CORRECTION, MAX_TOOL_CORRECTION,
                                                    CorrectionError, Envelope, correction, envelope_postures)


@pytest.fixture(scope="module")
def real(gao):
    """Calibrations of three robots built within gao2023_delta2, each fitted to 30 measured poses."""
    delta = load_budget("gao2023_delta2", gao).vector_for(gao)
    out = []
    for seed in (1, 2, 3):
        q = gao.sample_joints(30, 5 + seed)
        out.append(calibrate(gao, q, measure(gao, q, as_built_errors(delta, seed), 1e-5, 0.0, None, seed=2), folds=3))
    return out


def rogue(cal, gao, error=0.05):
    """The calibration with ``error`` rad more on joint 2's zero offset."""
    bad = copy.deepcopy(cal)
    bad.dx = cal.dx.copy()
    bad.dx[list(gao.param_names).index("theta2")] += error
    return bad


def test_calibrations_of_a_robot_built_within_its_budget_pass_the_default_envelope(gao, real):
    for cal in real:
        check = Envelope().check(cal, gao)
        assert check["ok"] and check["reason"] == "", check
        assert 0 < check["joint_rad"] < 0.2 * MAX_JOINT_CORRECTION and 0 < check["tool_m"] < 0.2 * MAX_TOOL_CORRECTION
        assert check["poses"] == 30 + 64                              # its 30 campaign postures and 64 samples
        Envelope().require(cal, gao)


def test_a_50_mrad_joint_error_is_refused_naming_the_joint_and_the_tool(gao, real):
    check = Envelope().check(rogue(real[0], gao), gao)
    assert not check["ok"]
    assert 0.049 < check["joint_rad"] < 0.052 and check["joint"] == "joint2" and check["tool_m"] > 0.03
    assert "changes joint2 by up to 5" in check["reason"] and "max_joint_correction 20 mrad" in check["reason"]
    assert "moves the tool point by up to" in check["reason"] and "(max_tool_correction 5 mm)" in check["reason"]
    with pytest.raises(CorrectionError, match="correction outside the envelope: .*joint2"):
        Envelope().require(rogue(real[0], gao), gao)
    assert Envelope(max_joint=0.06, max_tool=0.06).check(rogue(real[0], gao), gao)["ok"]   # wider bounds pass it


def test_the_joint_correction_is_the_compensations_largest_change_away_from_singularities(gao, real):
    cal = rogue(real[1], gao, 0.01)
    c = correction(cal, gao)
    q = envelope_postures(cal, gao)
    comp = compensate(cal.mechanism(gao), cal.nominal_at_tool_point(gao), joints=q)
    sv = np.linalg.svd(joint_jacobian(gao, q)[1], compute_uv=False)
    counted = comp.reached & ~comp.near_singularity & (sv[:, -1] >= CONDITIONED * sv[:, 0])
    assert counted.sum() > 0.3 * len(q) and c["unreached"] == len(q) - counted.sum()
    assert c["joint_max"] == pytest.approx(np.abs(comp.correction[counted]).max(axis=0))
    tool = np.linalg.norm(cal.mechanism(gao).fk(q)[:, :3, 3] - gao.fk(q)[:, :3, 3], axis=1)
    assert c["tool_m"] == pytest.approx(tool.max())


def test_the_postures_are_the_campaigns_within_limits_capped_and_the_samples(gao, real):
    cal = copy.deepcopy(real[0])
    many = gao.sample_joints(1000, 9)
    cal.training = {"postures": np.vstack([many, [[9.0] * 7], [[np.nan] * 7]]).tolist()}  # out of limits, not finite
    q = envelope_postures(cal, gao)
    assert q.shape == (200 + 64, 7) and np.all(np.isfinite(q)) and not gao.out_of_limits(q).any()
    cal.training = {"postures": "junk"}
    assert envelope_postures(cal, gao).shape == (64, 7)


def test_points_whose_joint_change_exceeds_the_bound_are_named(gao):
    change = np.zeros((3, 7))
    change[1, 2] = -0.03
    change[2, 6] = 0.019
    assert Envelope().point_changes(gao, change) == {
        1: "joint change 0.03 rad on joint3 exceeds max_joint_correction 0.02 rad"}


@pytest.mark.parametrize("kwargs", [{"max_joint": 0.0}, {"max_joint": 4.0}, {"max_tool": -1e-3}, {"max_tool": 2.0},
                                    {"max_joint": float("nan")}])
def test_bounds_outside_their_range_are_refused(kwargs):
    with pytest.raises(ValueError, match="max_(joint|tool)_correction: expected a value in"):
        Envelope(**kwargs)


def test_a_small_ur5_calibration_passes_though_near_singular_samples_would_need_large_joint_changes(ur5, ur5_delta):
    q = ur5.sample_joints(30, 5)
    cal = calibrate(ur5, q, measure(ur5, q, as_built_errors(ur5_delta, 1), 1e-5, 0.0, None, seed=2), folds=3)
    check = Envelope().check(cal, ur5)
    assert check["ok"] and check["tool_m"] < 1e-3 and check["joint_rad"] < 0.01, check
    near = envelope_postures(cal, ur5)
    comp = compensate(cal.mechanism(ur5), cal.nominal_at_tool_point(ur5), joints=near)
    assert np.abs(comp.correction).max() > 0.02   # where the arm is near a singularity: not counted
    assert not Envelope().check(rogue_ur5(cal, ur5), ur5)["ok"]


def rogue_ur5(cal, ur5):
    bad = copy.deepcopy(cal)
    bad.dx = cal.dx.copy()
    bad.dx[list(ur5.param_names).index("shoulder_lift_joint.offset")] += 0.05
    return bad
