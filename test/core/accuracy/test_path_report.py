"""The path report on simulated streams with known truth: the latency back within 0.5 ms (its uncertainty
covering the error), AT_p and RT_p within 10 % of the figures of the true as-built path (registered as the
report registers), the points off the test path counted, the budget's tube, and a refusal when the latency
is too uncertain for the budget."""
import numpy as np
import pytest

from path_runs import run
from tolerance_ros.core.accuracy import path as P
from tolerance_ros.core.accuracy.path_report import PathOptions, _cycles, command_points, path_report
from tolerance_ros.core.accuracy.registration import kabsch
from tolerance_ros.core.accuracy.repeats import split_runs
from tolerance_ros.core.budget import load_budget
from tolerance_ros.render.path_report import summary_lines


def truth_figures(model, st, noisy=False):
    """The ISO figures of the true as-built path: measured at the true times, without noise (or with the tracker's,
    ``noisy``), in the base frame registered onto the command as the report registers (Kabsch over every point)."""
    pc = command_points(model, st.joints)
    runs, _ = split_runs(st.joint_stamps, pc, P.motions(st.joint_stamps, pc), 0.002)
    picked, _ = P.cycles_of(pc, runs)
    at = np.column_stack([np.interp(st.true_times, st.joint_stamps, pc[:, k]) for k in range(3)])
    A = st.T_tracker_base
    pts = (st.points - A[:3, 3]) @ A[:3, :3] if noisy else st.true_points
    R, t, _ = kabsch(pts, at)
    cycles = _cycles(st.joint_stamps, pc, st.true_times, pts @ R.T + t, runs, picked)
    return P.path_characteristics(cycles, P.segment_bounds(cycles[0].s[-1], P.corners(cycles[0].p)))


def assert_true_figures(model, st, doc, latency=0.008):
    """The latency within 0.5 ms (its uncertainty covering the error), AT_p within 10 % of the truth (or of the
    noise left in a barycentre); RT_p, which includes the tracker's noise, within 10 % of the truth seen through
    that noise (measured at the true times)."""
    assert abs(doc["latency_s"] - latency) < 0.5e-3
    assert abs(doc["latency_s"] - latency) < 2 * doc["latency_std_s"]
    truth, seen = truth_figures(model, st), truth_figures(model, st, noisy=True)
    assert len(truth) == len(doc["segments"])
    floor = 4 * st.noise / np.sqrt(doc["cycles"])   # what the tracker's noise leaves in a barycentre
    for seg, tr, tn in zip(doc["segments"], truth, seen):
        assert abs(seg["AT_p_m"] - tr["AT_p_m"]) <= max(0.1 * tr["AT_p_m"], floor), seg["name"]
        assert seg["RT_p_m"] == pytest.approx(tn["RT_p_m"], rel=0.1), seg["name"]
    return truth


def test_rectangle_latency_at_rt_against_the_truth(rect_run):
    model, st = rect_run
    doc = path_report(model, st.stamps, st.points, st.joint_stamps, st.joints)
    assert doc["cycles"] == 10 and len(doc["segments"]) == 4 and doc["cycles_from"]["method"] == "rests"
    truth = assert_true_figures(model, st, doc)
    floor = 4 * st.noise / np.sqrt(doc["cycles"])
    assert sum(tr["AT_p_m"] > 5 * floor for tr in truth) >= 2
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
    budget.limit_position = 1e-6      # 1 um: the latency's uncertainty moves the path by more than a share of it,
    doc = path_report(model, st.stamps, st.points, st.joint_stamps, st.joints, budget=budget)
    ends = doc["budget"]["AT_p_at_latency_interval_m"]     # but the path misses it wherever the latency lies
    assert doc["refused"] is None and min(ends) > 1e-6 and "exceeds the design limit" in doc["missed"][0]


@pytest.mark.parametrize("ends, refused", [((0.9, 1.1), True), ((0.5, 0.8), False), ((1.2, 1.5), False)])
def test_an_uncertain_latency_refuses_only_a_verdict_it_could_change(rect_run, ends, refused):
    """The latency's interval (+-2 uncertainties) moves AT_p between ``ends`` (times the limit): the verdict is
    refused only where the limit lies between them."""
    from tolerance_ros.core.accuracy.path_report import _judge
    model, st = rect_run
    doc = path_report(model, st.stamps, st.points, st.joint_stamps, st.joints)
    limit = doc["overall"]["AT_p_m"] / (0.95 if refused else np.mean(ends))
    budget = load_budget("gao2023_delta2", model)
    budget.limit_position = limit
    doc["latency_std_s"] = 1.0           # whatever the speed: a shift over a share of the limit
    at = {doc["latency_s"] - 2.0: ends[0] * limit, doc["latency_s"] + 2.0: ends[1] * limit}
    _judge(doc, model, budget, _ref(model, st, doc), st.joint_stamps, st.joints, 0.1, None, lambda tau: at[tau])
    assert (doc["refused"] is not None) == refused
    if refused:
        assert "too uncertain" in doc["refused"] and doc["missed"] == [doc["refused"]]


def _ref(model, st, doc):
    """The first cycle's arc lengths and times, as path_report keeps them for the bound tube."""
    from types import SimpleNamespace
    s = np.asarray(doc["segments"][0]["along"]["s_m"])
    return SimpleNamespace(s=np.r_[0.0, s[-1] * 10], t=np.r_[st.joint_stamps[0], st.joint_stamps[-1]])


def test_a_given_latency_is_used_as_given(rect_run):
    model, st = rect_run
    doc = path_report(model, st.stamps, st.points, st.joint_stamps, st.joints, options=PathOptions(latency=0.0))
    good = path_report(model, st.stamps, st.points, st.joint_stamps, st.joints, options=PathOptions(latency=0.008))
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
    from tolerance_ros.core.targets import at_point
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


@pytest.mark.parametrize("kind", ["line", "rectangle", "circle"])
def test_a_program_that_loops_without_a_stop_gives_its_cycles_and_their_true_figures(gao, kind):
    """10 cycles driven without a rest between them: found from the command's repetition (the line's return strokes
    are other motions), AT_p and RT_p as the truth's."""
    st = run(gao, kind, dwell=0.0)
    doc = path_report(gao, st.stamps, st.points, st.joint_stamps, st.joints)
    assert doc["cycles"] == 10 and doc["other_motions"] == (10 if kind == "line" else 0)
    assert doc["cycles_from"]["method"] == "repetition"
    assert_true_figures(gao, st, doc)


@pytest.mark.parametrize("latency", [-0.3, -0.008, 0.0, 0.008, 0.118, 0.3, 1.0])
def test_a_latency_of_any_size_is_found_without_a_window(gao, latency):
    st = run(gao, "rectangle", latency=latency)
    doc = path_report(gao, st.stamps, st.points, st.joint_stamps, st.joints)
    assert doc["latency"]["coarse"] and abs(doc["latency"]["center_s"] - latency) <= 0.02
    assert_true_figures(gao, st, doc, latency)


def test_a_loop_without_a_stop_118_ms_late_is_aligned_on_its_own_cycle(gao):
    st = run(gao, "line", dwell=0.0, latency=0.118)
    doc = path_report(gao, st.stamps, st.points, st.joint_stamps, st.joints)
    assert doc["cycles"] == 10 and abs(doc["latency_s"] - 0.118) < 0.5e-3


def test_an_estimate_at_the_edge_of_a_given_window_is_refused_naming_it(gao):
    st = run(gao, "rectangle", latency=0.118, cycles=3)
    with pytest.raises(ValueError, match=r"edge of the search window -100\.0 ms to \+100\.0 ms"):
        path_report(gao, st.stamps, st.points, st.joint_stamps, st.joints, options=PathOptions(window=0.1))


def _rows(t, *arrays, order):
    return (t[order],) + tuple(a[order] for a in arrays)


def test_repeated_stamps_and_rows_out_of_order_give_the_clean_figures_and_are_counted(rect_run):
    """Every joint state logged twice with one stamp, every tenth tracker row too, and rows swapped in both:
    the figures of the clean stream, exactly; the report says what it did."""
    model, st = rect_run
    clean = path_report(model, st.stamps, st.points, st.joint_stamps, st.joints)
    j = np.repeat(np.arange(len(st.joint_stamps)), 2)
    j[1000:1010] = j[1000:1010][::-1]
    m = np.sort(np.concatenate([np.arange(len(st.stamps)), np.arange(0, len(st.stamps), 10)]))
    m[5000], m[5003] = m[5003], m[5000]
    doc = path_report(model, *_rows(st.stamps, st.points, order=m), *_rows(st.joint_stamps, st.joints, order=j))
    for a, b in zip(doc["segments"], clean["segments"]):
        for key in ("AT_p_m", "RT_p_m", "CR_m", "CO_m", "AV", "RV", "FV_m_s"):
            assert a[key] == b[key] or a[key] == pytest.approx(b[key], rel=1e-9, abs=1e-15), (a["name"], key)
    js, ms = doc["streams"]["joint_states"], doc["streams"]["points"]
    assert js["repeated"] == len(st.joint_stamps) and js["reordered"] > 0 and js["conflicting"] == 0
    assert ms["repeated"] == len(np.arange(0, len(st.stamps), 10)) and ms["reordered"] > 0
    out = doc["outside"]
    assert out["left_out"] == ms["repeated"] and doc["points"] == len(m)
    assert out["points"] - out["left_out"] == clean["outside"]["points"]
    assert "row(s) repeated a stamp" in " ".join(summary_lines(doc))


def test_a_clock_jump_in_the_joint_states_is_cut_there_said_and_bounded_in_memory(gao):
    """The joint states' clock jumps by 1e7 s half way (a reset): the cycles before it are judged, those after it
    are not (no tracker point on their clock), memory stays bounded by the rows."""
    import tracemalloc
    st = run(gao, "rectangle", cycles=6)
    tj = st.joint_stamps.copy()
    half = len(tj) // 2
    tj[half:] += 1e7
    tracemalloc.start()
    doc = path_report(gao, st.stamps, st.points, tj, st.joints)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak < 400e6
    assert doc["streams"]["joint_states"]["jumps"][0]["row"] == half
    assert 2 <= doc["cycles"] <= 3 and abs(doc["latency_s"] - 0.008) < 0.5e-3
    assert doc["not_judged"] and all("tracker point(s) along it" in w for w in doc["not_judged"])
    assert doc["outside"]["outside_joint_states"] > 0.3 * len(st.stamps)


def test_both_clocks_starting_again_judge_every_cycle(gao):
    st = run(gao, "rectangle", cycles=6)
    tj, tm = st.joint_stamps.copy(), st.stamps.copy()
    cut = tj[len(tj) // 2]
    tj[tj >= cut] -= 900.0
    tm[tm >= cut] -= 900.0
    doc = path_report(gao, tm, st.points, tj, st.joints)
    assert doc["streams"]["joint_states"]["epochs"] == doc["streams"]["points"]["epochs"] == 2
    assert doc["cycles"] >= 5 and abs(doc["latency_s"] - 0.008) < 0.5e-3


def test_joint_states_sparser_than_a_path_are_refused(gao):
    """One joint state per second (a static campaign's rows): not a path."""
    st = run(gao, "rectangle", cycles=3)
    sel = np.arange(0, len(st.joint_stamps), 500)
    with pytest.raises(ValueError, match="not a path"):
        path_report(gao, st.stamps, st.points, st.joint_stamps[sel], st.joints[sel])


def test_a_trajectory_file_gives_the_cycles_and_the_corners(gao):
    from tolerance_ros.core.accuracy.iso_paths import plan_path
    from path_runs import Q_CENTER
    jp, tp = plan_path(gao, "rectangle", speed=0.2, accel=1.0, cycles=4, q_center=Q_CENTER, dwell=0.0)
    st = run(gao, "rectangle", cycles=4, dwell=0.0)
    t = np.arange(int(jp.duration * 500) + 1) / 500
    doc = path_report(gao, st.stamps, st.points, t, jp.at(t), options=PathOptions(trajectory=jp))
    assert doc["cycles_from"] == {"method": "trajectory", "period_s": jp.period} and doc["cycles"] == 4
    corners = np.cumsum([s["length_m"] for s in doc["segments"]])[:-1]
    side = tp.side * 0.8
    expect = np.cumsum([side * np.sqrt(2), side, side * np.sqrt(2)])   # P3->P4, P4->P2, P2->P5 in the plane
    assert corners == pytest.approx(expect, abs=5e-4)      # along the sampled path, which cuts each corner a little
    assert abs(doc["latency_s"] - 1000.008) < 0.5e-3


def test_a_continuous_joint_logged_unwrapped_is_judged_as_its_wrap():
    """The Kinova's first joint is continuous: its angle logged a turn up (past its nominal limits) is the same
    path, and the same report, as the angle logged wrapped."""
    from helpers import example_urdf
    from tolerance_ros.core.accuracy.iso_paths import plan_path
    from tolerance_ros.core.accuracy.simulate import path_streams
    from tolerance_ros.core.models import URDFChain
    chain = URDFChain(example_urdf("kinova.urdf"), tip_link="j2s6s200_end_effector")
    center = np.array([0.3, 3.4, 1.6, -0.5, 2.4, 0.2])
    jp, _ = plan_path(chain, "rectangle", speed=0.1, cycles=3, q_center=center, side=0.1)
    st = path_streams(chain, jp, latency=0.008, noise=10e-6, seed=2)
    wrapped = path_report(chain, st.stamps, st.points, st.joint_stamps, st.joints)
    q = st.joints.copy()
    q[:, 0] += 2 * np.pi
    assert q[:, 0].min() > chain.joint_limits[0, 1]
    doc = path_report(chain, st.stamps, st.points, st.joint_stamps, q)
    assert doc["cycles"] == wrapped["cycles"] == 3
    assert doc["overall"]["AT_p_m"] == pytest.approx(wrapped["overall"]["AT_p_m"], rel=1e-6)


def test_the_return_strokes_of_a_line_are_judged_where_asked(gao):
    """A line driven back and forth without a stop: the forward strokes are the cycles, or, with ``reverse``, the
    return strokes (the same line driven backwards), each with its own figures; the rectangle has none."""
    st = run(gao, "line", cycles=4, dwell=0.0)
    fwd = path_report(gao, st.stamps, st.points, st.joint_stamps, st.joints)
    back = path_report(gao, st.stamps, st.points, st.joint_stamps, st.joints, options=PathOptions(reverse=True))
    assert fwd["cycles"] == back["cycles"] == 4 and fwd["other_motions"] == back["other_motions"] == 4
    assert back["path_length_m"] == pytest.approx(fwd["path_length_m"], rel=1e-3)
    a, b = fwd["segments"][0]["along"]["command_m"], back["segments"][0]["along"]["command_m"]
    assert np.linalg.norm(np.asarray(a[0]) - np.asarray(b[-1])) < 0.01        # the same line, backwards
    assert back["overall"]["AT_p_m"] != fwd["overall"]["AT_p_m"]
    rect = run(gao, "rectangle", cycles=3)
    with pytest.raises(ValueError, match="no motion drives the test path backwards"):
        path_report(gao, rect.stamps, rect.points, rect.joint_stamps, rect.joints, options=PathOptions(reverse=True))
