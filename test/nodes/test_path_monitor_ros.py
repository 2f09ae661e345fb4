"""The accuracy monitor's path figures over a real ROS 2 graph (skipped without rclpy): joint states and a
tracker's points of a simulated rectangle published as they would arrive, a report on tolerance/path_report
when each motion ends, and the path monitor's status on /diagnostics."""
import json
import time
import uuid

import numpy as np
import pytest

rclpy = pytest.importorskip("rclpy", reason="ROS 2 Jazzy is not sourced (rclpy not importable)")

from builtin_interfaces.msg import Time  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from geometry_msgs.msg import PointStamped  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_msgs.msg import String  # noqa: E402

from path_runs import T_TB, run  # noqa: E402
from ros_graph import Graph, wait_for  # noqa: E402
from tolerance_ros.core.geometry import rpy_from_matrix  # noqa: E402
from tolerance_ros.core.models import load_robot  # noqa: E402
from tolerance_ros.nodes.common import MEASUREMENT_QOS, STATUS_QOS  # noqa: E402


def _stamp(t):
    return Time(sec=int(t), nanosec=int(round((t - int(t)) * 1e9)) % 1_000_000_000)


def _feed(g, monitor, ns, gao, st, reports, diags, twice=False, shift=None):
    """Publish the run ``st`` as a robot and a tracker would, in real time (never more than 0.2 s ahead of the
    monitor: a loaded test machine starves its executor, and DDS's keep-last would then drop what it holds);
    each joint state ``twice`` with one stamp; ``shift(t)`` (s) added to both streams' stamps. Returns the
    (joint states, points) published."""
    def taken():
        """(joint states, points) the monitor's path monitor has taken so far, judged, queued or left out."""
        path = monitor.path
        if path is None:
            return 0, 0
        left = {kind: sum(path.live[kind].counts.values()) - path.live[kind].counts["jumps"] for kind in path.live}
        return (path.counts["joint_states"] + len(path.queued["joints"][0]) + left["joints"],
                path.counts["points"] + len(path.queued["points"][0]) + left["points"])
    node = g.node(f"feeder_{uuid.uuid4().hex[:6]}", ns)
    node.create_subscription(String, "tolerance/path_report", reports.append, STATUS_QOS)
    node.create_subscription(DiagnosticArray, "/diagnostics", diags.append, 10)
    js = node.create_publisher(JointState, "joint_states", MEASUREMENT_QOS)
    pts = node.create_publisher(PointStamped, "measured_point", MEASUREMENT_QOS)
    assert wait_for(lambda: js.get_subscription_count() and pts.get_subscription_count(), 20)
    shift = shift or (lambda t: 0.0)
    copies = 2 if twice else 1
    k, start = 0, time.monotonic()
    for i, (t, q) in enumerate(zip(st.joint_stamps, st.joints)):
        if i % 100 == 0 and i:
            t0 = time.monotonic()
            assert wait_for(lambda: taken()[0] >= copies * (i - 100) and taken()[1] >= k - 200, 30), (i, k, taken())
            start += time.monotonic() - t0
        time.sleep(max(0.0, (t - st.joint_stamps[0]) - (time.monotonic() - start)))
        m = JointState(name=list(gao.joint_names), position=[float(v) for v in q])
        m.header.stamp = _stamp(t + shift(t))
        for _ in range(copies):
            js.publish(m)
        while k < len(st.stamps) and st.stamps[k] <= t:
            p = PointStamped()
            p.header.stamp = _stamp(st.stamps[k] + shift(st.stamps[k]))
            p.point.x, p.point.y, p.point.z = (float(v) for v in st.points[k])
            pts.publish(p)
            k += 1
    assert wait_for(lambda: taken() == (copies * len(st.joint_stamps), k), 20), (taken(), k)   # nothing lost
    return copies * len(st.joint_stamps), k


def _start(tmp_path, ns):
    from tolerance_ros.nodes.accuracy_monitor import AccuracyMonitor
    base = [float(v) for v in np.concatenate([T_TB[:3, 3], rpy_from_matrix(T_TB[None, :3, :3])[0]])]
    g = Graph()
    monitor = g.start(AccuracyMonitor, ns, measurement="point", tracker_to_base=base, log_dir=str(tmp_path),
                      path_latency="8ms", report_period=0.3)
    return g, monitor


def test_path_report_topic_and_diagnostics(tmp_path):
    gao = load_robot("gao2023_7dof")
    st = run(gao, "rectangle", cycles=2)
    ns = f"/t{uuid.uuid4().hex[:8]}"
    g, monitor = _start(tmp_path, ns)
    try:
        reports, diags = [], []
        _feed(g, monitor, ns, gao, st, reports, diags)
        assert wait_for(lambda: len(reports) >= 2, 60)
        doc = json.loads(reports[-1].data)
        counts = monitor.path.counts
        assert doc["cycles"] == 2 and len(doc["segments"]) == 4 and doc["overall"]["AT_p_m"] < 1e-3, counts
        assert doc["stops"]["band_m"] == 1e-4 and doc["stops"]["judged"] == 1   # the stop after the first cycle
        assert counts["rejected"] == 0, monitor.path.reasons
        assert wait_for(lambda: any(s.name.endswith("path monitor") and "AT_p" in s.message
                                    for d in diags for s in d.status), 20)
    finally:
        g.close()


def test_repeated_stamps_and_a_clock_that_starts_again_over_a_real_graph(tmp_path):
    """Every joint state published twice with one stamp, and both clocks set back by 900 s after the second
    cycle (a simulation restarted): the motion under way is reported not judged with why, on the topic; the
    cycles before and after it are judged; the status says what was left out and warns of the jump."""
    gao = load_robot("gao2023_7dof")
    st = run(gao, "rectangle", cycles=4)
    cut = st.joint_stamps[0] + 2 * 4.56 + 0.3
    ns = f"/t{uuid.uuid4().hex[:8]}"
    g, monitor = _start(tmp_path, ns)
    try:
        reports, diags = [], []
        _feed(g, monitor, ns, gao, st, reports, diags, twice=True, shift=lambda t: -900.0 if t >= cut else 0.0)
        assert wait_for(lambda: sum(json.loads(r.data).get("judged") is True for r in reports) >= 3, 60)
        docs = [json.loads(r.data) for r in reports]
        skipped = [d for d in docs if d.get("judged") is False]
        assert skipped and "clock jumped" in skipped[0]["reason"], [d.get("reason") for d in docs]
        live = monitor.path.live["joints"].counts
        assert live["repeated"] > 0.99 * len(st.joint_stamps), (live, monitor.path.gaps["joint_states"].summary())
        assert monitor.path.counts["errors"] == 0 and getattr(monitor, "callback_errors", 0) == 0
        assert wait_for(lambda: any(s.name.endswith("path monitor") and "repeated stamp(s) left out" in s.message
                                    and "the clock jumped" in s.message for d in diags for s in d.status), 20)
    finally:
        g.close()
