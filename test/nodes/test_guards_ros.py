"""The guards that hold without SROS2, on a real ROS 2 Jazzy middleware (skipped without rclpy): the correction
envelope, trusted signatures, provenance in logs, diagnostics and the report, read-only parameters, managed
timers, the rclpy internal the error model reads joint states through, missing packages."""
import copy
import json
import subprocess
import sys
import time
import uuid

import numpy as np
import pytest

rclpy = pytest.importorskip("rclpy", reason="ROS 2 Jazzy is not sourced (rclpy not importable)")

from std_msgs.msg import String  # noqa: E402

from ros_graph import Graph, wait_for  # noqa: E402
from tolerance_ros.core.accuracy.simulate import as_built_errors, measure  # noqa: E402
from tolerance_ros.core.budget import load_budget  # noqa: E402
from tolerance_ros.core.calibration.calibrate import calibrate  # noqa: E402
from tolerance_ros.core.calibration.provenance import generate_key_pair, load_signing_key, new_provenance  # noqa: E402
from tolerance_ros.core.calibration.calibration_file import SI, calibration_from_text, calibration_text  # noqa: E402
from tolerance_ros.core.models import load_robot  # noqa: E402
from tolerance_ros.nodes.common import LATCHED_QOS  # noqa: E402

GAO = load_robot("gao2023_7dof")


@pytest.fixture
def graph():
    g = Graph()
    yield g
    g.close()


@pytest.fixture
def ns():
    return f"/g{uuid.uuid4().hex[:8]}"


@pytest.fixture(scope="module")
def cals():
    """(a calibration of a robot built within gao2023_delta2, the same with 50 mrad more on joint 2)."""
    q = GAO.sample_joints(30, 6)
    good = calibrate(GAO, q, measure(GAO, q, as_built_errors(load_budget("gao2023_delta2", GAO).vector_for(GAO), 1),
                                     1e-5, 0.0, None, seed=2), folds=3)
    good.provenance = new_provenance("/cell/tolerance_accuracy_monitor", request_id="k1")
    bad = copy.deepcopy(good)
    bad.dx = good.dx.copy()
    bad.dx[list(GAO.param_names).index("theta2")] += 0.05
    bad.provenance = new_provenance("/somewhere/else")
    return good, bad


def collect(node, msg_type, topic, qos=10):
    got = []
    node.create_subscription(msg_type, topic, got.append, qos)
    return got


def status(diags, name):
    """The latest DiagnosticStatus of that name, as (level, message, {key: value})."""
    found = [s for d in diags for s in d.status if s.name == name]
    if not found:
        return None
    s = found[-1]
    return s.level, s.message, {kv.key: kv.value for kv in s.values}


def test_a_50_mrad_calibration_is_refused_by_the_compensator_and_the_error_model_with_the_reason(graph, ns, cals):
    """Published on tolerance_calibration by a node outside the suite: the calibration in force stays (the
    compensated trajectory does not move), /diagnostics says why, the error model's calibrated model stays."""
    from diagnostic_msgs.msg import DiagnosticArray
    from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint
    from tolerance_ros.core.calibration.compensate import compensate
    from tolerance_ros.nodes.error_model_server import ErrorModelServer
    from tolerance_ros.nodes.trajectory_compensator import TrajectoryCompensator
    good, bad = cals
    graph.start(TrajectoryCompensator, ns, report_period=0.2)
    graph.start(ErrorModelServer, ns, report_period=0.2)
    node = graph.node("cell", ns)
    rogue = graph.node("rogue", ns)
    diags = collect(node, DiagnosticArray, "/diagnostics")
    out = collect(node, JointTrajectory, "joint_trajectory")
    plan = node.create_publisher(JointTrajectory, "joint_trajectory_in", 10)
    node.create_publisher(String, "tolerance_calibration", LATCHED_QOS).publish(String(data=calibration_text(good, SI)))
    comp_name, model_name = f"{ns}/tolerance_ros: trajectory compensator", f"{ns}/tolerance_ros: error model"
    good_sha = calibration_from_text(calibration_text(good, SI), GAO).content_sha256
    assert wait_for(lambda: all((status(diags, n) or (0, "", {}))[2].get("calibration_sha256") == good_sha
                                for n in (comp_name, model_name)), 30)
    rogue.create_publisher(String, "tolerance_calibration", LATCHED_QOS).publish(String(data=calibration_text(bad, SI)))
    bad_sha = calibration_from_text(calibration_text(bad, SI), GAO).content_sha256
    assert wait_for(lambda: all((status(diags, n) or (0, "", {}))[2].get("last_refused_sha256") == bad_sha
                                for n in (comp_name, model_name)), 30)
    for name in (comp_name, model_name):
        level, message, values = status(diags, name)
        assert level == b"\x01" and message.startswith(f"calibration {bad_sha[:12]} refused, the one in force stays: "
                                                       f"correction outside the envelope")
        assert "joint2 by up to 5" in message and values["calibration_sha256"] == good_sha
        assert values["calibration_made_by"] == "/cell/tolerance_accuracy_monitor" and values["calibrations_refused"] == "1"
    q = GAO.sample_joints(3, 4) * 0.5
    assert wait_for(lambda: plan.get_subscription_count() > 0)
    plan.publish(JointTrajectory(joint_names=list(GAO.joint_names),
                                 points=[JointTrajectoryPoint(positions=row.tolist()) for row in q]))
    assert wait_for(lambda: out, 20)
    sent = np.array([p.positions for p in out[0].points])
    expect = compensate(good.mechanism(GAO), GAO, joints=q).q
    assert np.abs(sent - expect).max() < 1e-9                        # the good calibration's compensation
    client = graph.client(ns)
    assert client.wait_for_server("compute_error_jacobian", 20)
    served = client.compute_error_jacobian(q.tolist(), model="calibrated", include_jacobian=False)
    np.testing.assert_allclose(np.array(served["poses"]), good.fk(GAO, q), atol=1e-12)


def test_with_trusted_keys_only_signed_calibrations_are_put_in_force(graph, ns, cals, tmp_path):
    from diagnostic_msgs.msg import DiagnosticArray
    from tolerance_ros.nodes.trajectory_compensator import TrajectoryCompensator
    good, _ = cals
    generate_key_pair(tmp_path / "monitor.key", tmp_path / "monitor.pub")
    generate_key_pair(tmp_path / "other.key", tmp_path / "other.pub")
    comp = graph.start(TrajectoryCompensator, ns, report_period=0.2, trusted_calibration_keys=[str(tmp_path / "monitor.pub")])
    node = graph.node("cell", ns)
    diags = collect(node, DiagnosticArray, "/diagnostics")
    pub = node.create_publisher(String, "tolerance_calibration", LATCHED_QOS)
    name = f"{ns}/tolerance_ros: trajectory compensator"
    for text, why in ((calibration_text(good, SI), "unsigned, and this node trusts only"),
                      (calibration_text(good, SI, load_signing_key(tmp_path / "other.key")), "which this node does not trust")):
        pub.publish(String(data=text))
        assert wait_for(lambda: why in ((status(diags, name) or (0, "", {}))[1]), 20), status(diags, name)
        assert comp.logic.calibration is None
    signed = calibration_text(good, SI, load_signing_key(tmp_path / "monitor.key"))
    pub.publish(String(data=signed))
    assert wait_for(lambda: comp.logic.calibration is not None, 20)
    assert wait_for(lambda: (status(diags, name) or (0, "", {}))[2].get("calibration_signed_by") ==
                    calibration_from_text(signed, GAO).signature["key_id"], 20)


def test_the_monitors_report_names_the_calibration_in_force(graph, ns, cals, tmp_path):
    from tolerance_ros.nodes.accuracy_monitor import AccuracyMonitor
    good, _ = cals
    monitor = graph.start(AccuracyMonitor, ns, log_dir=str(tmp_path), report_period=0.2)
    node = graph.node("cell", ns)
    reports = collect(node, String, "tolerance/accuracy_report")
    node.create_publisher(String, "tolerance_calibration", LATCHED_QOS).publish(String(data=calibration_text(good, SI)))
    assert wait_for(lambda: reports and json.loads(reports[-1].data)["calibration"], 20)
    cal = json.loads(reports[-1].data)["calibration"]
    read = calibration_from_text(calibration_text(good, SI), GAO)
    assert cal["sha256"] == read.content_sha256 and cal["id"] == good.provenance["id"]
    assert cal["made_by"] == "/cell/tolerance_accuracy_monitor" and cal["request_id"] == "k1"
    assert cal["source"] == "tolerance_calibration" and monitor.gate.current["sha256"] == read.content_sha256
    log = next(tmp_path.glob("*.jsonl")).read_text()
    assert f'"sha256":"{read.content_sha256}"' in log.replace(" ", "")


def test_parameters_are_read_only_with_their_ranges(graph, ns):
    from rclpy.parameter import Parameter
    from tolerance_ros.nodes.accuracy_monitor import AccuracyMonitor
    from tolerance_ros.nodes.error_model_server import ErrorModelServer
    node = graph.start(ErrorModelServer, ns)
    result = node.set_parameters([Parameter("bound_rate", value=5.0)])[0]
    assert not result.successful and "read-only" in result.reason and node.get_parameter("bound_rate").value == 20.0
    desc = node.describe_parameter("bound_rate")
    assert desc.read_only and desc.floating_point_range[0].from_value == 1e-3
    assert node.describe_parameter("max_joint_correction").floating_point_range[0].to_value == pytest.approx(3.14159)
    assert node.describe_parameter("max_poses").integer_range[0].from_value == 1
    with pytest.raises(Exception, match="slop out of range"):
        graph.start(AccuracyMonitor, f"{ns}/x", slop=-1.0)


def test_a_managed_node_cancels_its_timers_while_inactive(graph, ns):
    from rclpy.lifecycle import TransitionCallbackReturn
    from tolerance_ros.nodes.lifecycle import managed
    from tolerance_ros.nodes.trajectory_compensator import TrajectoryCompensator
    node = graph.start(managed(TrajectoryCompensator), ns)
    ok = TransitionCallbackReturn.SUCCESS
    assert node.trigger_configure() == ok
    timers = node.made_timers()
    assert timers and all(t.is_canceled() for t in timers)           # configured: nothing wakes the executor
    assert node.trigger_activate() == ok
    assert not any(t.is_canceled() for t in timers)
    calls = []
    original = node.publish_status
    node.diag_pub.publish = lambda msg: calls.append(msg)
    assert wait_for(lambda: len(calls) >= 2, 10)
    assert node.trigger_deactivate() == ok
    assert all(t.is_canceled() for t in timers)
    seen = len(calls)
    time.sleep(2.5)                                                  # report_period 1 s: two periods and more
    assert len(calls) == seen and original is not None
    assert node.trigger_activate() == ok
    assert wait_for(lambda: len(calls) > seen, 10)


def test_take_latest_reads_rclpys_subscription_handle(graph, ns):
    """The error model reads joint states through rclpy's own ``subscription.handle.take_message`` (an internal
    of rclpy): this test fails when rclpy changes it. The newest message is returned, older ones dropped."""
    from rclpy.serialization import deserialize_message
    from sensor_msgs.msg import JointState
    from tolerance_ros.nodes.common import MEASUREMENT_QOS, take_latest
    from tolerance_ros.nodes.error_model_server import ErrorModelServer
    server = graph.start(ErrorModelServer, ns)
    sub = server.joint_states
    assert hasattr(sub, "handle") and hasattr(sub.handle, "take_message") and sub.msg_type is JointState
    pub = graph.node("robot", ns).create_publisher(JointState, "joint_states", MEASUREMENT_QOS)
    assert wait_for(lambda: pub.get_subscription_count() > 0)
    for timer in server.timers:  # nothing else takes from the subscription while this test reads it
        timer.cancel()
    for k in range(5):
        msg = JointState(name=list(GAO.joint_names), position=[0.1 * k] * 7)
        msg.header.stamp.sec = k
        pub.publish(msg)
        time.sleep(0.05)
    raw = None
    deadline = time.monotonic() + 10
    while raw is None and time.monotonic() < deadline:
        raw = take_latest(sub)
        time.sleep(0.05)
    assert isinstance(raw, bytes) and deserialize_message(raw, JointState).header.stamp.sec == 4
    assert take_latest(sub) is None                                  # the older ones were dropped


MISSING = """
import sys
sys.modules["scipy"] = None          # as a ROS Python without scipy
from tolerance_ros.nodes.accuracy_monitor import main
main(["--ros-args", "-r", "__ns:=" + sys.argv[1], "-p", "log_dir:=" + sys.argv[2]])
"""


def test_a_node_without_scipy_refuses_to_start_and_says_how_to_install_it(ns, tmp_path):
    out = subprocess.run([sys.executable, "-c", MISSING, ns, str(tmp_path)], capture_output=True, text=True, timeout=120)
    assert out.returncode == 1, out.stderr
    assert f"{ns}/tolerance_accuracy_monitor cannot start" in out.stderr and "lacks 'scipy'" in out.stderr
    assert "pip install 'scipy>=1.11.2'" in out.stderr and "Traceback" not in out.stderr
    assert not list(tmp_path.glob("*.jsonl"))                         # it never started
