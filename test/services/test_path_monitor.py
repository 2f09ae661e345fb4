"""The on-line path monitor fed the streams in batches as they would arrive: the same figures as the offline
report on the same log (latency and placement given to both), close to them when it estimates its own, the
points counted as offline, bounded memory, and its diagnostic."""
import numpy as np
import pytest

from path_runs import T_TB, feed, run
from tolerance_ros.core.accuracy import path as P
from tolerance_ros.core.accuracy.path_report import PathOptions, command_points, path_report
from tolerance_ros.core.budget import load_budget
from tolerance_ros.services.path_monitor import ERROR, OK, WARN, PathMonitor


@pytest.fixture(scope="module")
def rect(gao):
    return run(gao, "rectangle", cycles=4)


def test_online_figures_equal_the_offline_report(gao, rect):
    st = rect
    offline = path_report(gao, st.stamps, st.points, st.joint_stamps, st.joints,
                          options=PathOptions(latency=0.008, T_tracker_base=T_TB, step=0.002))
    mon = PathMonitor(gao, latency=0.008, T_tracker_base=T_TB, step=0.002)
    reports = feed(mon, st)
    assert [r["cycles"] for r in reports] == [1, 2, 3, 4]           # one report as each path ends
    last = reports[-1]
    assert len(last["segments"]) == len(offline["segments"]) == 4
    for on, off in zip(last["segments"], offline["segments"]):
        for key in ("AT_p_m", "RT_p_m", "CR_m", "CO_m", "AV", "RV", "FV_m_s"):
            if off[key] is None:
                assert on[key] is None, (on["name"], key)
            else:
                assert on[key] == pytest.approx(off[key], rel=1e-9, abs=1e-15), (on["name"], key)
    c = mon.counts
    assert c["on_path"] + c["at_rest"] + c["outside_joint_states"] + c["other_motions"] == len(st.stamps)
    assert c["at_rest"] == offline["outside"]["at_rest"]
    assert c["outside_joint_states"] == offline["outside"]["outside_joint_states"]


def test_online_stops_equal_the_offline_ones_one_motion_late(gao):
    """A robot that rings at its stops: the monitor judges each stop when the next motion starts (or the streams
    end), with the figures path-report gives offline."""
    from tolerance_ros.core.accuracy.iso_paths import plan_path
    from tolerance_ros.core.accuracy.simulate import path_streams
    jp, _ = plan_path(gao, "line", 0.1, 1.0, 0.5, 3, None, None, seed=0)
    st = path_streams(gao, jp, None, T_TB, 500, 1000, 0.008, 10e-6, 3, settling=(2 * np.pi * 8, 0.2))
    offline = path_report(gao, st.stamps, st.points, st.joint_stamps, st.joints,
                          options=PathOptions(latency=0.008, T_tracker_base=T_TB))["stops"]
    mon = PathMonitor(gao, latency=0.008, T_tracker_base=T_TB)
    reports = feed(mon, st)
    assert [r["stops"]["judged"] for r in reports if r.get("judged")][:3] == [0, 1, 2]   # the stop before each
    from tolerance_ros.core.accuracy.settling import summary
    online = summary(list(mon.stop_list), mon.band)
    assert len(online["stops"]) == len(offline["stops"]) == 6
    for on, off in zip(online["stops"], offline["stops"]):
        for key in ("t_stop_s", "rest_s", "stabilisation_time_s", "overshoot_m", "positioning_time_s"):
            assert on[key] == pytest.approx(off[key], rel=1e-9, abs=1e-12), key
    assert online["stabilisation_time_s"]["max"] > 0.05


def test_online_estimates_its_latency_and_placement(gao, rect):
    st = rect
    offline = path_report(gao, st.stamps, st.points, st.joint_stamps, st.joints)
    mon = PathMonitor(gao, budget=load_budget("gao2023_delta2", gao))
    assert mon.status()[0] == WARN
    reports = feed(mon, st, batch=0.2)
    assert abs(mon.latency - 0.008) < 0.5e-3
    assert reports[-1]["cycles"] == offline["cycles"]
    for on, off in zip(reports[-1]["segments"], offline["segments"]):
        assert on["AT_p_m"] == pytest.approx(off["AT_p_m"], rel=0.1, abs=5e-6)
        assert on["RT_p_m"] == pytest.approx(off["RT_p_m"], rel=0.1)
    level, words = mon.status()
    assert level == OK and "AT_p" in words and "latency 8.0" in words, words


def test_online_refuses_an_uncertain_latency(gao, rect):
    budget = load_budget("gao2023_delta2", gao)
    budget.limit_position = 1e-6
    mon = PathMonitor(gao, budget=budget)
    feed(mon, rect, batch=0.2)
    level, words = mon.status()
    assert level == ERROR and "too uncertain" in words


class _Msg:
    """A duck-typed ROS message: attributes from keywords, nested with dicts."""

    def __init__(self, **kw):
        for k, v in kw.items():
            setattr(self, k, _Msg(**v) if isinstance(v, dict) else v)


def test_messages_are_queued_judged_and_bad_ones_counted(gao, rect):
    st = rect
    mon = PathMonitor(gao, latency=0.008, T_tracker_base=T_TB, step=0.002)
    names = list(gao.joint_names)[::-1]                  # another order: put back in the model's
    reports = []
    stop = st.joint_stamps[0] + 12.0
    for t, q in zip(st.joint_stamps[st.joint_stamps < stop], st.joints[st.joint_stamps < stop]):
        mon.on_joint_state_msg(_Msg(header={"stamp": float(t)}, name=names, position=list(q[::-1])))
    for t, p in zip(st.stamps[st.stamps < stop], st.points[st.stamps < stop]):
        mon.on_point_msg(_Msg(header={"stamp": float(t)}, point={"x": p[0], "y": p[1], "z": p[2]}))
    mon.on_point_msg(_Msg(header={"stamp": float(stop)}, point={"x": float("nan"), "y": 0.0, "z": 0.0}))
    mon.on_joint_state_msg(_Msg(header={"stamp": float(stop)}, name=["joint1"], position=[0.0]))
    reports += mon.flush()
    assert len(reports) == 2 and reports[-1]["cycles"] == 2
    d = mon.diagnostic()
    assert d["values"]["rejected"] == "2" and "no value for joint(s)" in d["values"]["last_rejected"]
    assert d["level"] == OK and "AT_p" in d["message"] and float(d["values"]["AT_p_m"]) > 0


def test_the_simulated_tracker_streams_and_the_monitor_finds_its_latency(gao):
    """The loop without a graph: joint states of a planned rectangle at 500 Hz into the streaming simulated
    tracker (1 kHz, 8 ms late), both into the path monitor."""
    from tolerance_ros.core.accuracy.iso_paths import plan_path
    from tolerance_ros.services.tracker import SimulatedTracker
    jp, _ = plan_path(gao, "rectangle", speed=0.2, cycles=3, q_center=np.radians([0, 45, 0, 60, 0, 30, 0]))
    sim = SimulatedTracker(gao, load_budget("gao2023_delta2", gao).vector_for(gao), seed=2, T_tracker_base=T_TB)
    mon = PathMonitor(gao)
    tj = 100.0 + np.arange(0.0, jp.duration + 0.5, 0.002)
    qj = jp.at(tj - 100.0)
    reports = []
    for k in range(0, len(tj), 50):
        readings = [r for t, q in zip(tj[k:k + 50], qj[k:k + 50]) for r in sim.stream(t, q, 1000.0, 0.008)]
        assert all(np.diff([s for s, _ in readings]) > 0)
        reports += mon.add_joint_states(tj[k:k + 50], qj[k:k + 50])
        if readings:
            reports += mon.add_points(np.array([s for s, _ in readings]), np.array([T[:3, 3] for _, T in readings]))
    assert abs(mon.latency - 0.008) < 0.5e-3
    assert reports and reports[-1]["cycles"] == 3 and reports[-1]["overall"]["AT_p_m"] < 1e-3


def _without(st, joints=None, points=None):
    """The streams of ``st`` with the joint states in ``joints`` (s, s) and the points in ``points`` lost."""
    from tolerance_ros.core.accuracy.simulate import PathStreams
    keep_j = np.ones(len(st.joint_stamps), bool) if joints is None else \
        ~((st.joint_stamps >= joints[0]) & (st.joint_stamps < joints[1]))
    keep_m = np.ones(len(st.stamps), bool) if points is None else ~((st.stamps >= points[0]) & (st.stamps < points[1]))
    return PathStreams(**dict(vars(st), joint_stamps=st.joint_stamps[keep_j], joints=st.joints[keep_j],
                              stamps=st.stamps[keep_m], points=st.points[keep_m]))


@pytest.mark.parametrize("lost", ["joints", "points"])
def test_a_motion_with_lost_messages_is_not_judged_and_the_loss_is_warned_of(gao, rect, lost):
    """0.3 s of one stream lost in the middle of the second cycle: the other three cycles are judged, on line as
    offline (the same figures), the second's points are counted as not judged with the reason, and the status
    names the stream's gap."""
    full = PathMonitor(gao, latency=0.008, T_tracker_base=T_TB, step=0.002)
    motions = []
    for a, b in P.motions(rect.joint_stamps, command_points(gao, rect.joints), 1e-3, 0.05, step=0.002):
        motions.append((rect.joint_stamps[a], rect.joint_stamps[b]))
    start, end = motions[1]
    hole = ((start + end) / 2, (start + end) / 2 + 0.3)
    st = _without(rect, **{lost: hole})
    mon = PathMonitor(gao, latency=0.008, T_tracker_base=T_TB, step=0.002)
    reports = feed(mon, st)
    whole = feed(full, rect)
    assert [r.get("cycles") for r in reports] == [1, None, 2, 3]      # the second cycle's report: not judged
    skipped = reports[1]
    assert not skipped["judged"] and f"{start:.3f} s" in skipped["reason"] and skipped["points"] > 0
    reports = [r for r in reports if r["judged"]]
    assert mon.counts["motions"] == full.counts["motions"] and mon.counts["not_judged"] > 0
    stream = "joint_states" if lost == "joints" else "points"
    assert reports[-1]["stream_gaps"][stream]["gaps"] == 1
    assert abs(reports[-1]["stream_gaps"][stream]["missing"] - (0.3 / (0.002 if lost == "joints" else 0.001))) <= 2
    assert "not judged" in reports[-1]["not_judged"][0] and f"{start:.3f} s" in reports[-1]["not_judged"][0]
    level, words = mon.status()
    assert level == WARN and f"{stream}: 1 gap(s)" in words and "not judged" in words, words
    assert mon.diagnostic()["values"][f"{stream}_gaps"] == "1"
    assert whole[-1]["cycles"] == 4 and full.status()[0] == OK
    offline = path_report(gao, st.stamps, st.points, st.joint_stamps, st.joints,
                          options=PathOptions(latency=0.008, T_tracker_base=T_TB, step=0.002))
    assert offline["cycles"] == 3 and offline["not_judged"] == reports[-1]["not_judged"]
    assert offline["outside"]["not_judged"] == mon.counts["not_judged"]
    assert offline["stream_gaps"][stream]["gaps"] == 1
    for on, off in zip(reports[-1]["segments"], offline["segments"]):
        assert on["AT_p_m"] == pytest.approx(off["AT_p_m"], rel=1e-9) and on["RT_p_m"] == pytest.approx(off["RT_p_m"], rel=1e-9)


def test_a_short_gap_while_the_robot_rests_is_counted_but_judges_every_motion(gao, rect):
    """20 ms of joint states missing before the first motion (a timer late once): every cycle is judged and the
    status stays OK; the gap is counted in the report."""
    st = _without(rect, joints=(rect.joint_stamps[0] + 0.1, rect.joint_stamps[0] + 0.12))
    mon = PathMonitor(gao, latency=0.008, T_tracker_base=T_TB, step=0.002)
    reports = feed(mon, st)
    assert [r["cycles"] for r in reports] == [1, 2, 3, 4] and mon.counts["not_judged"] == 0
    assert reports[-1]["stream_gaps"]["joint_states"]["gaps"] == 1 and mon.status()[0] == OK
