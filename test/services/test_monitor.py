"""The accuracy monitor's logic with real ROS 2 Jazzy message shapes (from the rosbags package)."""
import json

import numpy as np
import pytest
from rosbags.typesys import Stores, get_typestore

from tolerance_ros.core.accuracy.io import MeasurementError, read_log
from tolerance_ros.core.budget import load_budget
from tolerance_ros.core.campaign import Campaign, TestPose
from tolerance_ros.core.jsonio import dumps_fast
from tolerance_ros.core.geometry import matrices_to_quat, transform
from tolerance_ros.services.monitor import ERROR, OK, WARN, MonitorLogic
from tolerance_ros.services.tracker import SimulatedTracker, stamp_fields

TS = get_typestore(Stores.ROS2_JAZZY)
T_TB = transform([1.5, 0.2, 0.0], [0, 0, 0.5])


def time_msg(t):
    ns = int(round(t * 1e9))
    return TS.types["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9)


def joint_state(t, names, q):
    return TS.types["sensor_msgs/msg/JointState"](
        header=TS.types["std_msgs/msg/Header"](stamp=time_msg(t), frame_id=""), name=list(names),
        position=np.asarray(q, float), velocity=np.zeros(0), effort=np.zeros(0))


def pose_stamped(t, T):
    sec, nsec = stamp_fields(t)
    p, q = T[:3, 3], matrices_to_quat(T[None, :3, :3])[0]
    P, Q = TS.types["geometry_msgs/msg/Point"], TS.types["geometry_msgs/msg/Quaternion"]
    return TS.types["geometry_msgs/msg/PoseStamped"](
        header=TS.types["std_msgs/msg/Header"](stamp=TS.types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec),
                                               frame_id="tracker"),
        pose=TS.types["geometry_msgs/msg/Pose"](position=P(x=p[0], y=p[1], z=p[2]),
                                                orientation=Q(x=q[0], y=q[1], z=q[2], w=q[3])))


def _position_and_quaternion(T):
    return T[:3, 3], matrices_to_quat(T[None, :3, :3])[0]


@pytest.fixture
def setup(gao, tmp_path):
    budget = load_budget("gao2023_delta2", gao)
    qk = gao.sample_joints(3, 1)
    camp = Campaign("c", [TestPose(f"P{i + 1}", joints=qk[i]) for i in range(3)], cycles=5)
    sim = SimulatedTracker(gao, budget.vector_for(gao), seed=2, T_tracker_base=T_TB)
    clock = {"t": 0.0}
    mon = MonitorLogic(gao, budget, camp, slop=0.01, max_wait=0.5, T_tracker_base=T_TB,
                       log_path=tmp_path / "log.jsonl", clock=lambda: clock["t"])
    yield mon, sim, qk, clock, tmp_path / "log.jsonl"
    mon.close()                                     # its campaign log, for the tests that do not close it


def test_pairs_measurements_and_rebuilds_from_the_log(gao, setup):
    mon, sim, qk, clock, log = setup
    t = 100.0
    results = []
    for cycle in range(5):
        for k in range(3):
            q = qk[k]
            results += mon.on_joint_state_msg(joint_state(t - 0.004, gao.joint_names, q))
            # The tracker reading arrives after the state at t - 4 ms and before the one at t + 6 ms.
            results += mon.on_pose_msg(pose_stamped(t, sim.measure_at(q)))
            results += mon.on_joint_state_msg(joint_state(t + 0.006, gao.joint_names, q))
            t += 0.5
    assert len(results) == 15 and mon.counts["paired"] == 15 and mon.counts["unpaired"] == 0
    assert all(r["verdict"] == "within" for r in results)
    rep = mon.report()
    assert rep["summary"]["test_poses"]["P1"]["n"] == 5
    assert json.loads(dumps_fast(rep))["counts"]["paired"] == 15
    mon.close()
    back = read_log(log)
    assert len(back) == 15 and np.allclose(back.joints[0], qk[0]) and list(back.pose[:3]) == ["P1", "P2", "P3"]


def test_unpaired_and_rejected_are_counted_logged_and_reported(gao, setup):
    mon, sim, qk, clock, log = setup
    mon.on_joint_state(10.0, gao.joint_names, qk[0])
    mon.on_joint_state(11.0, gao.joint_names, qk[0])
    assert mon.on_pose(10.5, "tracker", [1, 2, 3], [0, 0, 0, 1]) == []     # no state within 10 ms
    mon.on_pose(12.0, "tracker", [1, 2, np.nan], [0, 0, 0, 1])            # rejected
    assert mon.counts["unpaired"] == 1 and mon.counts["rejected"] == 1
    mon.on_pose(13.0, "tracker", [1, 2, 3], [0, 0, 0, 1])                 # waits for a later state
    assert len(mon.pending) == 1
    clock["t"] = 10.0                                                      # max_wait elapsed
    mon.resolve()
    assert mon.counts["unpaired"] == 2 and not mon.pending
    d = mon.diagnostic()
    assert d["level"] == WARN and "2 unpaired and 1 rejected" in d["message"]
    assert any("unpaired" in r for r in mon.report()["recent_issues"])
    mon.close()
    events = [json.loads(line)["event"] for line in log.read_text().splitlines()]
    assert events.count("measurement") == 3 and events.count("unpaired") == 2
    with pytest.raises(MeasurementError, match="no paired measurements"):
        read_log(log)


def test_joint_state_with_other_names_is_rejected_not_crashing(gao, setup):
    mon, *_ = setup
    assert mon.on_joint_state(1.0, ["a", "b"], [0, 0]) == []
    assert mon.counts["joint_states_rejected"] == 1


def test_names_that_are_not_a_list_and_a_frame_that_is_not_utf8_are_refused_and_counted(gao, setup):
    mon, _, _, _, log = setup
    assert mon.on_joint_state(1.0, None, [0.0] * 7) == []
    assert mon.on_joint_state(1.0, list(gao.joint_names) + ["joint1"], [0.0] * 8) == []
    assert mon.counts["joint_states_rejected"] == 2 and mon.counts["joint_states"] == 0
    assert "name: expected a list of joint names" in mon.last_reasons[-2]
    assert mon.on_pose(1.0, "tracker\ud800", [1, 2, 3], [0, 0, 0, 1]) == []
    assert mon.counts["rejected"] == 1 and "frame_id: not UTF-8 text" in mon.last_reasons[-1]
    mon.close()
    rec = [json.loads(line) for line in log.read_text().splitlines()][-1]
    assert rec["frame"] == "tracker\\ud800" and rec["rejected"].startswith("frame_id")


@pytest.mark.parametrize("criterion", [["paper"], "banana", "per-axis"])
def test_a_budget_with_a_criterion_that_is_not_a_limit_criterion_is_refused_when_it_arrives(gao, setup, criterion):
    from tolerance_ros.services.contracts import ContractError
    mon, sim, qk, _, _ = setup
    before = mon.budget
    bad = load_budget("gao2023_delta2", gao)
    bad.criterion = criterion
    with pytest.raises(ContractError, match=r"budget.criterion: expected one of \['paper', 'worst-case', 'rss'\]"):
        mon.set_budget(bad)
    assert mon.budget is before
    mon.on_joint_state(1.0, gao.joint_names, qk[0])
    [paired] = mon.on_pose(1.0, "tracker", *_position_and_quaternion(sim.measure_at(qk[0])))
    assert paired["verdict"] == "within" and np.isfinite(paired["bound"])  # the bounds of the previous budget


def test_hostile_names_and_frames_take_bounded_space(gao, setup):
    """A joint state with 1,000 long names and a measurement with a 100 kB frame_id: the report and the
    campaign log stay small."""
    mon, _, _, _, log = setup
    for _ in range(20):
        mon.on_joint_state(1.0, ["x" * 5000] * 1000, [0.0] * 1000)
        mon.on_pose(1.0, "f" * 100_000, [1, 2, 3], [0, 0, 0, 1])
    assert len(dumps_fast(mon.report())) < 50_000
    mon.close()
    assert max(len(line) for line in log.read_text().splitlines()) < 1000


def test_diagnostic_levels(gao, setup):
    mon, sim, qk, clock, log = setup
    assert mon.diagnostic()["level"] == OK
    mon.on_joint_state(1.0, gao.joint_names, qk[0])
    T = sim.measure_at(qk[0])
    T[:3, 3] += [0.01, 0, 0]  # 10 mm off: above the 1.4 mm limit
    mon.on_pose(1.0, "tracker", T[:3, 3], matrices_to_quat(T[None, :3, :3])[0])
    mon.on_joint_state(1.01, gao.joint_names, qk[0])
    d = mon.diagnostic()
    assert d["level"] == ERROR and d["values"]["over_limit"] == "1"
    mon.set_budget(None)
    assert mon.diagnostic()["level"] == WARN


def point_stamped(t, p):
    sec, nsec = stamp_fields(t)
    return TS.types["geometry_msgs/msg/PointStamped"](
        header=TS.types["std_msgs/msg/Header"](stamp=TS.types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec),
                                               frame_id="tracker"),
        point=TS.types["geometry_msgs/msg/Point"](x=p[0], y=p[1], z=p[2]))


def test_several_reflectors_are_judged_at_their_own_points_and_logged_by_name(gao, tmp_path):
    from tolerance_ros.core.accuracy.simulate import measure_targets
    from tolerance_ros.services.monitor import monitor_targets
    targets = monitor_targets("point", "A, B", [0.2, 0.0, 0.05, 0.0, 0.2, 0.05])
    assert targets.names == ("A", "B") and not targets.frames
    budget = load_budget("gao2023_delta2", gao)
    qk = gao.sample_joints(3, 2)
    camp = Campaign("c", [TestPose(f"P{i + 1}", joints=qk[i]) for i in range(3)], cycles=2)
    mon = MonitorLogic(gao, budget, camp, slop=0.01, max_wait=0.5, T_tracker_base=T_TB, targets=targets,
                       log_path=tmp_path / "log.jsonl", clock=lambda: 0.0, orientation=False)
    q = np.repeat(qk, 2, axis=0)
    m = measure_targets(gao, q, None, targets, 0.0, 0.0, T_TB, stamps=np.arange(len(q)) + 10.0)
    results = []
    for i in range(len(m)):
        if i % 2 == 0:
            mon.on_joint_state_msg(joint_state(m.stamps[i], gao.joint_names, m.joints[i]))
        results += mon.on_point_msg(point_stamped(m.stamps[i], m.T[i, :3, 3]), str(m.target[i]))
    mon.on_joint_state_msg(joint_state(100.0, gao.joint_names, qk[0]))
    results += mon.resolve()
    assert len(results) == 12 and {r["target"] for r in results} == {"A", "B"}
    assert max(r["position_error"] for r in results) < 1e-9 and all(r["orientation_error"] is None for r in results)
    rep = mon.report()["summary"]
    assert sorted(rep["test_poses"]) == sorted(f"P{i}@{t}" for i in (1, 2, 3) for t in "AB")
    assert rep["orientation_error_rad"] is None
    assert mon.on_point_msg(point_stamped(50.0, [0, 0, 0]), "C") == [] and mon.counts["rejected"] == 1
    mon.close()
    back = read_log(tmp_path / "log.jsonl")
    assert back.has_orientation is False and sorted(set(back.target)) == ["A", "B"] and len(back) == 12


@pytest.mark.parametrize("args, message", [
    (("pose", "A,B", [0.0] * 3), None),
    (("pose", "A,A", [0.0] * 3), "appears twice"),
    (("pose", "A,2b", [0.0] * 3), "not a ROS name token"),
    (("pose", "A,B", [0.1, 0.0, 0.0]), "expected 6 values"),
    (("laser", "", [0.0] * 3), "expected 'pose' or 'point'"),
    (("point", "", [0.0, 0.0, 9.0]), "more than 5 m"),
])
def test_the_monitors_target_parameters_are_checked(args, message):
    from tolerance_ros.services.monitor import monitor_targets
    if message is None:
        assert monitor_targets(*args).names == ("A", "B")
        return
    with pytest.raises(ValueError, match=message):
        monitor_targets(*args)


def test_the_messages_a_stream_lost_are_seen_in_its_stamps_and_warned_of(gao, setup):
    """A 1 kHz joint-state stream whose reader lost 1.2 s of it (its queue overflowed): the status warns, names
    the stream and says about how many messages never came; the same stream complete is not warned of."""
    mon, sim, qk, clock, log = setup
    t = 100.0 + np.arange(3000) * 1e-3
    for k in np.r_[0:1000, 2200:3000]:
        mon.on_joint_state_msg(joint_state(t[k], gao.joint_names, qk[0]))
    mon.on_pose_msg(pose_stamped(t[2500], sim.measure_at(qk[0])))
    mon.resolve()
    d = mon.diagnostic()
    assert d["level"] == WARN and "joint_states: 1 gap(s)" in d["message"] and "about 1,200 message(s)" in d["message"]
    assert d["values"]["joint_states_gaps"] == "1" and d["values"]["measured_pose_gaps"] == "0"
    gaps = json.loads(dumps_fast(mon.report()))["stream_gaps"]
    assert gaps["joint_states"]["missing"] == 1200 and abs(gaps["joint_states"]["longest_gap_s"] - 1.201) < 1e-9
    assert mon.counts["paired"] == 1

    complete = MonitorLogic(gao, None, None, slop=0.01, max_wait=0.5, T_tracker_base=T_TB)
    for k in range(3000):
        complete.on_joint_state(t[k], gao.joint_names, qk[0])
    assert "gap" not in complete.diagnostic()["message"] and complete.report()["stream_gaps"]["joint_states"]["gaps"] == 0
    late = MonitorLogic(gao, None, None, slop=0.01, max_wait=0.5, T_tracker_base=T_TB)   # a timer 0.1 s late once
    for k in np.r_[0:1000, 1100:3000]:
        late.on_joint_state(t[k], gao.joint_names, qk[0])
    assert "gap" not in late.diagnostic()["message"] and late.report()["stream_gaps"]["joint_states"]["gaps"] == 0


def test_a_short_hole_is_warned_of_when_the_monitor_was_behind_and_its_queue_overflowed(gao, setup):
    """0.3 s of a 1 kHz stream lost while the monitor's callbacks waited (a queue of 1,000: the message after
    the hole is 1 s old when taken): under the 0.5 s of a late publisher, yet warned of, as the monitor's own
    loss, with the ROS time each message was taken; without it (offline) the hole is a late timer."""
    mon, sim, qk, clock, log = setup
    t = 100.0 + np.arange(3000) * 1e-3
    taken = np.r_[0:1000, 1300:3000]
    received = np.where(taken < 2300, t[2300] + (taken - 1300) * 1e-6, t[taken] + 2e-4)
    received[taken < 1000] = t[taken[taken < 1000]] + 2e-4
    offline = MonitorLogic(gao, None, None, slop=0.01, max_wait=0.5, T_tracker_base=T_TB)
    for k, r in zip(taken, received):
        mon.on_joint_state_msg(joint_state(t[k], gao.joint_names, qk[0]), received=r)
        offline.on_joint_state(t[k], gao.joint_names, qk[0])
    d = mon.diagnostic()
    assert d["level"] == WARN and "joint_states: 1 gap(s)" in d["message"] and "about 300 message(s)" in d["message"]
    assert "while this reader was behind" in d["message"]
    assert mon.report()["stream_gaps"]["joint_states"]["behind"] == 1
    assert "gap" not in offline.diagnostic()["message"]


def test_a_test_pose_that_drifts_is_a_warning_with_its_figure(gao, tmp_path):
    budget = load_budget("gao2023_delta2", gao)
    qk = gao.sample_joints(3, 1)
    camp = Campaign("c", [TestPose(f"P{i + 1}", joints=qk[i]) for i in range(3)], cycles=5)
    sim = SimulatedTracker(gao, budget.vector_for(gao), seed=2, T_tracker_base=T_TB, noise_position=0.0)
    mon = MonitorLogic(gao, budget, camp, slop=0.01, max_wait=0.5, T_tracker_base=T_TB, drift_window=60.0,
                       drift_limit=0.05e-3)
    t = 100.0
    for cycle in range(40):                               # 40 cycles of 10 s: P2 creeps 4 um a cycle along y
        for k in range(3):
            T = sim.measure_at(qk[k])
            if k == 1:
                T[:3, 3] += T_TB[:3, :3] @ [0, 4e-6 * cycle, 0]
            mon.on_joint_state_msg(joint_state(t - 0.004, gao.joint_names, qk[k]))
            mon.on_pose_msg(pose_stamped(t, T))
            mon.on_joint_state_msg(joint_state(t + 0.006, gao.joint_names, qk[k]))
            t += 10.0 / 3
    d = mon.report()["drift"]["poses"]
    assert d["P1"]["dAP_p_m"] < 1e-9 and d["P2"]["windows"] == 6
    # windows of 6 cycles: the last closed one (cycles 30-35) against the first (0-5): 30 cycles x 4 um
    assert d["P2"]["dAP_p_m"] == pytest.approx(30 * 4e-6, rel=1e-6)
    diag = mon.diagnostic()
    assert diag["level"] == WARN and "drift: P2 moved 0.1200 mm since its first 60 s (limit 0.0500 mm)" in \
        diag["message"]
    assert float(diag["values"]["drift_max_m"]) == pytest.approx(1.2e-4, rel=1e-6)
