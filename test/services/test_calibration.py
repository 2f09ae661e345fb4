"""The calibration service: from the monitor's campaign log to a calibration put in force, or refused."""
import json

import numpy as np
import pytest
from tolerance_ros.testing.schemas import validator

from tolerance_ros.core.accuracy.io import write_csv
from tolerance_ros.core.accuracy.simulate import as_built_errors, measure_targets
from tolerance_ros.core.budget import load_budget
from tolerance_ros.core.calibration.calibration_file import calibration_from_text
from tolerance_ros.core.geometry import transform
from tolerance_ros.services.calibration import FIELDS, CalibrationService
from tolerance_ros.services.robots import RobotSet


@pytest.fixture(scope="module")
def campaign(gao, tmp_path_factory):
    dx = as_built_errors(load_budget("gao2023_delta2", gao).vector_for(gao), 5)
    q = np.repeat(gao.sample_joints(30, 5), 2, axis=0)
    m = measure_targets(gao, q, dx, None, 1e-5, 0.0, transform([1.5, 0.2, 0.0], [0, 0, 0.5]), seed=2,
                        labels=[f"P{i // 2}" for i in range(60)], stamps=np.arange(60) * 0.5)
    return write_csv(tmp_path_factory.mktemp("cal") / "log.csv", m)


RESPONSE = validator("calibrate.response")


class Recorder(list):
    """Every (kind, doc) a service emits, in order; every answer checked against the shipped schema (after a
    JSON round trip, as it goes out)."""

    def __call__(self, kind, doc):
        if kind == "response":
            RESPONSE.validate(json.loads(json.dumps(doc)))
        self.append((kind, doc))

    @property
    def items(self):
        return list(self)


def wait(out, rid, timeout=60.0):
    import time
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        for kind, doc in out.items:
            if kind == "response" and doc.get("id") == rid and doc.get("status") not in ("accepted",):
                return doc
        time.sleep(0.05)
    raise AssertionError(f"no final answer to {rid}")


def test_the_request_schema_names_the_fields_the_service_takes():
    request = validator("calibrate.request")
    assert set(request.schema["properties"]) == set(FIELDS) | {"id"}
    request.validate({"id": "k", "log": "current", "window": [0.0, 1.0], "prior": None, "folds": 5})
    assert not request.is_valid({"id": "k", "parameters": "everything"})


def test_a_calibration_from_the_log_is_answered_and_put_in_force(gao, campaign, tmp_path):
    out = Recorder()
    svc = CalibrationService(RobotSet(["gao2023_7dof"], "gao2023_7dof"), out, current_log=lambda: str(campaign),
                             save_dir=tmp_path)
    try:
        svc.handle(json.dumps({"id": "k1", "log": "current", "window": [0.0, 29.75]}))
        assert out.items[0][1]["status"] == "accepted"
        svc.handle(json.dumps({"id": "s1", "command": "status"}))
        resp = wait(out, "k1")
        assert resp["ok"] and resp["success"] and resp["measurements"] == 60 and resp["model"]["parameters"] == "full"
        assert resp["validation"]["improvement"] > 0.9 and "_calibration" not in resp
        put = [d for kind, d in out.items if kind == "calibration"]
        assert len(put) == 1 and put[0]["robot"] == "gao2023_7dof"
        cal = calibration_from_text(put[0]["text"], gao)
        assert cal.validation["after"]["position_rms_m"] < 3e-5
        assert (tmp_path / "k1" / "calibration.yaml").exists()
        assert any(kind == "progress" and d["id"] == "k1" for kind, d in out.items)
    finally:
        svc.close()


@pytest.mark.parametrize("req, code, message", [
    ({"id": "b1", "log": "nowhere.jsonl"}, "invalid_request", "log: no such file"),
    ({"id": "b2", "parameters": "everything"}, "invalid_request", "parameters: expected one of"),
    ({"id": "b3", "window": [5, 1]}, "invalid_request", "window: t_start must be before t_end"),
    ({"id": "b4", "robot": "nobody"}, "unknown_robot", "nobody"),
    ({"id": "b5", "time_limit": 1e-300}, "invalid_request", "time_limit"),
    ({"id": "b6", "log": "a\x00b.csv"}, "invalid_request", "holds a NUL byte"),
    ({"id": "b7", "log": "x" * 300 + ".csv"}, "invalid_request", "longer than a file name can be"),
    ({"id": "b8", "log": "/" + "d/" * 3000 + "m.csv"}, "invalid_request", "longer than a file name can be"),
    ({"id": "b9", "decision_rule": "guarded:0"}, "invalid_request", "decision_rule: decision rule"),
])
def test_bad_requests_are_refused_naming_the_field(campaign, req, code, message):
    out = Recorder()
    svc = CalibrationService(RobotSet(["gao2023_7dof"], "gao2023_7dof"), out, current_log=lambda: str(campaign))
    try:
        svc.handle(json.dumps(req))
        doc = out.items[0][1]
        assert doc["ok"] is False and doc["error"]["code"] == code and message in doc["error"]["message"]
        assert len(doc["error"]["message"]) < 300          # at most a bounded piece of the name is shown
    finally:
        svc.close()


def test_a_log_that_cannot_be_calibrated_is_infeasible_with_the_reason(campaign):
    out = Recorder()
    svc = CalibrationService(RobotSet(["gao2023_7dof"], "gao2023_7dof"), out, current_log=lambda: str(campaign))
    try:
        svc.handle(json.dumps({"id": "w1", "log": "current", "window": [0.0, 0.6]}))  # one pose, measured twice
        doc = wait(out, "w1")
        assert doc["ok"] is False and doc["error"]["code"] == "infeasible"
        assert "distinct test poses" in doc["error"]["message"]
        svc.handle(json.dumps({"id": "w2", "log": "current", "window": [1e6, 2e6]}))
        doc = wait(out, "w2")
        assert doc["error"]["code"] == "infeasible" and "window: no measurement" in doc["error"]["message"]
    finally:
        svc.close()


def test_a_calibration_the_checks_refuse_is_answered_not_put_in_force(gao, tmp_path):
    q = np.repeat(gao.sample_joints(20, 6), 2, axis=0)
    m = measure_targets(gao, q, None, None, 1e-5, 0.0, transform([1.5, 0.2, 0.0], [0, 0, 0.5]), seed=1,
                        labels=[f"P{i // 2}" for i in range(40)])
    m.T[:, :3, 3] *= 1e-3                                     # metres labelled millimetres
    log = write_csv(tmp_path / "mm.csv", m)
    out = Recorder()
    svc = CalibrationService(RobotSet(["gao2023_7dof"], "gao2023_7dof"), out)
    try:
        svc.handle(json.dumps({"id": "r1", "log": str(log)}))
        resp = wait(out, "r1")
        assert resp["ok"] is False and resp["error"]["code"] == "infeasible" and "units" in resp["error"]["message"]
        assert not [d for kind, d in out.items if kind == "calibration"]
    finally:
        svc.close()


def test_only_logs_under_log_dir_are_read(campaign, tmp_path):
    import os
    logs = tmp_path / "campaigns"
    logs.mkdir()
    (logs / "ok.csv").write_bytes(campaign.read_bytes())
    os.symlink(campaign, logs / "link.csv")                          # inside by name, outside in fact
    out = Recorder()
    svc = CalibrationService(RobotSet(["gao2023_7dof"], "gao2023_7dof"), out, log_dir=logs)
    try:
        for rid, log in (("o1", str(campaign)), ("o2", "../" + campaign.name), ("o3", "link.csv"), ("o4", "/etc/passwd")):
            svc.handle(json.dumps({"id": rid, "log": log}))
            doc = [d for _, d in out.items if d.get("id") == rid][0]
            assert doc["error"]["code"] == "invalid_request" and "is outside this node's log_dir" in doc["error"]["message"]
        svc.handle(json.dumps({"id": "i1", "log": "ok.csv", "folds": 3}))   # relative: from log_dir
        assert [d for _, d in out.items if d.get("id") == "i1"][0]["status"] == "accepted"
        assert wait(out, "i1")["ok"]
    finally:
        svc.close()


def test_the_calibration_carries_its_provenance_and_the_hash_of_the_log_it_was_fitted_to(gao, campaign, tmp_path):
    from tolerance_ros.core.calibration.provenance import (file_sha256, generate_key_pair, load_public_keys,
                                                          load_signing_key, verify_signature)
    kid = generate_key_pair(tmp_path / "k.key", tmp_path / "k.pub")
    out = Recorder()
    svc = CalibrationService(RobotSet(["gao2023_7dof"], "gao2023_7dof"), out, current_log=lambda: str(campaign),
                             save_dir=tmp_path / "cals", made_by="/arm/tolerance_accuracy_monitor",
                             signing_key=load_signing_key(tmp_path / "k.key"))
    try:
        svc.handle(json.dumps({"id": "../p 1", "log": "current", "folds": 3}))
        resp = wait(out, "../p 1")
        folder = tmp_path / "cals" / "___p_1"                          # the id as a folder name, no '..' or '/'
        p = resp["provenance"]
        assert resp["success"] and p["made_by"] == "/arm/tolerance_accuracy_monitor" and p["request_id"] == "../p 1"
        assert p["log"] == str(folder / "measurements.csv") and p["log_sha256"] == file_sha256(campaign)
        assert (folder / "measurements.csv").read_bytes() == campaign.read_bytes()
        text = [d for kind, d in out.items if kind == "calibration"][0]["text"]
        assert (folder / "calibration.yaml").read_text() == text and resp["calibration_file"] == str(folder / "calibration.yaml")
        cal = calibration_from_text(text, gao)
        assert cal.content_sha256 == p["content_sha256"] and resp["signed_by"] == kid
        assert verify_signature(cal.content_sha256, cal.signature, load_public_keys([tmp_path / "k.pub"])) == kid
    finally:
        svc.close()


def test_a_calibration_outside_the_envelope_is_answered_not_put_in_force(campaign, tmp_path):
    from tolerance_ros.core.calibration.envelope import Envelope
    out = Recorder()
    svc = CalibrationService(RobotSet(["gao2023_7dof"], "gao2023_7dof"), out, current_log=lambda: str(campaign),
                             save_dir=tmp_path, envelope=Envelope(max_joint=1e-4, max_tool=1e-5))
    try:
        svc.handle(json.dumps({"id": "e1", "log": "current", "folds": 3}))
        resp = wait(out, "e1")
        assert resp["ok"] and resp["plausibility"]["ok"] and resp["success"] is False
        assert not resp["envelope"]["ok"] and "max_tool_correction 0.01 mm" in resp["envelope"]["reason"]
        assert not [d for kind, d in out.items if kind == "calibration"]
        assert (tmp_path / "e1" / "calibration.refused.yaml").exists() and not (tmp_path / "e1" / "calibration.yaml").exists()
    finally:
        svc.close()


def test_the_parts_a_calibration_identifies_are_judged_against_the_nodes_budget(gao, campaign):
    """With a budget in force, the answer judges each identified part (report's groups and decision rule); the arm
    was built within delta_2, so no part is decided out; without a budget there is no such section."""
    budget = load_budget("gao2023_delta2", gao)
    for given, rid, rule in ((budget, "j1", None), (budget, "j2", "simple"), (None, "j3", None)):
        out = Recorder()
        svc = CalibrationService(RobotSet(["gao2023_7dof"], "gao2023_7dof"), out, current_log=lambda: str(campaign),
                                 budget=lambda: given)
        try:
            svc.handle(json.dumps({"id": rid, "log": "current", **({"decision_rule": rule} if rule else {})}))
            resp = wait(out, rid)
        finally:
            svc.close()
        if given is None:
            assert "budget" not in resp
            continue
        grp = resp["budget"]
        assert grp["rule"] == (rule or "guarded:2") and grp["source"] == budget.source
        assert not grp["out_of_tolerance"] and sum(grp["counts"].values()) == len(grp["groups"]) > 10
        assert {g["decision"] for g in grp["groups"]} <= ({"within"} if rule else {"within", "undecided"})
