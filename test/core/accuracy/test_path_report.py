"""The path report on simulated streams with known truth: the latency back within 0.5 ms (its uncertainty
covering the error), AT_p and RT_p within 10 % of the figures of the true as-built path (registered as the
report registers), the points off the test path counted, the budget's tube, and a refusal when the latency
is too uncertain for the budget."""
import numpy as np
import pytest

from path_runs import run
from tolerance_ros.core.accuracy import path as P
from tolerance_ros.core.accuracy.path_report import _cycles, command_points, path_report
from tolerance_ros.core.accuracy.registration import kabsch
from tolerance_ros.core.budget import load_budget


def truth_figures(model, st):
    """The ISO figures of the true as-built path: measured at the true times, without noise, in the base frame
    registered onto the command as the report registers (Kabsch over every point)."""
    pc = command_points(model, st.joints)
    runs = P.motions(st.joint_stamps, pc)
    picked, _ = P.cycles_of(pc, runs)
    at = np.column_stack([np.interp(st.true_times, st.joint_stamps, pc[:, k]) for k in range(3)])
    R, t, _ = kabsch(st.true_points, at)
    cycles = _cycles(st.joint_stamps, pc, st.true_times, st.true_points @ R.T + t, runs, picked)
    return P.path_characteristics(cycles, P.segment_bounds(cycles[0].s[-1], P.corners(cycles[0].p)))


def test_rectangle_latency_at_rt_against_the_truth(rect_run):
    model, st = rect_run
    doc = path_report(model, st.stamps, st.points, st.joint_stamps, st.joints)
    assert abs(doc["latency_s"] - 0.008) < 0.5e-3
    assert abs(doc["latency_s"] - 0.008) < 2 * doc["latency_std_s"]
    assert doc["cycles"] == 10 and len(doc["segments"]) == 4
    truth = truth_figures(model, st)
    floor = 4 * st.noise / np.sqrt(doc["cycles"])   # what the tracker's noise leaves in a barycentre
    assert sum(tr["AT_p_m"] > 5 * floor for tr in truth) >= 2
    for seg, tr in zip(doc["segments"], truth):
        assert abs(seg["AT_p_m"] - tr["AT_p_m"]) <= max(0.1 * tr["AT_p_m"], floor), seg["name"]
        assert seg["RT_p_m"] == pytest.approx(tr["RT_p_m"], rel=0.1), seg["name"]
    assert doc["overall"]["AT_p_m"] == max(s["AT_p_m"] for s in doc["segments"])
    assert [s["CR_m"] is None for s in doc["segments"]] == [True, False, False, False]
    out = doc["outside"]
    assert out["points"] == out["at_rest"] + out["other_motions"] + out["outside_joint_states"] > 0
    assert doc["registration"]["residual_rms_m"] < 1e-3


def test_line_return_is_another_motion_and_its_points_are_counted(gao):
    st = run(gao, "line", cycles=3, repeatability=0.0)
    doc = path_report(gao, st.stamps, st.points, st.joint_stamps, st.joints)
    assert doc["cycles"] == 3 and doc["other_motions"] == 3 and len(doc["segments"]) == 1
    assert doc["outside"]["other_motions"] > 0.4 * len(st.stamps)
    assert abs(doc["latency_s"] - 0.008) < 0.5e-3


def test_budget_tube_verdict_and_refusal_of_an_uncertain_latency(rect_run):
    model, st = rect_run
    budget = load_budget("gao2023_delta2", model)
    doc = path_report(model, st.stamps, st.points, st.joint_stamps, st.joints, budget=budget)
    b = doc["budget"]
    assert b["bound_max_m"] > doc["overall"]["AT_p_m"] and doc["refused"] is None
    assert len(doc["segments"][0]["along"]["bound_m"]) == doc["stations_per_segment"]
    budget.limit_position = 1e-5      # 10 um: the latency's uncertainty alone moves the path more than 1 um
    doc = path_report(model, st.stamps, st.points, st.joint_stamps, st.joints, budget=budget)
    assert doc["refused"] and "too uncertain" in doc["refused"] and doc["missed"] == [doc["refused"]]


def test_a_given_latency_is_used_as_given(rect_run):
    model, st = rect_run
    doc = path_report(model, st.stamps, st.points, st.joint_stamps, st.joints, latency=0.0)
    good = path_report(model, st.stamps, st.points, st.joint_stamps, st.joints, latency=0.008)
    assert doc["latency_s"] == 0.0 and doc["latency"]["given"]
    assert doc["registration"]["residual_rms_m"] > 3 * good["registration"]["residual_rms_m"]


def test_joint_states_at_rest_are_refused(gao):
    q = np.zeros((100, gao.dof))
    t = np.arange(100) * 0.002
    with pytest.raises(ValueError, match="never moves"):
        path_report(gao, t, np.zeros((100, 3)), t, q)


def test_the_target_jacobian_is_the_offset_points_finite_difference(gao):
    """The bound tube at a target off the tool frame: the position rows of the error Jacobian at that point
    equal central differences of its position over each parameter."""
    from tolerance_ros.core.accuracy.targets import at_point
    q = gao.sample_joints(4, 3)
    offset = np.array([0.03, -0.02, 0.12])
    J = at_point(gao, offset).error_jacobian(q).position
    h = 1e-7
    cols = []
    for j in range(J.shape[2]):
        dx = np.zeros(J.shape[2])
        dx[j] = h
        Tp, Tm = gao.fk(q, dx), gao.fk(q, -dx)
        cols.append(((Tp[:, :3, :3] @ offset + Tp[:, :3, 3]) - (Tm[:, :3, :3] @ offset + Tm[:, :3, 3])) / (2 * h))
    assert np.allclose(J, np.stack(cols, axis=2), atol=1e-7)
    assert not np.allclose(J, gao.error_jacobian(q).position, atol=1e-4)
