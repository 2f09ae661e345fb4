"""The nodes for real, in one process, over a ROS 2 Jazzy middleware (skipped without rclpy)."""
import json
import os
import threading
import time

import pytest

rclpy = pytest.importorskip("rclpy", reason="ROS 2 Jazzy is not sourced (rclpy not importable)")

from rclpy.executors import MultiThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402

from tolerance_ros.nodes.client import ServiceError, ToleranceClient  # noqa: E402

Q = [0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6]


@pytest.fixture
def ros(tmp_path):
    """rclpy on a private domain, an executor spinning in a thread, and a node factory."""
    rclpy.init(domain_id=100 + os.getpid() % 100)
    executor = MultiThreadedExecutor(num_threads=4)
    nodes = []

    def start(cls, **params):
        node = cls(parameter_overrides=[Parameter(k, value=v) for k, v in params.items()])
        executor.add_node(node)
        nodes.append(node)
        return node

    thread = threading.Thread(target=executor.spin, daemon=True)
    thread.start()
    yield start
    executor.shutdown(timeout_sec=2.0)
    for n in nodes:
        if hasattr(n, "close"):
            n.close()
        n.destroy_node()
    rclpy.shutdown()
    thread.join(timeout=2.0)


@pytest.fixture
def client(ros):
    node = rclpy.create_node("test_client")
    c = ToleranceClient(node=node)
    ex = MultiThreadedExecutor()
    ex.add_node(node)
    t = threading.Thread(target=ex.spin, daemon=True)
    t.start()
    yield c
    ex.shutdown(timeout_sec=2.0)
    node.destroy_node()


def test_error_model_round_trip_and_bad_requests(ros, client):
    from tolerance_ros.nodes.error_model_server import ErrorModelServer
    ros(ErrorModelServer, max_poses=100)
    assert client.wait_for_server("compute_error_jacobian", 20)
    r = client.compute_error_jacobian(Q)
    assert r["ok"] and r["n"] == 1 and len(r["parameters"]) == 28
    for bad, code in (('{"id": "m1", "joints": [1, 2', "invalid_json"),
                      ('{"id": "m2", "joints": [0, 0]}', "invalid_request"),
                      ('{"id": "m3", "joints": ' + json.dumps([Q] * 101) + '}', "too_large")):
        with pytest.raises(ServiceError) as exc:
            _raw(client, "compute_error_jacobian", bad)
        assert exc.value.code == code
    r = client.compute_error_jacobian([Q, Q], outputs="position")
    assert r["ok"] and r["n"] == 2  # still serving


def _raw(client, service, text):
    """Publish raw text with a known id and wait for the response (ServiceError when not ok)."""
    from std_msgs.msg import String
    rid = json.loads(text[: text.index(",")] + "}")["id"]
    ev = threading.Event()
    with client._lock:
        client._events[rid] = ev
    client._pubs[service].publish(String(data=text))
    assert ev.wait(10), f"no response to {rid}"
    with client._lock:
        doc = client._responses.pop(rid)[0]
        client._events.pop(rid)
    if not doc["ok"]:
        raise ServiceError(doc)
    return doc


def test_allocator_answers_while_solving_and_latches_the_budget(ros, client, tmp_path):
    from std_msgs.msg import String
    from tolerance_ros.nodes.common import LATCHED_QOS
    from tolerance_ros.nodes.tolerance_allocator import ToleranceAllocator
    ros(ToleranceAllocator, budget_dir=str(tmp_path))
    assert client.wait_for_server("allocate_tolerances", 20)
    result, progress = {}, []
    worker = threading.Thread(target=lambda: result.update(
        client.allocate_tolerances(0.0014, mc_poses=1000, progress=lambda d: progress.append(d["fraction"]))))
    worker.start()
    time.sleep(1.0)
    status = client.request("allocate_tolerances", {"command": "status"}, 5)
    assert status["ok"] and status["running"] is not None
    with pytest.raises(ServiceError) as exc:
        client.allocate_tolerances(-1.0, timeout=5)
    assert exc.value.code == "invalid_request"
    worker.join(120)
    assert result["status"] == "done" and result["supremum_m"]["paper"] <= 0.0014 and progress
    assert os.path.exists(result["budget_file"])
    # A subscriber that arrives after the fact still gets the budget (transient local).
    late = rclpy.create_node("late_subscriber")
    got = []
    late.create_subscription(String, "tolerance_budget", lambda m: got.append(json.loads(m.data)), LATCHED_QOS)
    deadline = time.monotonic() + 10
    while not got and time.monotonic() < deadline:
        rclpy.spin_once(late, timeout_sec=0.1)
    late.destroy_node()
    assert got and got[0]["budget"]["robot"] == "gao2023_7dof"


def test_publisher_tracker_and_monitor_loop(ros, tmp_path):
    from diagnostic_msgs.msg import DiagnosticArray
    from std_msgs.msg import String
    from tolerance_ros.nodes.accuracy_monitor import AccuracyMonitor
    from tolerance_ros.nodes.joint_state_source import JointStateSource
    from tolerance_ros.nodes.simulated_tracker import SimulatedTrackerNode
    base = [1.5, 0.2, 0.0, 0.0, 0.0, 0.5]
    ros(AccuracyMonitor, budget="gao2023_delta2", campaign="gao2023_iso_cube", tracker_to_base=base,
        log_dir=str(tmp_path), report_period=0.5)
    ros(SimulatedTrackerNode, tracker_to_base=base, measure_every=5)
    ros(JointStateSource, mode="campaign", campaign="gao2023_iso_cube", dwell=0.2, loop=True)
    listener = rclpy.create_node("listener")
    reports, diags = [], []
    listener.create_subscription(String, "/tolerance/accuracy_report", lambda m: reports.append(json.loads(m.data)), 10)
    listener.create_subscription(DiagnosticArray, "/diagnostics", diags.append, 10)
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline and not (reports and reports[-1]["counts"]["paired"] >= 20 and diags):
        rclpy.spin_once(listener, timeout_sec=0.1)
    listener.destroy_node()
    rep = reports[-1]
    assert rep["counts"]["paired"] >= 20 and rep["counts"]["unpaired"] == 0
    assert rep["summary"]["verdicts"]["within"] == rep["counts"]["paired"]
    st = diags[-1].status[0]
    assert st.name == "tolerance_ros: accuracy monitor" and st.level == b"\x00"
    assert any(kv.key == "paired" for kv in st.values)
    logs = list(tmp_path.glob("*.jsonl"))
    assert logs and '"event": "measurement"' in logs[0].read_text()


def test_predicted_bound_at_the_current_joint_state(ros):
    from sensor_msgs.msg import JointState
    from std_msgs.msg import String
    from tolerance_ros.core.budget import load_budget
    from tolerance_ros.core.jsonio import dumps_fast
    from tolerance_ros.core.models import load_robot
    from tolerance_ros.nodes.common import LATCHED_QOS, REQUEST_QOS
    from tolerance_ros.nodes.error_model_server import ErrorModelServer
    ros(ErrorModelServer)
    model = load_robot("gao2023_7dof")
    budget = load_budget("gao2023_delta2", model)
    node = rclpy.create_node("bound_test")
    got = []
    node.create_subscription(String, "/tolerance/predicted_bound", lambda m: got.append(json.loads(m.data)), 10)
    pub_budget = node.create_publisher(String, "tolerance_budget", LATCHED_QOS)
    pub_js = node.create_publisher(JointState, "joint_states", REQUEST_QOS)
    pub_budget.publish(String(data=dumps_fast({"robot": model.name, "budget": budget.to_dict()})))
    deadline = time.monotonic() + 20
    while not got and time.monotonic() < deadline:
        msg = JointState(name=list(model.joint_names), position=Q)
        msg.header.stamp = node.get_clock().now().to_msg()
        pub_js.publish(msg)
        rclpy.spin_once(node, timeout_sec=0.2)
    node.destroy_node()
    assert got and got[0]["criterion"] == "paper" and 0 < got[0]["position_bound_m"] < 1.4e-3
