"""Calibration without a tracker on a real ROS 2 graph (skipped without rclpy): the accuracy monitor latches the
joint state of each ``tolerance/contact`` request into its log, answers on ``tolerance/contact/result``, and its
calibrate service fits that log and puts the calibration in force."""
import json
import time
import uuid
from pathlib import Path

import numpy as np
import pytest

rclpy = pytest.importorskip("rclpy", reason="ROS 2 Jazzy is not sourced (rclpy not importable)")

from sensor_msgs.msg import JointState  # noqa: E402
from std_msgs.msg import String  # noqa: E402

from ros_graph import Graph, wait_for  # noqa: E402
from tolerance_ros.core.accuracy.simulate import as_built_errors, touch  # noqa: E402
from tolerance_ros.core.models.urdf import URDFChain  # noqa: E402
from tolerance_ros.nodes.common import LATCHED_QOS, MEASUREMENT_QOS, SERVICE_REQUEST_QOS  # noqa: E402

URDF = Path(__file__).resolve().parents[1] / "data" / "fanuc_r2000ic" / "fanuc_r2000ic_165f.urdf"
PLANES = [("floor", (0, 0, 1.0), 0.3), ("wall", (1.0, 0, 0), 1.7), ("side", (0, 1.0, 0), -0.9)]


@pytest.fixture
def graph():
    g = Graph()
    yield g
    g.close()


def test_contacts_are_latched_on_the_graph_and_calibrated_there(graph, tmp_path):
    from tolerance_ros.nodes.accuracy_monitor import AccuracyMonitor
    ns = f"/t{uuid.uuid4().hex[:8]}"
    model = URDFChain(URDF)
    dx = as_built_errors(np.array([1e-4 if k == "length" else 5e-4 for k in model.param_kinds]), 2)
    graph.start(AccuracyMonitor, ns, robot=str(URDF), log_dir=str(tmp_path), measurement="point")
    feeder = graph.node("cell", ns)
    js = feeder.create_publisher(JointState, "joint_states", MEASUREMENT_QOS)
    contact = feeder.create_publisher(String, "tolerance/contact", SERVICE_REQUEST_QOS)
    request = feeder.create_publisher(String, "tolerance/calibrate/request", SERVICE_REQUEST_QOS)
    results, answers, calibrations = [], [], []
    feeder.create_subscription(String, "tolerance/contact/result", lambda m: results.append(json.loads(m.data)), 10)
    feeder.create_subscription(String, "tolerance/calibrate/response", lambda m: answers.append(json.loads(m.data)),
                               10)
    feeder.create_subscription(String, "tolerance_calibration", lambda m: calibrations.append(m.data), LATCHED_QOS)
    now = {"q": None}

    def publish_state():
        if now["q"] is not None:
            msg = JointState(name=list(model.joint_names), position=[float(v) for v in now["q"]])
            msg.header.stamp = feeder.get_clock().now().to_msg()
            js.publish(msg)
    feeder.create_timer(0.02, publish_state)
    assert wait_for(lambda: contact.get_subscription_count() > 0 and request.get_subscription_count() > 0, 30)
    bad = len(results)
    contact.publish(String(data='{"contact": "line:x", "targets": ["A"]}'))
    assert wait_for(lambda: len(results) > bad, 10)
    assert results[-1]["ok"] is False and results[-1]["error"] in ("invalid_request", "no_joint_state", "not_ready")
    latched = 0
    for c, (name, normal, d) in enumerate(PLANES):
        for i, q in enumerate(touch(model, dx, [0.012, -0.006, 0.11], "plane", (np.array(normal), d), 20,
                                    seed=[7, c], noise=1e-5)):
            now["q"] = q
            time.sleep(0.2)            # ten joint states of this posture reach the monitor before the request
            rid = f"{name}{i}"
            contact.publish(String(data=json.dumps({"id": rid, "contact": f"plane:{name}", "targets":
                                                    {"A": [0.0, 0.0, 0.1]}, "session": "s1", "pose": rid})))
            assert wait_for(lambda: any(r.get("id") == rid for r in results), 10, 0.02), rid
            answer = next(r for r in results if r.get("id") == rid)
            assert answer["ok"] and np.allclose(answer["joints"], q), answer
            latched += 1
    request.publish(String(data=json.dumps({"id": "c1", "log": "current", "folds": 5})))
    assert wait_for(lambda: any(a.get("id") == "c1" and a.get("status") == "done" for a in answers), 180, 0.2)
    done = next(a for a in answers if a.get("id") == "c1" and a.get("status") == "done")
    assert done["success"] and done["validation"]["after"]["contact_rms_m"] < 3e-5 < 2e-4 < \
        done["validation"]["before"]["contact_rms_m"]
    assert done["measurements"] == latched == 60 and not done["rejected"]
    assert wait_for(lambda: calibrations, 10) and "registration" in calibrations[-1]
