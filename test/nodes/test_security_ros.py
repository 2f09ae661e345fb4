"""SROS2 on a real graph (ROS 2 Jazzy, Cyclone DDS with its security plugins, sros2's `ros2 security`):

- the shipped policy grants each node exactly its own topics (checked against the live nodes, no security);
- a keystore from `tolerance-ros keystore`, the loop's nodes in processes of their own, each in its enclave,
  security enforced: nodes outside the keystore (no security; another keystore's CA) cannot join, a node in
  another enclave cannot publish tolerance_calibration, tolerance_budget or a calibrate request, and none of
  their attempts changes the compensation; the operator's calibrate request closes the loop.
Skipped, with the reason, where rclpy, sros2 or Cyclone's security plugins are missing."""
import fnmatch
import importlib.util
import json
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
import uuid
from pathlib import Path

import numpy as np
import pytest

rclpy = pytest.importorskip("rclpy", reason="ROS 2 Jazzy is not sourced (rclpy not importable)")

from std_msgs.msg import String  # noqa: E402

from helpers import private_domain_id  # noqa: E402
from ros_graph import Graph, wait_for  # noqa: E402
from tolerance_ros.core.models import load_robot  # noqa: E402
from tolerance_ros.services.security import enclave, grants, policy_path, specialise  # noqa: E402

GAO = load_robot("gao2023_7dof")
BASE = [1.5, 0.2, 0.0, 0.0, 0.0, 0.5]


def _plugins() -> bool:
    dirs = os.environ.get("LD_LIBRARY_PATH", "").split(os.pathsep)
    return any((Path(d) / "libdds_security_ac.so").exists() for d in dirs if d)


SECURE = shutil.which("ros2") is not None and importlib.util.find_spec("sros2") is not None and _plugins()
needs_sros2 = pytest.mark.skipif(not SECURE, reason="sros2 (ros2 security) or Cyclone DDS's security plugins "
                                                    "(libdds_security_ac.so) are not installed")


# ------------------------------------------------------------------ the policy against the live nodes

# Grants the nodes use only with some parameters (robot: robot_description; measurement: point; targets;
# use_sim_time; --managed) or never subscribe though they may (/parameter_events).
CONDITIONAL = {"robot_description", "measured_point", "measured_point/*", "measured_pose/*", "/clock",
               "/parameter_events", "~/transition_event"}
LIFECYCLE = {"change_state", "get_available_states", "get_available_transitions", "get_state", "get_transition_graph"}


def test_the_policy_grants_each_node_exactly_the_topics_it_uses(tmp_path):
    from tolerance_ros.nodes.accuracy_monitor import AccuracyMonitor
    from tolerance_ros.nodes.error_model_server import ErrorModelServer
    from tolerance_ros.nodes.joint_state_source import JointStateSource
    from tolerance_ros.nodes.lifecycle import managed
    from tolerance_ros.nodes.simulated_tracker import SimulatedTrackerNode
    from tolerance_ros.nodes.tolerance_allocator import ToleranceAllocator
    from tolerance_ros.nodes.trajectory_compensator import TrajectoryCompensator
    ns = f"/p{uuid.uuid4().hex[:8]}"
    text = specialise(policy_path().read_text(), ns)
    g = Graph()
    try:
        started = {"tolerance_accuracy_monitor": (AccuracyMonitor, {"log_dir": str(tmp_path)}),
                   "tolerance_error_model": (ErrorModelServer, {}),
                   "tolerance_allocator": (ToleranceAllocator, {"budget_dir": str(tmp_path)}),
                   "tolerance_simulated_tracker": (SimulatedTrackerNode, {}),
                   "tolerance_joint_state_source": (JointStateSource, {"compensated": True}),
                   "tolerance_trajectory_compensator": (managed(TrajectoryCompensator), {})}
        for cls, params in started.values():
            g.start(cls, ns, **params)
        for node in g.nodes:
            if hasattr(node, "trigger_configure"):
                node.trigger_configure()
        probe = g.node("probe", ns)
        time.sleep(2.0)
        for name in started:
            granted = grants(text, enclave(ns, name))
            nodes = [name] + (["tolerance_error_model_joint_states"] if name == "tolerance_error_model" else [])
            live = {"publish": set(), "subscribe": set(), "reply": set()}
            for n in nodes:
                live["publish"] |= {t for t, _ in probe.get_publisher_names_and_types_by_node(n, ns)}
                live["subscribe"] |= {t for t, _ in probe.get_subscriber_names_and_types_by_node(n, ns)}
                live["reply"] |= {t for t, _ in probe.get_service_names_and_types_by_node(n, ns)}
            for kind in live:
                missing = [t for t in live[kind] if not any(fnmatch.fnmatchcase(t, g_) for g_ in granted[kind])]
                assert not missing, (name, kind, missing)                 # everything it uses is granted
            optional = {f"{ns}/{c}" if not c.startswith(("/", "~")) else c.replace("~", f"{ns}/{name}") for c in CONDITIONAL}
            optional |= {f"{ns}/{name}/{s}" for s in LIFECYCLE}
            for kind in ("publish", "subscribe", "reply"):
                unused = sorted(granted[kind] - live[kind] - optional)
                assert not unused, (name, kind, unused)                   # and nothing else
            assert not granted["request"]
    finally:
        g.close()


# ------------------------------------------------------------------ the loop with security enforced

SUITE = (("tolerance_accuracy_monitor", "accuracy_monitor"), ("tolerance_simulated_tracker", "simulated_tracker"),
         ("tolerance_trajectory_compensator", "trajectory_compensator"),
         ("tolerance_joint_state_source", "joint_state_source"))

ROGUE = r"""
import json, sys, time, rclpy
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import String
ns, calibration, name = sys.argv[1], open(sys.argv[2]).read(), sys.argv[3]
latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
try:
    rclpy.init()
    node = rclpy.create_node(name, namespace=ns)
except Exception as exc:
    print(json.dumps({"joined": False, "error": f"{type(exc).__name__}: {exc}"[:300]}), flush=True)
    sys.exit(0)
out, pubs = {"joined": True}, {}
for topic, text in (("tolerance_calibration", calibration), ("tolerance_budget", '{"robot": "gao2023_7dof"}'),
                    ("tolerance/calibrate/request", '{"id": "rogue", "log": "current"}')):
    try:
        pubs[topic] = (node.create_publisher(String, topic, latched), text)
        out[topic] = "created"
    except Exception as exc:
        out[topic] = f"refused: {type(exc).__name__}"
for _ in range(30):
    for pub, text in pubs.values():
        pub.publish(String(data=text))
    time.sleep(0.1)
out["sees"] = sorted(n for n, _ in node.get_node_names_and_namespaces())
print(json.dumps(out), flush=True)
"""


def _env(base, domain, keystore, enclave_path):
    env = dict(base, ROS_DOMAIN_ID=str(domain))
    for k in ("ROS_SECURITY_KEYSTORE", "ROS_SECURITY_ENABLE", "ROS_SECURITY_STRATEGY", "ROS_SECURITY_ENCLAVE_OVERRIDE"):
        env.pop(k, None)
    if keystore is not None:
        env.update(ROS_SECURITY_KEYSTORE=str(keystore), ROS_SECURITY_ENABLE="true", ROS_SECURITY_STRATEGY="Enforce",
                   ROS_SECURITY_ENCLAVE_OVERRIDE=enclave_path)
    return env


class Operator:
    """The test's own participant, in the operator's enclave: an rclpy context spun in a thread."""

    def __init__(self, domain, keystore, ns):
        saved = dict(os.environ)
        os.environ.update(_env({}, domain, keystore, enclave(ns, "tolerance_operator")))
        try:
            self.context = rclpy.Context()
            rclpy.init(context=self.context, domain_id=domain)
            self.node = rclpy.create_node("tolerance_client_security_test", namespace=ns, context=self.context)
        finally:
            os.environ.clear()
            os.environ.update(saved)
        from rclpy.executors import SingleThreadedExecutor
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._spin, daemon=True)
        self.thread.start()

    def _spin(self):
        while not self.stop.is_set() and self.context.ok():
            self.executor.spin_once(timeout_sec=0.05)

    def collect(self, msg_type, topic, qos=10, raw=False):
        got = []
        self.node.create_subscription(msg_type, topic, got.append, qos, raw=raw)
        return got

    def close(self):
        self.stop.set()
        self.thread.join(timeout=5)
        self.executor.shutdown(timeout_sec=5)
        self.node.destroy_node()
        rclpy.shutdown(context=self.context)


@pytest.fixture(scope="module")
def secure(tmp_path_factory):
    """The loop's four nodes in processes of their own, each in its enclave of a keystore made by
    `tolerance-ros keystore`, security enforced; the operator in the test's process."""
    if not SECURE:
        pytest.skip("sros2 (ros2 security) or Cyclone DDS's security plugins are not installed")
    import yaml
    from tolerance_ros.core.calibration.planning import campaign_dict, plan
    tmp = tmp_path_factory.mktemp("secure")
    ns, domain = f"/s{uuid.uuid4().hex[:8]}", private_domain_id(20, 60)
    ks = tmp / "keystore"
    t0 = time.monotonic()
    made = subprocess.run([sys.executable, "-m", "tolerance_ros.cli", "keystore", "--out", str(ks), "--namespace", ns,
                           "--domain-id", str(domain), "--quiet", "--json"], capture_output=True, text=True, timeout=180,
                          env=dict(os.environ, ROS_DOMAIN_ID=str(domain)))
    assert made.returncode == 0, made.stderr
    keystore_s = time.monotonic() - t0
    planned = plan(GAO, 24, "observability", candidates=500, seed=3).q
    (tmp / "planned.yaml").write_text(yaml.safe_dump(campaign_dict(GAO, planned, "planned", 1)))
    params = {"accuracy_monitor": {"tracker_to_base": BASE, "log_dir": str(tmp / "logs"), "report_period": 0.3,
                                   "slop": 0.005},
              "simulated_tracker": {"tracker_to_base": BASE, "measure_every": 3, "seed": 4},
              "trajectory_compensator": {"report_period": 0.3},
              "joint_state_source": {"mode": "campaign", "campaign": str(tmp / "planned.yaml"), "dwell": 0.25,
                                     "loop": True, "compensated": True}}
    procs = []
    for name, module in SUITE:
        argv = [sys.executable, "-m", f"tolerance_ros.nodes.{module}", "--ros-args", "-r", f"__ns:={ns}"]
        for k, v in params[module].items():
            argv += ["-p", f"{k}:={json.dumps(v) if isinstance(v, (list, bool)) else v}"]
        log = open(tmp / f"{module}.log", "w")
        procs.append((subprocess.Popen(argv, env=_env(os.environ, domain, ks, enclave(ns, name)), stdout=log,
                                       stderr=subprocess.STDOUT, start_new_session=True), log))
    operator = Operator(domain, ks, ns)
    state = {"ns": ns, "domain": domain, "keystore": ks, "tmp": tmp, "planned": planned, "operator": operator,
             "keystore_s": keystore_s, "procs": procs}
    try:
        yield state
    finally:
        operator.close()
        for p, log in procs:
            os.killpg(p.pid, signal.SIGINT)
        for p, log in procs:
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                os.killpg(p.pid, signal.SIGKILL)
            log.close()
        for _, module in SUITE:
            text = (tmp / f"{module}.log").read_text()
            assert "Traceback" not in text, text[-3000:]


def _rogue(secure, calibration_file, keystore=None, enclave_path=None, name="rogue", timeout=60):
    out = subprocess.run([sys.executable, "-c", ROGUE, secure["ns"], str(calibration_file), name], capture_output=True,
                         text=True, timeout=timeout, env=_env(os.environ, secure["domain"], keystore, enclave_path))
    lines = [ln for ln in out.stdout.splitlines() if ln.startswith("{")]
    assert lines, out.stderr[-2000:]
    return json.loads(lines[-1])


def _rogue_calibration(tmp):
    """A calibration made elsewhere: the robot built within gao2023_delta2, and 50 mrad more on joint 2."""
    from tolerance_ros.core.accuracy.simulate import as_built_errors, measure
    from tolerance_ros.core.budget import load_budget
    from tolerance_ros.core.calibration.calibrate import calibrate
    from tolerance_ros.core.calibration.calibration_file import SI, calibration_text
    q = GAO.sample_joints(30, 6)
    cal = calibrate(GAO, q, measure(GAO, q, as_built_errors(load_budget("gao2023_delta2", GAO).vector_for(GAO), 1),
                                    1e-5, 0.0, None, seed=2), folds=3)
    cal.dx = cal.dx.copy()
    cal.dx[list(GAO.param_names).index("theta2")] += 0.05
    path = tmp / "rogue_calibration.yaml"
    path.write_text(calibration_text(cal, SI))
    return path


def _compensation(operator):
    """(planned, sent) lists the operator sees on joint_trajectory_in and joint_trajectory."""
    from trajectory_msgs.msg import JointTrajectory
    return operator.collect(JointTrajectory, "joint_trajectory_in"), operator.collect(JointTrajectory, "joint_trajectory")


def _largest_change(planned, sent, since=0):
    """Largest |sent - planned| over the one-point trajectories received after index ``since`` (paired in order)."""
    plan = {tuple(np.round(m.points[0].positions, 12)) for m in planned}
    assert plan
    changes = []
    for m in sent[since:]:
        q = np.array(m.points[0].positions)
        changes.append(min(np.abs(q - np.array(p)).max() for p in plan))
    return max(changes) if changes else None


@needs_sros2
def test_nodes_outside_the_keystore_or_in_another_enclave_change_nothing(secure):
    """No security at all, another keystore's CA, and the simulated tracker's enclave (a suite node that has no
    grant for them) each try to put a 50 mrad calibration in force, a budget and a calibrate request."""
    from diagnostic_msgs.msg import DiagnosticArray
    op, ns = secure["operator"], secure["ns"]
    planned, sent = _compensation(op)
    diags = op.collect(DiagnosticArray, "/diagnostics")
    assert wait_for(lambda: len(sent) >= 5, 90), "the secure loop did not start: " + \
        (secure["tmp"] / "trajectory_compensator.log").read_text()[-2000:]
    t0 = time.monotonic()
    rogue_file = _rogue_calibration(secure["tmp"])
    other = secure["tmp"] / "other_keystore"
    for argv in (["create_keystore", str(other)], ["create_enclave", str(other), "/intruder"]):
        subprocess.run(["ros2", "security", *argv], check=True, capture_output=True, timeout=60,
                       env=dict(os.environ, ROS_DOMAIN_ID=str(secure["domain"])))
    n0 = len(sent)
    unsecured = _rogue(secure, rogue_file)
    foreign_ca = _rogue(secure, rogue_file, other, "/intruder")
    inside = _rogue(secure, rogue_file, secure["keystore"], enclave(ns, "tolerance_simulated_tracker"),
                    "tolerance_simulated_tracker")                  # the tracker's process, taken over
    # outside the keystore: they publish, but no node of the suite is seen or sees them
    for r in (unsecured, foreign_ca):
        assert r["joined"] and r["tolerance_calibration"] == "created" and "tolerance_trajectory_compensator" not in r["sees"]
    # in another enclave: the middleware refuses the publishers themselves
    assert inside["joined"] and "tolerance_trajectory_compensator" in inside["sees"], inside
    for topic in ("tolerance_calibration", "tolerance_budget", "tolerance/calibrate/request"):
        assert inside[topic].startswith("refused"), inside
    assert wait_for(lambda: len(sent) >= n0 + 8, 30)
    assert _largest_change(planned, sent, n0) < 1e-12                # still passed through: no calibration in force
    name = f"{ns}/tolerance_ros: trajectory compensator"
    values = [{kv.key: kv.value for kv in s.values} for d in diags for s in d.status if s.name == name]
    assert values and values[-1]["calibration_sha256"] == "none" and values[-1]["calibrations_refused"] == "0"
    print(f"keystore made in {secure['keystore_s']:.1f} s; rogues tried and checked in {time.monotonic() - t0:.1f} s")


@needs_sros2
def test_with_security_enforced_the_operators_calibrate_request_closes_the_loop(secure):
    op, ns = secure["operator"], secure["ns"]
    planned, sent = _compensation(op)
    reports, answers = op.collect(String, "tolerance/accuracy_report"), op.collect(String, "tolerance/calibrate/response")
    request = op.node.create_publisher(String, "tolerance/calibrate/request", 10)

    def report():
        return json.loads(reports[-1].data) if reports else {"counts": {"paired": 0}}
    assert wait_for(lambda: report()["counts"]["paired"] >= 2 * 24 * 2, 120), report()
    before = report()["summary"]["position_error_m"]["mean"]
    assert wait_for(lambda: request.get_subscription_count() > 0, 20)
    request.publish(String(data=json.dumps({"id": "secure-k1", "log": "current", "registration": "base",
                                            "noise": 1e-5})))
    assert wait_for(lambda: any(json.loads(a.data).get("status") == "done" for a in answers), 120)
    done = next(json.loads(a.data) for a in answers if json.loads(a.data).get("status") == "done")
    assert done["success"] and done["provenance"]["made_by"] == f"{ns}/tolerance_accuracy_monitor", done
    assert wait_for(lambda: (report().get("calibration") or {}).get("sha256") == done["provenance"]["content_sha256"]
                    and report()["summary"]["measurements"] >= 40, 60)
    after = report()["summary"]["position_error_m"]["mean"]
    assert after <= 0.1 * before, (before, after)
    n0 = len(sent)
    assert wait_for(lambda: len(sent) >= n0 + 5, 30)
    assert 1e-5 < _largest_change(planned, sent, n0) < 0.02            # compensated now, within the envelope
