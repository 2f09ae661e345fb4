"""The trajectory compensator's logic with real ROS 2 Jazzy message shapes (from the rosbags package):
the compensated points are what ``tolerance-ros compensate`` gives for the same targets."""
import json

import numpy as np
import pytest
import yaml
from rosbags.typesys import Stores, get_typestore

from tolerance_ros.cli import main
from tolerance_ros.core.accuracy.simulate import as_built_errors, measure_targets
from tolerance_ros.core.budget import load_budget
from tolerance_ros.core.calibration.calibrate import calibrate_measurements
from tolerance_ros.core.calibration.planning import campaign_dict
from tolerance_ros.core.calibration.calibration_file import calibration_from_text, calibration_text, save_calibration
from tolerance_ros.core.geometry import transform
from tolerance_ros.services.trajectory import TrajectoryError, TrajectoryLogic

TS = get_typestore(Stores.ROS2_JAZZY)


@pytest.fixture(scope="module")
def calibration(gao):
    dx = as_built_errors(load_budget("gao2023_delta2", gao).vector_for(gao), 7)
    q = np.repeat(gao.sample_joints(30, 7), 2, axis=0)
    m = measure_targets(gao, q, dx, None, 1e-5, 0.0, transform([1.5, 0.2, 0.0], [0, 0, 0.5]), seed=3,
                        labels=[f"P{i // 2}" for i in range(60)])
    return calibrate_measurements(gao, m, sigma_position=1e-5)


def trajectory(names, P, V=None):
    Pt = TS.types["trajectory_msgs/msg/JointTrajectoryPoint"]
    Dur = TS.types["builtin_interfaces/msg/Duration"]
    pts = [Pt(positions=np.asarray(p, float), velocities=np.asarray(V[i] if V is not None else [], float),
              accelerations=np.zeros(0), effort=np.zeros(0), time_from_start=Dur(sec=i, nanosec=0))
           for i, p in enumerate(P)]
    return TS.types["trajectory_msgs/msg/JointTrajectory"](
        header=TS.types["std_msgs/msg/Header"](stamp=TS.types["builtin_interfaces/msg/Time"](sec=0, nanosec=0),
                                               frame_id=""), joint_names=list(names), points=pts)


def test_the_points_are_what_compensate_gives_in_any_joint_order_extra_joints_untouched(gao, calibration, tmp_path,
                                                                                         capsys):
    q = gao.sample_joints(8, 4) * 0.6
    cal_path = save_calibration(calibration, tmp_path / "calibration.yaml")
    (tmp_path / "targets.yaml").write_text(yaml.safe_dump(campaign_dict(gao, q, "t", 1)))
    assert main(["compensate", "--robot", "gao2023_7dof", "--calibration", str(cal_path), "--poses",
                 str(tmp_path / "targets.yaml"), "--json", "--quiet"]) == 0
    cli = np.array([r["joints"] for r in json.loads(capsys.readouterr().out)["poses"]])
    order = [3, 0, 6, 1, 5, 2, 4]
    names = [gao.joint_names[i] for i in order] + ["gripper"]
    P = np.c_[q[:, order], np.full(len(q), 0.02)]
    logic = TrajectoryLogic(gao, calibration_from_text(calibration_text(calibration, {"length": "m", "angle": "rad"}),
                                                       gao))
    res = logic.compensate_msg(trajectory(names, P, np.ones_like(P) * 0.1))
    assert res["ok"] and not res["flagged"]
    assert np.abs(res["positions"][:, :7] - cli[:, order]).max() < 1e-9
    assert np.array_equal(res["positions"][:, 7], P[:, 7]) and np.array_equal(res["velocities"][:, 7], P[:, 7] * 0 + 0.1)
    assert 0 < np.abs(res["positions"][:, :7] - P[:, :7]).max() < 0.1


def test_flagged_points_reject_the_trajectory_or_go_as_planned(gao, calibration):
    q = gao.sample_joints(4, 5) * 0.6
    q[2] = 0.0                                             # stretched out: near a singularity
    for on_flag in ("reject", "nominal"):
        logic = TrajectoryLogic(gao, calibration, on_flag=on_flag)
        res = logic.compensate(gao.joint_names, q)
        assert res["flagged"] == [2] and "singularity" in res["reasons"][2]
        if on_flag == "reject":
            assert not res["ok"] and "rejected" in res["message"] and logic.counts["rejected"] == 1
        else:
            assert res["ok"] and np.array_equal(res["positions"][2], q[2]) and not np.array_equal(res["positions"][0], q[0])


def test_without_a_calibration_trajectories_pass_through_and_bad_ones_are_refused(gao):
    logic = TrajectoryLogic(gao)
    q = gao.sample_joints(3, 1)
    res = logic.compensate(gao.joint_names, q)
    assert res["ok"] and np.array_equal(res["positions"], q) and "passed through" in res["message"]
    assert logic.diagnostic()["level"] == 1
    with pytest.raises(TrajectoryError, match=r"no \['joint7'\]"):
        logic.compensate(gao.joint_names[:6], q[:, :6])
    with pytest.raises(TrajectoryError, match="point 1: not finite"):
        logic.compensate(gao.joint_names, np.where(np.arange(3)[:, None] == 1, np.nan, q))
    with pytest.raises(TrajectoryError, match="given for some points"):
        logic.compensate_msg(_mixed(gao, q))


def _mixed(gao, q):
    a = trajectory(gao.joint_names, q[:1], np.zeros((1, 7)))
    b = trajectory(gao.joint_names, q[1:2])
    a.points.append(b.points[0])
    return a


def test_the_cdr_codec_reads_and_writes_what_ros_serializes(gao):
    from tolerance_ros.services.trajectory_cdr import CdrError, decode, encode
    rng = np.random.default_rng(0)
    q = rng.normal(size=(5, 7))
    msg = trajectory(list(gao.joint_names), q, rng.normal(size=(5, 7)))
    msg.header.frame_id = "bäse"
    msg.points[2].effort = rng.normal(size=3)
    raw = bytes(TS.serialize_cdr(msg, "trajectory_msgs/msg/JointTrajectory"))
    t = decode(raw)
    assert t.joint_names == list(gao.joint_names) and t.frame_id == "bäse"
    assert np.array_equal(np.array(t.positions), q) and len(t.effort[2]) == 3 and len(t.accelerations[0]) == 0
    assert encode(t) == raw
    back = TS.deserialize_cdr(encode(t), "trajectory_msgs/msg/JointTrajectory")
    assert np.array_equal(back.points[4].velocities, msg.points[4].velocities)
    assert [p.time_from_start.sec for p in back.points] == list(range(5))
    with pytest.raises(CdrError, match="does not fit|truncated"):
        decode(raw[:-9])


def test_the_codec_reads_every_layout_the_fast_way_and_the_slow_way_alike():
    """Random trajectories (point counts, sizes equal or not, empty arrays, odd string lengths that shift the
    alignment): decoded exactly, re-encoded byte for byte, a truncated one refused."""
    from tolerance_ros.services.trajectory_cdr import CdrError, decode, encode, replaced
    T, rng = TS.types, np.random.default_rng(1)
    for trial in range(150):
        m, k = int(rng.integers(0, 9)), int(rng.integers(1, 8))
        same = [k] + [int(rng.integers(0, 4)) * int(rng.random() < 0.5) for _ in range(3)]
        pts = []
        for _ in range(m):
            sv = same if trial % 2 else [int(rng.integers(0, 9)) for _ in range(4)]
            pts.append(T["trajectory_msgs/msg/JointTrajectoryPoint"](
                positions=rng.normal(size=sv[0]), velocities=rng.normal(size=sv[1]),
                accelerations=rng.normal(size=sv[2]), effort=rng.normal(size=sv[3]),
                time_from_start=T["builtin_interfaces/msg/Duration"](sec=int(rng.integers(-5, 5)),
                                                                     nanosec=int(rng.integers(0, 10 ** 9)))))
        msg = T["trajectory_msgs/msg/JointTrajectory"](
            header=T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=3, nanosec=4),
                                            frame_id="x" * int(rng.integers(0, 5))),
            joint_names=[f"j{i}" for i in range(int(rng.integers(0, 4)))], points=pts)
        raw = bytes(TS.serialize_cdr(msg, "trajectory_msgs/msg/JointTrajectory"))
        t = decode(raw)
        assert encode(t) == raw
        for i, p in enumerate(pts):
            for f in ("positions", "velocities", "accelerations", "effort"):
                assert np.array_equal(np.asarray(getattr(t, f)[i]), getattr(p, f))
            assert tuple(t.time_from_start[i]) == (p.time_from_start.sec, p.time_from_start.nanosec)
        if m and trial % 2:
            new = rng.normal(size=(m, k))
            back = TS.deserialize_cdr(replaced(raw, t, new), "trajectory_msgs/msg/JointTrajectory")
            assert np.array_equal(np.array([p.positions for p in back.points]), new)
            with pytest.raises(CdrError):
                decode(raw[:-1])


def test_a_serialized_trajectory_in_gives_the_same_compensation_out(gao, calibration):
    q = gao.sample_joints(6, 8) * 0.6
    msg = trajectory(list(gao.joint_names), q, np.full_like(q, 0.2))
    logic = TrajectoryLogic(gao, calibration)
    raw, res = logic.compensate_raw(bytes(TS.serialize_cdr(msg, "trajectory_msgs/msg/JointTrajectory")))
    ref = logic.compensate_msg(msg)
    back = TS.deserialize_cdr(raw, "trajectory_msgs/msg/JointTrajectory")
    assert np.array_equal(np.array([p.positions for p in back.points]), ref["positions"])
    assert np.array_equal(np.array([p.velocities for p in back.points]), ref["velocities"])


@pytest.mark.parametrize("sizes", [(1, 0), (7, 6), (0, 7)])
def test_a_serialized_trajectory_with_ragged_positions_is_refused_naming_the_point(gao, calibration, sizes):
    q = gao.sample_joints(2, 3)
    msg = trajectory(list(gao.joint_names), q)
    for p, k in zip(msg.points, sizes):
        p.positions = p.positions[:k]
    bad = next(i for i, k in enumerate(sizes) if k != 7)
    with pytest.raises(TrajectoryError, match=rf"points\[{bad}\].positions: expected 7 numbers"):
        TrajectoryLogic(gao, calibration).compensate_raw(bytes(TS.serialize_cdr(msg, "trajectory_msgs/msg/JointTrajectory")))


def test_a_point_whose_joint_change_exceeds_the_envelope_is_flagged_and_never_sent_corrected(gao, calibration):
    from tolerance_ros.core.calibration.envelope import Envelope
    q = gao.sample_joints(4, 11) * 0.6
    free = TrajectoryLogic(gao, calibration)
    change = np.abs(free.compensate(gao.joint_names, q)["positions"] - q).max(axis=1)
    tight = Envelope(max_joint=float(np.sort(change)[1]) * 1.0001)  # the two points of largest change exceed it
    over = sorted(np.argsort(change)[2:].tolist())
    logic = TrajectoryLogic(gao, calibration, envelope=tight)
    res = logic.compensate(gao.joint_names, q)
    assert not res["ok"] and res["flagged"] == over and logic.counts["points_over_envelope"] == 2
    assert "exceeds max_joint_correction" in res["reasons"][over[0]] and res["message"].startswith("trajectory rejected")
    sent = TrajectoryLogic(gao, calibration, on_flag="nominal", envelope=tight).compensate(gao.joint_names, q)
    assert sent["ok"] and np.array_equal(sent["positions"][over], q[over])       # sent as planned, uncorrected
    kept = [i for i in range(4) if i not in over]
    assert np.abs(sent["positions"][kept] - q[kept]).max() > 0
    assert TrajectoryLogic(gao, calibration, envelope=Envelope()).compensate(gao.joint_names, q)["flagged"] == []
