"""Hostile messages through the node classes themselves (skipped without rclpy).

Each node runs in a private rclpy context that does not spin: the test calls every subscription
callback (through the node's last-resort wrapper) with generated messages that went through the
middleware's serialisation, as a subscription would deliver them, then the node's timers. What the
nodes publish is recorded after being serialised, as ``publish`` does. Asserted: the last-resort
handler is never needed (``callback_errors`` stays 0), every service answer is strict JSON that
validates against its schema with a documented code and never 'internal', what is published is
finite and well-formed, and the node still serves a valid request afterwards.
"""
import json
import math
from collections import defaultdict

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

rclpy = pytest.importorskip("rclpy", reason="ROS 2 Jazzy is not sourced (rclpy not importable)")

from geometry_msgs.msg import PoseStamped  # noqa: E402
from rclpy.serialization import deserialize_message, serialize_message  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_msgs.msg import String  # noqa: E402
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint  # noqa: E402

from tolerance_ros.testing.fuzz_corpus import (ENCODINGS, ODD_IDS, Q, allocate_request, encode, jacobian_request,  # noqa: E402
                         json_values, scalars, yaml_file)
from helpers import example_urdf  # noqa: E402
from ros_graph import Graph, wait_for  # noqa: E402
from tolerance_ros.testing.schemas import validator  # noqa: E402
from tolerance_ros.core.accuracy.io import read_log  # noqa: E402
from tolerance_ros.core.accuracy.simulate import as_built_errors, measure  # noqa: E402
from tolerance_ros.core.budget import load_budget  # noqa: E402
from tolerance_ros.core.calibration.calibrate import calibrate  # noqa: E402
from tolerance_ros.core.calibration.calibration_file import save_calibration  # noqa: E402
from tolerance_ros.core.jsonio import dumps_fast, loads_strict  # noqa: E402
from tolerance_ros.core.models import load_robot  # noqa: E402
from tolerance_ros.services.contracts import CODES  # noqa: E402

EXAMPLES = 200
FUZZ = settings(max_examples=EXAMPLES, deadline=None, suppress_health_check=list(HealthCheck), database=None)
CALIBRATION_FUZZ = settings(FUZZ, max_examples=60)  # a calibration document is large: each example parses it
JACOBIAN_RESPONSE = validator("compute_error_jacobian.response")
ALLOCATE_RESPONSE = validator("allocate_tolerances.response")
CALIBRATE_RESPONSE = validator("calibrate.response")
GAO = load_robot("gao2023_7dof")
BUDGET = load_budget("gao2023_delta2", GAO)
URDF = example_urdf("ur5_robot.urdf").read_text()


class Harness:
    """A started node whose publishers record what they would send (after serialising it) and whose
    logger keeps the errors it logs; ``call`` runs a subscription callback as the executor would."""

    def __init__(self, node):
        self.node = node
        self.sent = defaultdict(list)
        self.errors = []
        self.prefix = node.get_namespace().rstrip("/") + "/"
        for pub in list(node.publishers):
            pub.publish = self._recorder(pub.topic_name)
        node.get_logger = lambda: self

    def _recorder(self, topic):
        key = topic[len(self.prefix):] if topic.startswith(self.prefix) else topic

        def publish(msg):
            if not isinstance(msg, bytes):
                serialize_message(msg)
            self.sent[key].append(msg)
        return publish

    def error(self, message, **_):
        self.errors.append(message)

    def info(self, message, **_):
        pass

    warning = warn = debug = info

    def subscriptions(self):
        """The node's subscriptions and those of its helper node (the error model's joint states, taken on
        its timer rather than delivered one by one)."""
        helper = getattr(self.node, "joint_state_node", None)
        return list(self.node.subscriptions) + (list(helper.subscriptions) if helper is not None else [])

    def topics(self):
        return sorted(s.topic_name[len(self.prefix):] for s in self.subscriptions())

    def call(self, topic, msg):
        """The subscription callback of ``topic`` (relative to the namespace) with ``msg`` as delivered (bytes
        to a raw subscription: ``msg`` itself when it is bytes); a subscription the node takes from on a timer
        gets ``msg`` as its only waiting message, then the timers run."""
        sub = next(s for s in self.subscriptions() if s.topic_name == self.prefix + topic)
        if sub in self.node.subscriptions:
            raw = msg if isinstance(msg, bytes) else serialize_message(msg)
            sub.callback(raw if sub.raw else deserialize_message(raw, type(msg)))
            self.check()
            return
        waiting = [serialize_message(msg)]
        self.node.latest_joint_state = lambda: waiting.pop() if waiting else None
        self.tick()

    def tick(self):
        """Every timer callback once."""
        for timer in self.node.timers:
            timer.callback()
        self.check()

    def take(self, topic):
        return self.sent.pop(topic, [])

    def check(self):
        """The last-resort handler was not needed (its count restarts, so that one failure is reported once)."""
        needed, self.node.callback_errors = getattr(self.node, "callback_errors", 0), 0
        assert needed == 0, f"the last-resort handler was needed: {self.errors[-1:]}"


def answer(text, response_schema):
    """The parsed answer, after checking it: strict JSON, valid against the schema, a documented code."""
    doc = loads_strict(text)
    response_schema.validate(doc)
    if not doc["ok"]:
        assert doc["error"]["code"] in CODES and doc["error"]["code"] != "internal", doc
    return doc


def ros_text(text):
    """Text as a std_msgs/String carries it: UTF-8, whatever is not UTF-8 arrives replaced."""
    if isinstance(text, str):
        text = text.encode("utf-8", errors="surrogatepass")
    return text.decode("utf-8", errors="replace")


# Hostile message contents.
HOSTILE_FLOATS = [math.nan, math.inf, -math.inf, 1e200, -1e200, 1.7e308, -1.7e308, 5e-324, -0.0, 1e-300]
floats = st.one_of(st.floats(), st.sampled_from(HOSTILE_FLOATS), st.floats(-3.0, 3.0))
stamps = st.one_of(st.tuples(st.integers(0, 3), st.integers(0, 999_999_999)),
                   st.tuples(st.integers(-2 ** 31, 2 ** 31 - 1), st.integers(0, 2 ** 32 - 1)),
                   st.tuples(st.sampled_from([-2 ** 31, -1, 0, 1_700_000_000, 2 ** 31 - 1]),
                             st.sampled_from([0, 999_999_999, 1_000_000_000, 2 ** 32 - 1])))
texts = st.text(max_size=30)
frames = st.one_of(texts, st.just("f" * 100_000))


def stamped(msg, stamp, frame=""):
    msg.header.stamp.sec, msg.header.stamp.nanosec = stamp
    msg.header.frame_id = frame
    return msg


@st.composite
def joint_states(draw, joint_names=GAO.joint_names):
    names = list(joint_names)
    name = draw(st.one_of(st.just(names), st.permutations(names), st.lists(st.sampled_from(names + ["x", ""]),
                                                                           max_size=12),
                          st.lists(texts, max_size=12), st.just(names * 3), st.just([]), st.just(["x" * 2000] * 200)))
    position = draw(st.one_of(st.lists(floats, min_size=len(name), max_size=len(name)), st.lists(floats, max_size=14),
                              st.lists(st.floats(-3.0, 3.0), min_size=len(names), max_size=len(names)),
                              st.integers(0, 3000).map(lambda n: [0.1] * n)))
    msg = JointState(name=name, position=position, velocity=draw(st.lists(floats, max_size=3)),
                     effort=draw(st.lists(floats, max_size=3)))
    return stamped(msg, draw(stamps), draw(frames))


@st.composite
def poses(draw):
    tip = GAO.fk(np.array([Q]))[0, :3, 3]
    position = draw(st.one_of(st.tuples(floats, floats, floats),
                              st.tuples(*(st.floats(v - 1e-3, v + 1e-3) for v in tip))))
    quaternion = draw(st.one_of(st.tuples(floats, floats, floats, floats), st.just((0.0, 0.0, 0.0, 0.0)),
                                st.just((0.0, 0.0, 0.0, 1.0)), st.just((1e-300, 0.0, 0.0, 0.0))))
    msg = PoseStamped()
    p, o = msg.pose.position, msg.pose.orientation
    p.x, p.y, p.z = position
    o.x, o.y, o.z, o.w = quaternion
    return stamped(msg, draw(stamps), draw(frames))


NUMBER_STRINGS = ["pi/2", "1e-5", "1+" * 30000 + "1", "-" * 100000 + "1", "(" * 99 + "1" + ")" * 99, "1" + "0" * 400,
                  "1e308*10", "pi/0", "__import__('os')", "1\x00"]


def budget_doc():
    return {"robot": GAO.name, "budget": BUDGET.to_dict()}


@st.composite
def budget_texts(draw):
    doc = budget_doc()
    inner = doc["budget"]
    mutation = draw(st.sampled_from(["none", "value", "key", "tolerance", "robot", "whole"]))
    if mutation == "value":
        inner[draw(st.sampled_from(sorted(inner)))] = draw(json_values())
    elif mutation == "key":
        inner[draw(texts)] = draw(json_values())
    elif mutation == "tolerance":
        inner["tolerances"][draw(st.sampled_from(sorted(inner["tolerances"]) + ["zz"]))] = draw(
            st.one_of(floats, json_values(), st.sampled_from(NUMBER_STRINGS)))
    elif mutation == "robot":
        doc["robot"] = draw(st.one_of(texts, json_values()))
    elif mutation == "whole":
        doc = draw(json_values())
    return ros_text(encode(doc, draw(st.sampled_from(ENCODINGS))))


def request_texts(requests):
    return st.tuples(requests, st.sampled_from(ENCODINGS)).map(lambda r: ros_text(encode(*r)))


def numbers_text(values, size):
    return st.lists(values, min_size=size, max_size=size).map(lambda v: " ".join(map(repr, v)))


HOSTILE_VECTOR = st.one_of(numbers_text(floats, 3), st.sampled_from(["0 0 0", "1 0", "a b c", "", "1e999 0 0",
                                                                     "nan nan nan", "1e300 1e300 1e300"]))
HOSTILE_NUMBER = st.one_of(floats.map(repr),
                           st.sampled_from(["nan", "inf", "1e999", "x", "", "1 2", "1e308", "-1e308"]))


@st.composite
def urdf_texts(draw):
    """robot_description text: a generated serial chain with hostile joints, mutated; or not a URDF."""
    kind = draw(st.sampled_from(["chain"] * 6 + ["mutated", "entities", "deep", "path", "junk"]))
    if kind == "path":
        return draw(st.sampled_from(["/etc/passwd", "/proc/self/status", "/dev/zero", "x" * 5000, "~", ".",
                                     str(example_urdf("ur5_robot.urdf")), "robot.urdf", " \n"]))
    if kind == "junk":
        return draw(st.one_of(texts, st.just(json.dumps(budget_doc())), st.just("<" * 1000)))
    if kind == "deep":
        n = draw(st.sampled_from([100, 10_000, 200_000]))
        return "<robot name='deep'>" + "<link name='a'>" * n + "</link>" * n + "</robot>"
    if kind == "entities":
        return ('<?xml version="1.0"?><!DOCTYPE r [<!ENTITY a "aaaaaaaaaa">' +
                "".join(f'<!ENTITY {c} "{("&" + p + ";") * 10}">' for p, c in zip("abcdefgh", "bcdefghi")) +
                ']><robot name="&i;"><link name="l0"/></robot>')
    n = draw(st.integers(1, 8))
    links = [f"l{k}" for k in range(n)] + ["tool0"]  # the nodes are told tip_link tool0
    rate = draw(st.sampled_from([0, 0, 2, 10, 30]))  # percent of hostile parts: many robots load, then meet the math

    def mostly(valid, hostile):
        return draw(hostile if draw(st.integers(0, 99)) < rate else valid)

    name = mostly(st.just("r"), st.sampled_from(["", "ü" * 3, "x" * 300, "&amp;"]))
    parts = [f'<robot name="{name}">'] + [f'<link name="{link}"/>' for link in links]
    for k in range(n):
        jtype = mostly(st.sampled_from(["revolute", "continuous", "prismatic"]),
                       st.sampled_from(["fixed", "floating", "planar", "screw", ""]))
        parent = mostly(st.just(links[k]), st.sampled_from([links[-1], "missing", links[k + 1]]))
        joint = mostly(st.just(f"j{k}"), st.just("j0"))
        xyz = mostly(numbers_text(st.floats(-1, 1), 3), HOSTILE_VECTOR)
        rpy = mostly(numbers_text(st.floats(-3.2, 3.2), 3), HOSTILE_VECTOR)
        axis = mostly(st.sampled_from(["0 0 1", "1 0 0", "0 1 0", "0.6 0 0.8"]), HOSTILE_VECTOR)
        lower = mostly(st.floats(-3, 0).map(repr), HOSTILE_NUMBER)
        upper = mostly(st.floats(0, 3).map(repr), HOSTILE_NUMBER)
        mimic = mostly(st.just(""), st.just('<mimic joint="j0"/>'))
        parts.append(f'<joint name="{joint}" type="{jtype}"><parent link="{parent}"/><child link="{links[k + 1]}"/>'
                     f'<origin xyz="{xyz}" rpy="{rpy}"/><axis xyz="{axis}"/>'
                     f'<limit lower="{lower}" upper="{upper}" effort="1" velocity="1"/>{mimic}</joint>')
    text = "".join(parts) + "</robot>"
    if kind == "mutated":
        cut = draw(st.integers(0, len(text)))
        text = draw(st.sampled_from([text[:cut], text + "<extra/>", text + "&undefined;", text.replace("<", "< ", 1),
                                     text[:cut] + "\x00" + text[cut:]]))
    return text


# The nodes, started once per module in a context that does not spin.
@pytest.fixture(scope="module")
def graph():
    g = Graph(spin=False)
    yield g
    g.close()


@pytest.fixture(scope="module")
def error_model(graph):
    from tolerance_ros.nodes.error_model_server import ErrorModelServer
    return Harness(graph.start(ErrorModelServer, "/fuzz_error_model"))


@pytest.fixture(scope="module")
def allocator(graph, tmp_path_factory):
    from tolerance_ros.nodes.tolerance_allocator import ToleranceAllocator
    return Harness(graph.start(ToleranceAllocator, "/fuzz_allocator", max_queue=2, max_time_limit=5.0,
                               budget_dir=str(tmp_path_factory.mktemp("budgets"))))


@pytest.fixture(scope="module")
def monitor(graph, tmp_path_factory):
    from tolerance_ros.nodes.accuracy_monitor import AccuracyMonitor
    return Harness(graph.start(AccuracyMonitor, "/fuzz_monitor", budget="gao2023_delta2", campaign="gao2023_iso_cube",
                               log_dir=str(tmp_path_factory.mktemp("campaigns"))))


@pytest.fixture(scope="module")
def tracker(graph):
    from tolerance_ros.nodes.simulated_tracker import SimulatedTrackerNode
    return Harness(graph.start(SimulatedTrackerNode, "/fuzz_tracker"))


@pytest.fixture(scope="module")
def source(graph):
    from tolerance_ros.nodes.joint_state_source import JointStateSource
    return Harness(graph.start(JointStateSource, "/fuzz_source"))


def test_every_subscription_is_fuzzed(error_model, allocator, monitor, tracker, source, compensator,
                                     compensated_source):
    """The callbacks fuzzed below are all the node classes subscribe to (robot_description further down)."""
    assert error_model.topics() == ["joint_states", "tolerance/compute_error_jacobian/request", "tolerance_budget",
                                    "tolerance_calibration"]
    assert allocator.topics() == ["tolerance/allocate_tolerances/request"]
    assert monitor.topics() == ["joint_states", "measured_pose", "tolerance/calibrate/request", "tolerance/contact",
                                "tolerance_budget", "tolerance_calibration"]
    assert tracker.topics() == ["joint_states"]
    assert source.topics() == []
    assert compensator.topics() == ["joint_trajectory_in", "tolerance_calibration"]
    assert compensated_source.topics() == ["joint_trajectory"]


# Error-model server.
@FUZZ
@given(text=request_texts(jacobian_request()))
def test_error_model_answers_every_request(error_model, text):
    error_model.call("tolerance/compute_error_jacobian/request", String(data=text))
    answers = error_model.take("tolerance/compute_error_jacobian/response")
    assert len(answers) == 1
    answer(answers[0].data, JACOBIAN_RESPONSE)


@FUZZ
@given(text=budget_texts())
def test_error_model_takes_or_ignores_every_budget(error_model, text):
    error_model.call("tolerance_budget", String(data=text))
    budget = error_model.node.service.current_budget
    assert budget is None or np.all(np.isfinite(budget.vector_for(GAO)))


@FUZZ
@given(msg=joint_states())
def test_error_model_bounds_every_joint_state(error_model, msg):
    error_model.call("tolerance_budget", String(data=dumps_fast(budget_doc())))
    error_model.call("joint_states", msg)
    for out in error_model.take("tolerance/predicted_bound"):
        bound = loads_strict(out.data)
        assert bound["position_bound_m"] >= 0 and bound["orientation_bound_rad"] >= 0
        assert math.isfinite(bound["stamp"])


def test_error_model_serves_after_the_fuzz(error_model):
    error_model.call("tolerance_budget", String(data=dumps_fast(budget_doc())))
    request = {"id": "after", "joints": [Q, Q], "tolerances": "current", "criteria": ["paper"]}
    error_model.call("tolerance/compute_error_jacobian/request", String(data=json.dumps(request)))
    doc = answer(error_model.take("tolerance/compute_error_jacobian/response")[-1].data, JACOBIAN_RESPONSE)
    assert doc["ok"] and doc["id"] == "after" and doc["n"] == 2 and 0 < doc["bounds"]["position"]["paper"][0] < 1.4e-3
    state = JointState(name=list(GAO.joint_names), position=list(Q))
    state.header.stamp.sec = 12
    error_model.call("joint_states", state)
    bound = loads_strict(error_model.take("tolerance/predicted_bound")[-1].data)
    assert bound["stamp"] == 12.0 and bound["position_bound_m"] == pytest.approx(doc["bounds"]["position"]["paper"][0])


# Allocator.
def allocator_answers(allocator):
    """The service answers published so far (each checked), with progress and budget messages checked too."""
    allocator.tick()
    for msg in allocator.take("tolerance/allocate_tolerances/progress"):
        progress = loads_strict(msg.data)
        assert 0.0 <= progress["fraction"] <= 1.0
    for msg in allocator.take("tolerance_budget"):
        assert loads_strict(msg.data)["budget"]["robot"] == GAO.name
    return [answer(m.data, ALLOCATE_RESPONSE) for m in allocator.take("tolerance/allocate_tolerances/response")]


@FUZZ
@given(request=allocate_request(), how=st.sampled_from(ENCODINGS))
def test_allocator_answers_every_request(allocator, request, how):
    """Every request is answered at once (a cancel of a running job when it has stopped); an accepted
    allocation is cancelled again, so that solves do not pile up."""
    allocator.call("tolerance/allocate_tolerances/request", String(data=ros_text(encode(request, how))))
    answers = allocator_answers(allocator)
    if request.get("command") != "cancel":
        assert answers
    for accepted in [a for a in answers if a.get("status") == "accepted"]:
        allocator.call("tolerance/allocate_tolerances/request",
                       String(data=json.dumps({"id": "cancel", "command": "cancel", "target": accepted["id"]})))


def test_allocator_serves_after_the_fuzz(allocator):
    """Cancel what the fuzz left running or queued; then a valid allocation is accepted, runs, and is
    cancelled on request (a solve takes longer than this test may)."""
    def send(doc):
        allocator.call("tolerance/allocate_tolerances/request", String(data=json.dumps(doc)))
        return allocator_answers(allocator)

    def status():
        return [a for a in send({"id": "s", "command": "status"}) if a.get("status") == "status"][-1]

    def idle():
        now = status()
        if now["running"] is not None:
            send({"id": "c", "command": "cancel", "target": now["running"]})
        return now["running"] is None and now["queued"] == 0

    assert wait_for(idle, 60, 0.2)
    accepted = send({"id": "after", "limit": 0.0014, "criterion": "paper", "mc_poses": 200})
    assert [(a["id"], a["ok"], a["status"]) for a in accepted] == [("after", True, "accepted")]
    assert wait_for(lambda: status()["running"] == "after", 30, 0.05)
    answers = send({"id": "stop", "command": "cancel", "target": "after"})
    assert wait_for(lambda: answers.extend(allocator_answers(allocator)) or len(answers) == 2, 30, 0.05)
    assert {(a["id"], a["status"]) for a in answers} == {("after", "cancelled"), ("stop", "cancelled")}


# Accuracy monitor.
def monitor_outputs(monitor):
    """Run the timers and check what they publish: a strict-JSON report of bounded size, diagnostics, finite
    markers."""
    monitor.tick()
    for msg in monitor.take("tolerance/accuracy_report"):
        loads_strict(msg.data)
        assert len(msg.data) < 100_000
    assert monitor.take("/diagnostics")
    for array in monitor.take("tolerance/markers"):
        for m in array.markers:
            values = [m.pose.position.x, m.pose.position.y, m.pose.position.z, m.pose.orientation.x,
                      m.pose.orientation.y, m.pose.orientation.z, m.pose.orientation.w, m.scale.x, m.scale.y,
                      m.scale.z] + [c for p in m.points for c in (p.x, p.y, p.z)]
            assert np.all(np.isfinite(values)), m


@FUZZ
@given(state=joint_states(), pose=poses())
def test_monitor_takes_or_rejects_every_measured_pose(monitor, state, pose):
    """A hostile pose, after a valid joint state at its stamp (so that it is paired when it can be)."""
    valid = JointState(name=list(GAO.joint_names), position=Q)
    valid.header.stamp = pose.header.stamp
    monitor.call("joint_states", valid)
    monitor.call("measured_pose", pose)
    monitor_outputs(monitor)


@FUZZ
@given(msg=joint_states())
def test_monitor_takes_or_rejects_every_joint_state(monitor, msg):
    monitor.call("joint_states", msg)
    monitor_outputs(monitor)


@FUZZ
@given(text=budget_texts())
def test_monitor_takes_or_ignores_every_budget(monitor, text):
    monitor.call("tolerance_budget", String(data=text))
    monitor_outputs(monitor)


def test_monitor_serves_after_the_fuzz(monitor):
    monitor.call("tolerance_budget", String(data=dumps_fast(budget_doc())))
    logic = monitor.node.logic
    paired = logic.counts["paired"]
    tip = GAO.fk(np.array([Q]))[0]
    for k in range(3):
        state = JointState(name=list(GAO.joint_names), position=Q)
        state.header.stamp.sec = 10 + k
        pose = PoseStamped()
        pose.header.stamp.sec = 10 + k
        pose.pose.position.x, pose.pose.position.y, pose.pose.position.z = tip[:3, 3]
        pose.pose.orientation.w = 1.0
        monitor.call("joint_states", state)
        monitor.call("measured_pose", pose)
    monitor_outputs(monitor)
    assert logic.counts["paired"] == paired + 3
    logged = read_log(logic.log.name)
    assert len(logged) >= 3
    with open(logic.log.name) as log:
        assert max(len(line) for line in log) < 2000


# Simulated tracker.
@FUZZ
@given(msg=joint_states())
def test_tracker_measures_or_ignores_every_joint_state(tracker, msg):
    tracker.call("joint_states", msg)
    for out in tracker.take("measured_pose"):
        p, o = out.pose.position, out.pose.orientation
        assert np.all(np.isfinite([p.x, p.y, p.z]))
        assert math.isclose(math.hypot(o.x, o.y, o.z, o.w), 1.0, rel_tol=1e-9)
        assert (out.header.stamp.sec, out.header.stamp.nanosec) == (msg.header.stamp.sec, msg.header.stamp.nanosec)


def test_tracker_serves_after_the_fuzz(tracker):
    state = JointState(name=list(GAO.joint_names), position=Q)
    state.header.stamp.sec = 7
    tracker.call("joint_states", state)
    out = tracker.take("measured_pose")
    assert len(out) == 1 and out[0].header.stamp.sec == 7


def test_joint_state_source_publishes_finite_states(source):
    for _ in range(3):
        source.tick()
    out = source.take("joint_states")
    assert len(out) == 3 and all(list(m.name) == list(GAO.joint_names) and np.all(np.isfinite(m.position))
                                 for m in out)


# Calibrations on the graph (tolerance_calibration), the calibrate service, trajectories.
@pytest.fixture(scope="module")
def calibration_text(tmp_path_factory):
    """A calibration file's text for the gao2023 arm, as the calibrate service publishes it."""
    q = GAO.sample_joints(30, 5)
    cal = calibrate(GAO, q, measure(GAO, q, as_built_errors(BUDGET.vector_for(GAO), 1), 1e-5, 0.0, None, seed=2),
                    folds=3)
    return save_calibration(cal, tmp_path_factory.mktemp("cal") / "calibration.yaml").read_text()


_PARSED = {}


@st.composite
def calibration_texts(draw, text):
    """A calibration text mutated (a value, a key, YAML tokens, its bytes), another robot's, or not one."""
    import copy
    import yaml
    kind = draw(st.sampled_from(["file"] * 6 + ["robot", "junk", "same"]))
    if kind == "same":
        return text
    if kind == "junk":
        return draw(st.one_of(texts, st.just(json.dumps(budget_doc())), st.just("- 1\n" * 1000), st.just("{" * 200)))
    if text not in _PARSED:
        _PARSED[text] = yaml.load(text, Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader))
    doc = copy.deepcopy(_PARSED[text])
    if kind == "robot":
        doc["robot"] = draw(st.one_of(st.sampled_from(["ur5", "rong2018_3pups", "", "x" * 300]), json_values()))
        return ros_text(yaml.safe_dump(doc))
    return ros_text(draw(yaml_file(doc)).decode("utf-8", errors="surrogateescape"))


def error_model_serves_calibrated(error_model, model="calibrated"):
    request = {"id": "cal", "joints": [Q], "model": model}
    error_model.call("tolerance/compute_error_jacobian/request", String(data=json.dumps(request)))
    return answer(error_model.take("tolerance/compute_error_jacobian/response")[-1].data, JACOBIAN_RESPONSE)


@CALIBRATION_FUZZ
@given(data=st.data())
def test_error_model_takes_or_refuses_every_calibration(error_model, calibration_text, data):
    error_model.call("tolerance_calibration", String(data=data.draw(calibration_texts(calibration_text))))
    doc = error_model_serves_calibrated(error_model)
    assert doc["ok"] or doc["error"]["code"] == "invalid_request"


def test_error_model_takes_a_calibration_after_the_fuzz(error_model, calibration_text):
    error_model.call("tolerance_calibration", String(data=calibration_text))
    doc, nominal = error_model_serves_calibrated(error_model), error_model_serves_calibrated(error_model, "nominal")
    assert doc["ok"] and nominal["ok"]
    assert 0 < np.abs(np.array(doc["jacobian"]) - np.array(nominal["jacobian"])).max() < 0.5


@st.composite
def calibrate_requests(draw):
    """Calibrate requests: valid ones (of the monitor's own log, short), status and cancel, hostile ones."""
    valid = st.fixed_dictionaries({"id": st.text(max_size=8)}, optional={
        "log": st.sampled_from(["current", "/nonexistent.jsonl"]), "window": st.lists(st.floats(-1e3, 1e3), min_size=2, max_size=2),
        "registration": st.sampled_from(["base", "base+tool"]), "folds": st.integers(2, 4),
        "parameters": st.sampled_from(["auto", "registration", "joint-offsets", "full", "full+elastic"]),
        "prior": st.one_of(st.none(), st.lists(st.floats(1e-6, 1.0), min_size=2, max_size=2)), "time_limit": st.floats(0.5, 2.0)})
    hostile = st.fixed_dictionaries({"id": st.one_of(st.text(max_size=12), st.integers(), st.sampled_from(ODD_IDS))},
                                    optional={k: st.one_of(scalars(), json_values()) for k in (
                                        "command", "robot", "log", "window", "registration", "parameters", "prior",
                                        "noise", "orientation_noise", "folds", "seed", "robust", "time_limit",
                                        "target", "zz")})
    commands = st.fixed_dictionaries({"id": st.text(max_size=8), "command": st.sampled_from(["status", "cancel"])},
                                     optional={"target": st.one_of(st.text(max_size=8), json_values())})
    return draw(request_texts(st.one_of(valid, hostile, commands)))


def calibrate_answers(monitor):
    monitor.tick()
    return [answer(m.data, CALIBRATE_RESPONSE) for m in monitor.take("tolerance/calibrate/response")]


@FUZZ
@given(text=calibrate_requests())
def test_monitor_answers_every_calibrate_request(monitor, text):
    monitor.call("tolerance/calibrate/request", String(data=text))
    calibrate_answers(monitor)
    for msg in monitor.take("tolerance/calibrate/progress"):
        loads_strict(msg.data)


@FUZZ
@given(text=request_texts(st.fixed_dictionaries({}, optional={
    "contact": st.one_of(st.sampled_from(["plane:table", "point:p1", "plane:", "line:x"]), scalars()),
    "targets": st.one_of(st.lists(st.sampled_from(["A", "B", "", "\x00"]), max_size=3), json_values(),
                         st.dictionaries(st.sampled_from(["A", "B"]), st.lists(st.floats(allow_nan=True), max_size=4))),
    "session": st.one_of(st.text(max_size=8), scalars()), "pose": json_values(), "id": st.sampled_from(ODD_IDS),
    "zz": scalars()})))
def test_monitor_answers_every_contact_request(monitor, text):
    """Each tolerance/contact request is answered once on tolerance/contact/result: latched, or refused with a code
    (the monitor goes on)."""
    monitor.call("tolerance/contact", String(data=text))
    answers = monitor.take("tolerance/contact/result")
    assert len(answers) == 1
    doc = json.loads(answers[0].data)
    assert doc["ok"] or (doc["error"] in ("invalid_request", "no_joint_state", "stale_joint_state",
                                          "invalid_joint_state", "not_ready") and doc["message"]), doc


@CALIBRATION_FUZZ
@given(data=st.data())
def test_monitor_takes_or_refuses_every_calibration(monitor, calibration_text, data):
    monitor.call("tolerance_calibration", String(data=data.draw(calibration_texts(calibration_text))))
    monitor_outputs(monitor)


def test_monitor_calibrates_after_the_fuzz(monitor, calibration_text):
    import time
    node = monitor.node
    deadline = time.monotonic() + 30
    while node.calibrator.queue or node.calibrator._running_id() is not None:
        assert time.monotonic() < deadline, "calibration jobs of the fuzz still running"
        time.sleep(0.05)
    calibrate_answers(monitor)
    monitor.call("tolerance/calibrate/request", String(data='{"id": "st", "command": "status"}'))
    assert [d for d in calibrate_answers(monitor) if d["id"] == "st"][0]["ok"]
    monitor.call("tolerance_calibration", String(data=calibration_text))
    assert node.logic.calibration is not None
    monitor_outputs(monitor)


@pytest.fixture(scope="module")
def compensator(graph):
    from tolerance_ros.nodes.trajectory_compensator import TrajectoryCompensator
    return Harness(graph.start(TrajectoryCompensator, "/fuzz_compensator", on_flag="nominal"))


@pytest.fixture(scope="module")
def compensated_source(graph):
    from tolerance_ros.nodes.joint_state_source import JointStateSource
    return Harness(graph.start(JointStateSource, "/fuzz_compensated_source", compensated=True))


@st.composite
def trajectories(draw):
    """JointTrajectory messages with hostile names, numbers, shapes and sizes."""
    names = list(GAO.joint_names)
    name = draw(st.one_of(st.just(names), st.permutations(names), st.just(names + ["gripper"]),
                          st.lists(st.sampled_from(names + ["x", ""]), max_size=9), st.just(names * 2), st.just([])))
    k = len(name)
    m = draw(st.sampled_from([0, 1, 2, 3, 5, 40]))
    sizes = draw(st.sampled_from(["same", "same", "ragged"]))
    row = st.lists(st.one_of(st.floats(-1.0, 1.0), floats), min_size=k, max_size=k)
    pts = []
    for _ in range(m):
        positions = draw(row if sizes == "same" else st.lists(floats, max_size=10))
        rates = draw(st.sampled_from(["none", "row", "ragged"]))
        velocities = [] if rates == "none" else draw(row if rates == "row" else st.lists(floats, max_size=10))
        pt = JointTrajectoryPoint(positions=positions, velocities=velocities,
                                  accelerations=draw(st.one_of(st.just([]), row)), effort=draw(st.lists(floats, max_size=3)))
        pt.time_from_start.sec = draw(st.integers(-2 ** 31, 2 ** 31 - 1))
        pts.append(pt)
    msg = JointTrajectory(joint_names=name, points=pts)
    return stamped(msg, draw(stamps), draw(frames))


@st.composite
def trajectory_bytes(draw):
    """A serialized trajectory, or its bytes edited (cut, flipped, padded), or junk."""
    raw = bytes(serialize_message(draw(trajectories())))
    how = draw(st.sampled_from(["keep", "keep", "cut", "flip", "pad", "junk", "counts"]))
    k = draw(st.integers(0, max(len(raw) - 1, 0)))
    if how == "cut":
        return raw[:k]
    if how == "flip":
        return raw[:k] + bytes([raw[k] ^ 0xFF]) + raw[k + 1:] if raw else raw
    if how == "pad":
        return raw + b"\x00" * draw(st.integers(1, 9))
    if how == "junk":
        return draw(st.binary(max_size=200))
    if how == "counts":
        return raw[:k - k % 4] + b"\xff\xff\xff\x7f" + raw[k - k % 4 + 4:]
    return raw


def published_trajectories(harness):
    """The trajectories published on ``joint_trajectory`` (the compensator publishes their bytes)."""
    return [deserialize_message(m, JointTrajectory) if isinstance(m, bytes) else m
            for m in harness.take("joint_trajectory")]


def compensator_outputs(compensator):
    compensator.tick()
    for out in published_trajectories(compensator):
        for p in out.points:
            assert np.all(np.isfinite(p.positions)) and np.all(np.isfinite(p.velocities))
    assert compensator.take("/diagnostics")


@FUZZ
@given(raw=trajectory_bytes())
def test_compensator_compensates_or_refuses_every_trajectory(compensator, calibration_text, raw):
    if compensator.node.logic.calibration is None:
        compensator.call("tolerance_calibration", String(data=calibration_text))
    compensator.call("joint_trajectory_in", raw)
    compensator_outputs(compensator)


@CALIBRATION_FUZZ
@given(data=st.data())
def test_compensator_takes_or_refuses_every_calibration(compensator, calibration_text, data):
    compensator.call("tolerance_calibration", String(data=data.draw(calibration_texts(calibration_text))))
    compensator_outputs(compensator)


def test_compensator_serves_after_the_fuzz(compensator, calibration_text):
    compensator.call("tolerance_calibration", String(data=calibration_text))
    assert compensator.node.logic.calibration is not None
    q = GAO.sample_joints(3, 1) * 0.5
    plan = JointTrajectory(joint_names=list(GAO.joint_names),
                           points=[JointTrajectoryPoint(positions=row.tolist()) for row in q])
    compensator.call("joint_trajectory_in", plan)
    out = published_trajectories(compensator)
    assert len(out) == 1 and len(out[0].points) == 3
    assert 0 < np.abs(np.array([p.positions for p in out[0].points]) - q).max() < 0.05


@FUZZ
@given(msg=trajectories())
def test_the_compensated_source_publishes_only_whole_finite_states(compensated_source, msg):
    source = compensated_source
    source.tick()
    source.call("joint_trajectory", msg)
    source.tick()
    source.take("joint_trajectory_in")
    for out in source.take("joint_states"):
        assert list(out.name) == list(GAO.joint_names)
        assert len(out.position) == GAO.dof and np.all(np.isfinite(out.position))


# robot_description, for every node class that can take its robot from it.
NODES_FROM_DESCRIPTION = {
    "error_model": ("tolerance_ros.nodes.error_model_server", "ErrorModelServer",
                    {"robots": ["robot_description"], "default_robot": "robot_description"}),
    "allocator": ("tolerance_ros.nodes.tolerance_allocator", "ToleranceAllocator",
                  {"robots": ["robot_description"], "default_robot": "robot_description"}),
    "monitor": ("tolerance_ros.nodes.accuracy_monitor", "AccuracyMonitor", {"robot": "robot_description"}),
    "tracker": ("tolerance_ros.nodes.simulated_tracker", "SimulatedTrackerNode", {"robot": "robot_description"}),
    "source": ("tolerance_ros.nodes.joint_state_source", "JointStateSource", {"robot": "robot_description"}),
    "compensator": ("tolerance_ros.nodes.trajectory_compensator", "TrajectoryCompensator",
                    {"robot": "robot_description"}),
}


@pytest.fixture(scope="module")
def ur5_files(tmp_path_factory):
    """A budget and a calibration file for the UR5 of example-robot-data, the robot of the valid description."""
    model = load_robot(str(example_urdf("ur5_robot.urdf")), tip_link="tool0")
    tmp = tmp_path_factory.mktemp("ur5")
    budget = tmp / "ur5_budget.json"
    budget.write_text(json.dumps({"robot": model.name, "tolerances": {n: 1e-5 for n in model.param_names}}))
    q = model.sample_joints(30, 5)
    delta = np.full(len(model.param_names), 1e-4)
    cal = calibrate(model, q, measure(model, q, as_built_errors(delta, 1), 1e-5, 0.0, None, seed=2), folds=3)
    return {"budget": str(budget), "calibration": str(save_calibration(cal, tmp / "ur5_calibration.yaml"))}


@pytest.fixture(scope="module", params=sorted(NODES_FROM_DESCRIPTION))
def described(request, graph, tmp_path_factory, ur5_files):
    """A node that takes its robot from robot_description, with files (budget, calibration) for the UR5 only."""
    import importlib
    module, cls, params = NODES_FROM_DESCRIPTION[request.param]
    tmp = tmp_path_factory.mktemp(request.param)
    extra = {"monitor": {"log_dir": str(tmp), "budget": ur5_files["budget"]}, "allocator": {"budget_dir": str(tmp)},
             "tracker": {"budget": ur5_files["budget"]},
             "error_model": {"calibration": ur5_files["calibration"]}}.get(request.param, {})
    node = graph.start(getattr(importlib.import_module(module), cls), f"/fuzz_description_{request.param}",
                       tip_link="tool0", **params, **extra)
    harness = Harness(node)
    harness.kind = request.param
    return harness


@settings(max_examples=60, deadline=None, suppress_health_check=list(HealthCheck), database=None)
@given(text=urdf_texts())
def test_every_robot_description_is_taken_or_ignored(described, text):
    """A robot the node's files do not fit (the UR5 budget or calibration) is refused or its calibration
    dropped, without the last-resort handler."""
    described.call("robot_description", String(data=text))
    described.tick()
    for msg in described.sent.pop("joint_states", []):
        assert np.all(np.isfinite(msg.position))
    described.sent.clear()


def test_the_robot_from_a_valid_description_after_the_fuzz(described):
    described.call("robot_description", String(data=URDF))
    described.tick()
    node, kind = described.node, described.kind
    robots = node.service.robots if kind in ("error_model", "allocator") else node.robots
    assert robots.default_name == "ur5"
    q = robots.single().sample_joints(1, 0)[0].tolist()
    if kind == "error_model":
        request = {"id": "after", "command": "compensate", "joints": [q]}
        described.call("tolerance/compute_error_jacobian/request", String(data=json.dumps(request)))
        doc = answer(described.take("tolerance/compute_error_jacobian/response")[-1].data, JACOBIAN_RESPONSE)
        assert doc["ok"] and doc["robot"] == "ur5" and doc["model"] == "calibrated"
    elif kind == "allocator":
        described.call("tolerance/allocate_tolerances/request", String(data='{"id": "s", "command": "status"}'))
        assert allocator_answers(described)[-1]["ok"]
    elif kind == "monitor":
        assert node.logic.model.name == "ur5" and node.logic.budget is not None
    elif kind == "tracker":
        state = JointState(name=list(robots.single().joint_names), position=q)
        described.call("joint_states", state)
        assert len(described.take("measured_pose")) == 1
    elif kind == "compensator":
        assert node.logic.model.name == "ur5"
        plan = JointTrajectory(joint_names=list(robots.single().joint_names), points=[JointTrajectoryPoint(positions=q)])
        described.call("joint_trajectory_in", plan)
        assert len(described.take("joint_trajectory")) == 1
    else:
        described.tick()
        assert list(described.take("joint_states")[-1].name) == list(robots.single().joint_names)
