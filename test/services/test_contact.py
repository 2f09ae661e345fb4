"""Contacts on the graph, ROS-free: the monitor latches the joint state of a ``tolerance/contact`` request into its
campaign log, and the calibrate service fits that log (calibration from contact, no tracker)."""
import json
from pathlib import Path

import numpy as np
import pytest

from tolerance_ros.core.accuracy.io.contact_csv import is_contact_campaign, read_contact_log
from tolerance_ros.core.accuracy.io.campaign_log import read_log
from tolerance_ros.core.accuracy.simulate import as_built_errors, touch
from tolerance_ros.core.calibration.calibration_file import calibration_from_text
from tolerance_ros.services.calibration import CalibrationService
from tolerance_ros.services.monitor import MonitorLogic
from tolerance_ros.services.robots import RobotSet

URDF = Path(__file__).resolve().parents[1] / "data" / "fanuc_r2000ic" / "fanuc_r2000ic_165f.urdf"
PLANES = [("floor", (0, 0, 1.0), 0.3), ("wall", (1.0, 0, 0), 1.7), ("side", (0, 1.0, 0), -0.9)]
TOOL = [0.012, -0.006, 0.11]


class Clock:
    def __init__(self):
        self.t = 0.0

    def __call__(self):
        return self.t


@pytest.fixture(scope="module")
def robots():
    return RobotSet([str(URDF)], str(URDF))


def monitor(model, path, clock):
    return MonitorLogic(model, None, None, slop=0.01, max_wait=0.5, log_path=path, clock=clock, orientation=False)


def test_a_contact_request_latches_the_newest_joint_state_into_the_log(robots, tmp_path):
    model = robots.select(None)[1]
    clock = Clock()
    mon = monitor(model, tmp_path / "log.jsonl", clock)
    bad = mon.on_contact(json.dumps({"contact": "plane:t", "targets": ["A"]}))
    assert not bad["ok"] and bad["error"] == "no_joint_state"
    q = np.array([0.1, -0.2, 0.3, 0.4, -0.5, 0.6])
    mon.on_joint_state(10.0, list(model.joint_names)[::-1] + ["gripper"], list(q[::-1]) + [0.02])
    mon.on_joint_state(9.0, list(model.joint_names), list(q + 1.0))     # older stamp, arriving later: not latched
    ans = mon.on_contact(json.dumps({"id": 7, "contact": "plane:table1", "targets": {"A": TOOL, "B": [0, 0, 0.1]},
                                     "session": "s1", "pose": "P1"}))
    assert ans["ok"] and ans["rows"] == 2 and ans["stamp"] == 10.0 and np.allclose(ans["joints"], q)
    clock.t = 2.0
    stale = mon.on_contact(json.dumps({"contact": "plane:table1", "targets": ["A"]}))
    assert not stale["ok"] and stale["error"] == "stale_joint_state" and "nothing latched" in stale["message"]
    mon.close()
    contacts, offsets = read_contact_log(tmp_path / "log.jsonl", model.joint_names)
    assert is_contact_campaign(tmp_path / "log.jsonl") and len(contacts) == 2
    assert list(contacts.target) == ["A", "B"] and set(contacts.contact) == {"plane:table1"}
    assert np.allclose(contacts.joints, q) and offsets == {"A": TOOL, "B": [0.0, 0.0, 0.1]}
    assert mon.counts["contacts"] == 2
    assert contacts.other_names == ("gripper",) and np.allclose(contacts.others, 0.02)   # the rest of the posture


def test_the_joints_outside_the_chain_are_latched_with_the_state_they_came_in(robots, tmp_path):
    """A humanoid's other leg and arm load the chain's joints: the contact keeps the readings of the joints outside
    the chain of the state it latches (finite, printable names only), and the log reads them back."""
    model = robots.select(None)[1]
    clock = Clock()
    mon = monitor(model, tmp_path / "log.jsonl", clock)
    q = np.array([0.1, -0.2, 0.3, 0.4, -0.5, 0.6])
    names = list(model.joint_names) + ["knee", "bad\udc80", "hip", "nan_joint"]
    mon.on_joint_state(1.0, names, list(q) + [0.5, 1.0, -0.25, float("nan")])
    assert mon.on_contact(json.dumps({"contact": "plane:t", "targets": ["A"], "pose": "P1"}))["ok"]
    mon.on_joint_state(2.0, names[:6] + ["knee"], list(q) + [0.7])
    assert mon.on_contact(json.dumps({"contact": "plane:t", "targets": ["A"], "pose": "P2"}))["ok"]
    mon.close()
    contacts, _ = read_contact_log(tmp_path / "log.jsonl", model.joint_names)
    assert contacts.other_names == ("knee",) and np.allclose(contacts.others[:, 0], [0.5, 0.7])
    assert contacts.ignored == ["hip"]                      # not in every event: listed, not used


@pytest.mark.parametrize("text, words", [
    ("not json", "not valid JSON"),
    ('{"contact": "line:x", "targets": ["A"]}', "contact: expected"),
    ('{"contact": "plane:t", "targets": []}', "targets: expected 1 to 20"),
    ('{"contact": "plane:t", "targets": {"A": [0, 0, NaN]}}', "NaN is not a number"),
    ('{"contact": "plane:t", "targets": {"A": [0, 0, 100]}}', "more than 5 m"),
    ('{"contact": "plane:t", "targets": ["A"], "speed": 1}', "unknown field"),
    ('{"contact": "plane:t", "targets": ["A", "A"]}', "distinct names"),
    ('[1, 2]', "expected a JSON object"),
    ('{"contact": "plane:t", "targets": [[]]}', "distinct names"),
    ('{"contact": "plane:t", "targets": [1, 2]}', "distinct names"),
    ('{"contact": "plane:t", "targets": ["\\ud800"]}', "UTF-8 text"),        # a lone surrogate raised TypeError
    ('{"contact": "plane:t", "targets": {"F\\udc80": [0, 0, 0.1]}}', "UTF-8 text"),
    ('{"contact": "plane:t", "targets": ["A"], "session": "s\\ud800"}', "session: expected"),
    ('{"contact": "plane:t", "targets": ["A"], "pose": "\\udfff"}', "pose: expected"),
    ('{"contact": "plane:t", "targets": ["A"], "id": "\\ud800"}', "id: expected"),
    ('{"contact": "plane:t", "targets": [" "]}', "targets: a name of 1 to 100"),  # logged, then it failed calibrate
    ('{"contact": "plane:t", "targets": {"A ": [0, 0, 0.1]}}', "surrounding blanks"),
])
def test_a_bad_contact_request_is_answered_with_the_field_and_the_monitor_goes_on(robots, tmp_path, text, words):
    model = robots.select(None)[1]
    mon = monitor(model, tmp_path / "log.jsonl", Clock())
    mon.on_joint_state(1.0, list(model.joint_names), [0.0] * 6)
    ans = mon.on_contact(text)
    assert not ans["ok"] and ans["error"] == "invalid_request" and words in ans["message"]
    assert mon.on_contact(json.dumps({"contact": "point:p", "targets": ["A"]}))["ok"]
    mon.close()
    contacts, _ = read_contact_log(tmp_path / "log.jsonl", model.joint_names)   # what was logged reads back
    assert list(contacts.target) == ["A"]


def test_the_calibrate_service_fits_the_contacts_the_monitor_logged(robots, tmp_path):
    model = robots.select(None)[1]
    dx = as_built_errors(np.array([1e-4 if k == "length" else 5e-4 for k in model.param_kinds]), 3)
    clock = Clock()
    log = tmp_path / "log.jsonl"
    mon = monitor(model, log, clock)
    stamp = 0.0
    for c, (name, n, d) in enumerate(PLANES):
        for q in touch(model, dx, TOOL, "plane", (np.array(n), d), 30, seed=[4, c], noise=1e-5):
            stamp += 1.0
            mon.on_joint_state(stamp, list(model.joint_names), list(q))
            assert mon.on_contact(json.dumps({"contact": f"plane:{name}", "targets": ["A"], "session": "s1"}))["ok"]
    mon.close()
    with pytest.raises(Exception, match="no paired measurements"):
        read_log(log)                        # a log of contacts has no tracker measurements to read
    out = []
    svc = CalibrationService(robots, lambda kind, doc: out.append((kind, doc)), current_log=lambda: str(log))
    try:
        svc.handle(json.dumps({"id": "c1", "log": "current", "targets": {"A": [0, 0, 0.1]}, "folds": 5}))
        import time
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and not any(k == "response" and d.get("status") == "done" for k, d in out):
            time.sleep(0.05)
        resp = next(d for k, d in out if k == "response" and d.get("status") == "done")
    finally:
        svc.close()
    from tolerance_ros.testing.schemas import validator
    validator("calibrate.response").validate(json.loads(json.dumps(resp)))
    v = resp["validation"]
    assert resp["success"] and resp["measurements"] == 90
    assert v["after"]["contact_rms_m"] < 2e-5 < 2e-4 < v["before"]["contact_rms_m"]
    put = [d for k, d in out if k == "calibration"]
    cal = calibration_from_text(put[0]["text"], model)
    assert cal.registration == "contact" and np.allclose(cal.targets.offsets[0], TOOL, atol=2e-4)


def test_a_camera_on_a_robot_link_measures_in_that_links_frame(tmp_path):
    """A chain from the wrist (eye in hand) to the base: a PoseStamped must name the wrist's link as its frame."""
    from tolerance_ros.core.models.urdf import URDFChain
    model = URDFChain(URDF, tip_link="base_link", base_link="flange")
    mon = MonitorLogic(model, None, None, slop=0.01, max_wait=0.5, clock=Clock())
    mon.on_joint_state(1.0, list(model.joint_names), [0.1] * 6)
    mon.on_pose(1.0, "camera_optical", (0.5, 0.1, 0.9), (0, 0, 0, 1))
    assert mon.counts["rejected"] == 1 and "sensor is on the robot link 'flange'" in mon.last_reasons[-1]
    mon.on_pose(1.0, "flange", (0.5, 0.1, 0.9), (0, 0, 0, 1))
    assert mon.counts["rejected"] == 1 and mon.counts["received"] == 2
