"""Targets on the tool: Jacobians moved to the target point (against finite differences), and reports of
measured points taken at the tool point, with no orientation figure anywhere."""
import json

import numpy as np
import pytest

from tolerance_ros.core.accuracy.evaluation import evaluate_file
from tolerance_ros.core.accuracy.simulate import as_built_errors, measure_targets
from tolerance_ros.core.targets import Targets, shift_jacobian
from tolerance_ros.core.geometry import transform
from tolerance_ros.core.jsonio import dumps

A = transform([2.1, -1.4, 0.6], [2.9, 0.4, -2.2])          # a tracker placed far off, turned, tilted
REFLECTORS = Targets.from_offsets(["A", "B", "C"], [[0.2, 0.0, 0.05], [0.0, 0.2, 0.05], [-0.14, -0.14, 0.05]])


def test_a_jacobian_at_a_target_point_matches_finite_differences(gao):
    q = gao.sample_joints(4, 3)
    tg = Targets.from_offsets(["A", "B"], [[0.3, -0.1, 0.2], [-0.5, 0.4, 0.9]])
    idx = np.array([0, 1, 0, 1])
    T, EJ = gao.fk_and_jacobian(q)
    J = shift_jacobian(EJ.J, tg.arms(T, idx))
    h = 1e-7
    for j in (0, 9, 20, 27):
        dx = np.zeros(gao.n_params)
        dx[j] = h
        up = tg.poses(gao.fk(q, dx), idx)[:, :3, 3]
        down = tg.poses(gao.fk(q, -dx), idx)[:, :3, 3]
        assert np.allclose((up - down) / (2 * h), J[:, :3, j], atol=1e-6)
    assert np.array_equal(J[:, 3:], EJ.J[:, 3:])


@pytest.fixture(scope="module")
def reflector_campaign(gao):
    """Three reflectors 0.2 m out from the flange, positions only, 10 um noise, an as-built robot."""
    delta = np.r_[np.full(14, 5e-5), np.full(14, 2e-4)]
    dx = as_built_errors(delta, 3)
    q = gao.sample_joints(24, 4)
    q = np.repeat(q, 3, axis=0)  # three repeats of each configuration
    return measure_targets(gao, q, dx, REFLECTORS, 1e-5, 0.0, A, seed=5, labels=[f"P{i // 3}" for i in range(72)])


def test_errors_of_reflectors_are_taken_at_each_reflector(gao, reflector_campaign):
    res = evaluate_file(gao, reflector_campaign, registration="base+tool")
    reg = res["registration"]
    assert reg["targets_estimated"] and [t["name"] for t in reg["targets"]] == ["A", "B", "C"]
    fitted = np.array([t["xyz_m"] for t in reg["targets"]])
    assert np.abs(fitted - REFLECTORS.offsets).max() < 2e-3   # the as-built robot's errors shift them a little
    pe = res["summary"]["position_error_m"]
    assert pe["max"] < 3e-3 and pe["mean"] < 1.5e-3            # the robot's own errors, not 200 mm of offset
    assert reg["residual_max_m"] == pytest.approx(pe["max"], rel=1e-9)  # errors are the residuals at the targets


def test_points_report_no_orientation_figure(gao, reflector_campaign):
    res = evaluate_file(gao, reflector_campaign, registration="base+tool")
    assert res["orientation_measured"] is False
    assert res["summary"]["orientation_error_rad"] is None
    assert res["rows"]["dphi"] is None and res["rows"]["orientation_error"] is None
    assert not any(k.startswith("orientation") for k in res["summary"]["exceeded"])
    text = dumps({k: v for k, v in res.items() if k != "rows"})
    assert "orientation_error" not in json.loads(text)["summary"] or \
        json.loads(text)["summary"]["orientation_error_rad"] is None


def test_one_reflector_with_its_offset_fitted_reports_the_robots_error_not_the_offset(gao):
    """The issue's 165 kg arm: one reflector 202 mm out, `--registration base+tool`, positions only."""
    tg = Targets.from_offsets([""], [[0.0, 0.05, 0.196]])
    delta = np.r_[np.full(14, 5e-5), np.full(14, 2e-4)]
    q = gao.sample_joints(30, 8)
    m = measure_targets(gao, q, as_built_errors(delta, 9), tg, 1e-5, 0.0, A, seed=1)
    res = evaluate_file(gao, m, registration="base+tool")
    assert np.allclose(res["registration"]["tool_offset_m"], tg.offsets[0], atol=2e-3)
    assert res["summary"]["position_error_m"]["mean"] < 1.5e-3


def test_several_targets_need_their_offsets_fitted(gao, reflector_campaign):
    with pytest.raises(ValueError, match="3 targets .* sit at different points of the tool; fit their offsets"):
        evaluate_file(gao, reflector_campaign, registration="base")


def test_tracker_frame_data_claimed_as_base_frame_is_called_out(gao):
    q = gao.sample_joints(20, 2)
    m = measure_targets(gao, q, None, None, 1e-5, 0.0, A, seed=3)
    res = evaluate_file(gao, m, registration="none")
    assert res["summary"]["position_error_m"]["mean"] > 0.5
    assert res["warnings"] and "not in the robot's base frame" in res["warnings"][0]
    assert not evaluate_file(gao, m, registration="base")["warnings"]
