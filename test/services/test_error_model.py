"""compute_error_jacobian: answers against the shipped schema, every error path, bounded work, compact arrays."""
import json

import jsonschema
import numpy as np
import pytest

from tolerance_ros.testing.schemas import schema
from tolerance_ros.core.jsonio import decode_arrays
from tolerance_ros.services.contracts import Limits
from tolerance_ros.services.error_model import ErrorModelService
from tolerance_ros.services.robots import RobotSet


@pytest.fixture(scope="module")
def service(gao):
    return ErrorModelService({"gao2023_7dof": gao}, "gao2023_7dof", Limits(max_bytes=200_000, max_poses=50))


Q = [0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6]


def ask(service, req):
    text = req if isinstance(req, str) else json.dumps(req)
    out = json.loads(service.handle_text(text))
    jsonschema.validate(out, schema("compute_error_jacobian.response"))
    return out


def test_single_and_many_configurations(service, gao):
    r = ask(service, {"id": "a", "joints": Q})
    assert r["ok"] and r["id"] == "a" and r["n"] == 1 and r["rows"] == ["dx", "dy", "dz", "drx", "dry", "drz"]
    T, EJ = gao.fk_and_jacobian(np.array([Q]))
    assert np.allclose(r["poses"], T) and np.allclose(r["jacobian"], EJ.J)
    assert np.allclose(r["sensitivity"], np.linalg.norm(EJ.position, axis=1))
    r = ask(service, {"id": 7, "joints": [Q, Q, Q], "outputs": "position", "include_jacobian": True})
    assert r["id"] == 7 and np.array(r["jacobian"]).shape == (3, 3, 28)


def test_bounds_with_tolerances(service, gao):
    tol = {n: 1e-4 if k == "length" else 3e-4 for n, k in zip(gao.param_names, gao.param_kinds)}
    r = ask(service, {"id": "b", "joints": Q, "tolerances": tol, "criteria": ["paper", "worst-case", "rss"]})
    b = r["bounds"]["position"]
    assert b["rss"][0] <= b["worst-case"][0] and b["paper"][0] <= b["worst-case"][0]
    assert set(r["bounds"]) == {"position", "orientation", "budget_criterion"}


@pytest.mark.parametrize("request_text, code, needle", [
    ("{not json", "invalid_json", "not valid JSON"),
    ('{"id": 1, "joints": [0, 0, 0, 0, 0, 0, NaN]}', "invalid_json", "not valid JSON"),
    ('[1, 2]', "invalid_request", "JSON object"),
    ('{"joints": [0,0,0,0,0,0,0]}', "invalid_request", "id: required"),
    ('{"id": true, "joints": [0,0,0,0,0,0,0]}', "invalid_request", "id: required"),
    ('{"id": 1}', "invalid_request", "joints: required"),
    ('{"id": 1, "joints": [0, 0]}', "invalid_request", "joints[0]: expected 7 values"),
    ('{"id": 1, "joints": [[0,0,0,0,0,0,0], [0,0]]}', "invalid_request", "joints[1]: expected 7 values"),
    ('{"id": 1, "joints": [0,0,0,"x",0,0,0]}', "invalid_request", "joints[0][3]: expected a number"),
    ('{"id": 1, "joints": [[0,0,0,0,0,0,0], 5, [0,0]]}', "invalid_request", "joints[1]: expected 7 values"),
    ('{"id": 1, "joints": [[0,0,0,0,0,0,0], [0,0,0,0,0,null,0]]}', "invalid_request",
     "joints[1][5]: expected a number, got NoneType"),
    ('{"id": 1, "joints": [[0,0,0,0,0,0,0], [0,0,-4,0,0,0,4], [0,0,0,0,0,0,4]]}', "out_of_limits",
     "joints[1][2] (joint3) = -4 is outside [-3.14159, 3.14159] (2 configuration(s) affected)"),
    ('{"id": 1, "joints": [0,0,0,true,0,0,0]}', "invalid_request", "joints[0][3]: expected a number"),
    ('{"id": 1, "joints": [0,0,0,0,0,0,1e999]}', "invalid_json", "infinity"),
    ('{"id": 1, "joints": [0,0,0,0,0,0,4]}', "out_of_limits", "joints[0][6] (joint7) = 4"),
    ('{"id": 1, "joints": [0,0,0,0,0,0,0], "robot": "ur5"}', "unknown_robot", "'ur5' is not served here"),
    ('{"id": 1, "joints": [0,0,0,0,0,0,0], "colour": "red"}', "invalid_request", "unknown field(s) ['colour']"),
    ('{"id": 1, "joints": [0,0,0,0,0,0,0], "outputs": "all"}', "invalid_request", "outputs"),
    ('{"id": 1, "joints": [0,0,0,0,0,0,0], "tolerances": {"a1": -1, "default": 0}}', "invalid_request", "a1"),
    ('{"id": 1, "joints": [0,0,0,0,0,0,0], "tolerances": {"bogus": 1e-4, "default": 0}}', "invalid_request", "bogus"),
    ('{"id": 1, "joints": [0,0,0,0,0,0,0], "tolerances": {"bogus": -1}}', "invalid_request", "-1 is outside [0, inf)"),
    ('{"id": 1, "joints": [0,0,0,0,0,0,0], "tolerances": {"a1": 1e-4}}', "invalid_request", "no tolerance for"),
    ('{"id": 1, "joints": [0,0,0,0,0,0,0], "tolerances": "current"}', "invalid_request", "no budget"),
    ('{"id": 1, "joints": [0,0,0,0,0,0,0], "tolerances": {"default": 0}}', "invalid_request",
     "tolerances: no parameter has a tolerance"),
    ('{"id": 1, "joints": [0,0,0,0,0,0,0], "tolerances": {"tolerances": {}, "default": 0}}', "invalid_request",
     "tolerances.tolerances: no parameter has a tolerance"),
    ('{"id": 1, "joints": [0,0,0,0,0,0,0], "tolerances": {"a1": 1e-4, "default": 0}, "criteria": ["max"]}',
     "invalid_request", "criteria"),
    ('{"id": 1, "joints": ' + json.dumps([[0] * 7] * 51) + '}', "too_large", "cap of 50"),
    ('{"id": 1, "joints": [0,0,0,0,0,0,0], "pad": "' + "x" * 200_001 + '"}', "too_large", "bytes"),
])
def test_error_paths(service, request_text, code, needle):
    r = ask(service, request_text)
    assert r["ok"] is False and r["error"]["code"] == code and needle in r["error"]["message"]


def test_id_is_echoed_even_when_the_json_is_broken(service):
    r = ask(service, '{"id": "abc", "joints": [NaN]}')
    assert r["id"] == "abc" and r["error"]["code"] == "invalid_json"


def test_the_answer_carries_the_top_level_id_never_a_nested_one(service):
    for req in ('{"zz": {"id": "inner"}, "id": "abc", "joints": [0, 0, 0, 0, 0, 0, 0]}',
                '{"tolerances": {"id": "inner", "a1": -1}, "id": "abc", "joints": [0, 0, 0, 0, 0, 0, 0]}',
                '{"zz": {"id": "inner"}, "id": "abc", "joints": [NaN]}'):
        assert ask(service, req)["id"] == "abc"
    assert ask(service, '{"zz": {"id": "inner"}, "joints": [0, 0, 0, 0, 0, 0, 0]}')["id"] is None


@pytest.mark.parametrize("payload", [None, 5, ["{}"], {"id": 1, "joints": Q}])
def test_a_payload_that_is_not_text_is_an_invalid_request_not_internal(service, payload):
    r = json.loads(service.handle_text(payload))
    jsonschema.validate(r, schema("compute_error_jacobian.response"))
    assert r["id"] is None and r["error"]["code"] == "invalid_request"


def test_out_of_limits_can_be_allowed_and_is_reported(service):
    r = ask(service, {"id": 2, "joints": [Q, [0, 0, 0, 0, 0, 0, 4]], "allow_out_of_limits": True})
    assert r["ok"] and r["out_of_limits"] == [1]
    r = ask(service, {"id": 3, "joints": [[0, 0, 0, 0, 0, 0, 4], Q, [-4, 0, 0, 0, 0, 0, 0]],
                      "allow_out_of_limits": True})
    assert r["ok"] and r["out_of_limits"] == [0, 2]
    assert ask(service, {"id": 4, "joints": [Q, Q]})["out_of_limits"] == []


def test_parse_joints_refuses_what_a_parser_may_let_through(gao):
    """Python's json module reads 1e999 as inf and keeps huge integers; orjson refuses both."""
    from tolerance_ros.services.contracts import ContractError
    from tolerance_ros.services.requests import parse_joints
    for value, needle in (([0] * 6 + [10 ** 400], "joints: a value is too large for a float"),
                          ([[0.0] * 7, [0.0] * 3 + [float("inf")] + [0.0] * 3], "joints[1][3]: not a finite number"),
                          ([[0.0] * 7, [float("nan")] * 7], "joints[1][0]: not a finite number")):
        with pytest.raises(ContractError, match=needle.replace("[", r"\[").replace("]", r"\]")):
            parse_joints(value, gao, Limits(), True)


def test_the_service_follows_a_replaced_model(gao):
    """What it keeps per model is keyed by the model object: a replaced model (or its limits) is seen."""
    svc = ErrorModelService({"gao2023_7dof": gao}, "gao2023_7dof")
    assert ask(svc, {"id": 1, "joints": [0, 0, 0, 0, 0, 0, 3]})["ok"]
    svc.robots.models["gao2023_7dof"] = gao.with_joint_limits([[-1.0, 1.0]] * 7)
    r = ask(svc, {"id": 2, "joints": [0, 0, 0, 0, 0, 0, 3]})
    assert r["error"]["code"] == "out_of_limits" and "[-1, 1]" in r["error"]["message"]


def test_bound_at_a_joint_state_uses_the_current_budget(gao):
    from tolerance_ros.core.budget import load_budget
    from tolerance_ros.core.errors import paper_bound
    svc = ErrorModelService({"gao2023_7dof": gao}, "gao2023_7dof")
    names = list(reversed(gao.joint_names))
    assert svc.bound_at(names, list(reversed(Q))) is None            # no budget yet
    svc.current_budget = load_budget("gao2023_delta2", gao)
    b = svc.bound_at(names, list(reversed(Q)), stamp=12.5)
    J = gao.error_jacobian(np.array([Q])).position
    assert (b["robot"], b["criterion"], b["stamp"]) == ("gao2023_7dof", "paper", 12.5)
    assert b["position_bound_m"] == pytest.approx(paper_bound(J, svc.current_budget.vector_for(gao))[0])
    assert svc.bound_at(["joint1"], [0.0]) is None                   # joints missing


@pytest.mark.parametrize("field, value, needle", [
    ("criterion", ["paper"], "budget.criterion: expected one of"), ("criterion", "banana", "budget.criterion"),
    ("limit_position", float("nan"), "budget.limit_position"), ("robot", "ur5", "budget for robot 'ur5'"),
])
def test_a_budget_that_would_fail_every_bound_is_refused_when_it_arrives(gao, field, value, needle):
    from tolerance_ros.core.budget import load_budget
    from tolerance_ros.services.contracts import ContractError
    svc = ErrorModelService({"gao2023_7dof": gao}, "gao2023_7dof")
    good = load_budget("gao2023_delta2", gao)
    svc.current_budget = good
    bad = load_budget("gao2023_delta2", gao)
    setattr(bad, field, value)
    with pytest.raises(ContractError, match=needle):
        svc.current_budget = bad
    assert svc.current_budget is good and svc.bound_at(gao.joint_names, Q)["criterion"] == "paper"
    with pytest.raises(ValueError, match="criterion: expected one of"):
        svc.bound_at(gao.joint_names, Q, criterion="banana")


def test_a_3pups_joint_at_1e10_with_allow_out_of_limits_is_a_clear_error_not_internal():
    from tolerance_ros.core.models import load_robot
    pups = load_robot("rong2018_3pups")
    svc = ErrorModelService({pups.name: pups}, pups.name)
    q = pups.joint_limits.mean(axis=1)
    q[0] = 1e10
    r = ask(svc, {"id": 1, "joints": q.tolist(), "allow_out_of_limits": True})
    assert r["error"]["code"] == "invalid_request" and "cannot close the platform triangle" in r["error"]["message"]


def test_compact_arrays_are_the_same_numbers(service):
    plain = ask(service, {"id": "p", "joints": [Q, Q], "tolerances": {"default": 0, "a1": 1e-4},
                          "criteria": ["paper"]})
    packed = ask(service, {"id": "p", "joints": [Q, Q], "tolerances": {"default": 0, "a1": 1e-4},
                           "criteria": ["paper"], "arrays": "base64"})
    assert packed["arrays"] == "base64" and set(packed["jacobian"]) == {"dtype", "shape", "data"}
    back = decode_arrays(packed)
    for key in ("poses", "jacobian", "sensitivity"):
        np.testing.assert_array_equal(back[key], np.array(plain[key]))
    np.testing.assert_array_equal(back["bounds"]["position"]["paper"], plain["bounds"]["position"]["paper"])


@pytest.mark.parametrize("field, value, needle", [
    ("tolerances", {"tolerances": [1]}, "tolerances.tolerances: expected an object"),
    ("tolerances", {"tolerances": 5}, "tolerances.tolerances: expected an object"),
    ("tolerances", {"a1": 1e160, "default": 0}, "tolerances.a1: 1e+160 is outside [0, 1]"),
    ("tolerances", {"alpha1": 4.0, "default": 0}, "tolerances.alpha1: 4 is outside [0, 3.14159]"),
    ("tolerances", {"a1": True, "default": 0}, "tolerances.a1: expected a number, got a boolean"),
    ("tolerances", {"default": 0, "free": "a1"}, "tolerances.free: expected a list"),
    ("criteria", [[[["paper"]]]], "criteria: expected names"),
    ("joints", [1e308] * 7, "outside"),
])
def test_bad_input_gets_its_own_code_never_internal(service, field, value, needle):
    req = {"id": "x", "joints": Q, "tolerances": {"default": 0, "a1": 1e-4}, field: value}
    r = ask(service, req)
    assert r["ok"] is False and r["error"]["code"] in ("invalid_request", "out_of_limits"), r
    assert needle in r["error"]["message"]


def test_prismatic_overflow_is_an_error_not_nulls(gao):
    from tolerance_ros.core.models import DHChain
    arm = DHChain("sliders", a=[0.1, 0.1], alpha=[0, 0], d=[0, 0], theta=[0, 0], joint_types=["prismatic"] * 2,
                  joint_limits=[[0, 1], [0, 1]])
    svc = ErrorModelService({"sliders": arm}, "sliders")
    r = json.loads(svc.handle_text(json.dumps({"id": 1, "joints": [1e308, 1e308], "allow_out_of_limits": True,
                                               "tolerances": {"default": 0, "d1": 1e-4}})))
    assert r["ok"] is False and r["error"]["code"] == "invalid_request" and "non-finite" in r["error"]["message"]


def test_duplicate_criteria_count_once_and_the_worst_case_is_capped(gao):
    svc = ErrorModelService({"gao2023_7dof": gao}, "gao2023_7dof", Limits(max_worst_case_poses=100))
    tol = {"default": 0, "a1": 1e-4, "theta2": 1e-4}
    r = ask(svc, {"id": 1, "joints": Q, "tolerances": tol, "criteria": ["worst-case"] * 10000})
    assert r["ok"] and list(r["bounds"]["position"]) == ["worst-case"]
    r = ask(svc, {"id": 2, "joints": [Q] * 101, "tolerances": tol, "criteria": ["paper", "worst-case"]})
    assert r["error"]["code"] == "too_large" and "'worst-case' for 101 configurations" in r["error"]["message"]


def test_robots_from_a_robot_set(gao):
    svc = ErrorModelService(RobotSet(["robot_description"], "robot_description"))
    r = ask(svc, {"id": 1, "joints": Q})
    assert r["error"]["code"] == "unknown_robot" and "waiting for a URDF on robot_description" in r["error"]["message"]
