"""The JSON contracts: every error path of both services, and the responses against the shipped schemas."""
import json
from pathlib import Path

import jsonschema
import numpy as np
import pytest

from tolerance_ros.core.synthesis import InfeasibleError
from tolerance_ros.services.allocation import AllocationJob, Command, parse_allocate_request, run_allocation
from tolerance_ros.services.contracts import ContractError, Limits, error_response
from tolerance_ros.services.error_model import ErrorModelService

SCHEMAS = Path(__file__).resolve().parents[2] / "schemas"


def schema(name):
    return json.loads((SCHEMAS / f"{name}.json").read_text())


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
    ('{"id": 1, "joints": [0,0,0,true,0,0,0]}', "invalid_request", "joints[0][3]: expected a number"),
    ('{"id": 1, "joints": [0,0,0,0,0,0,1e999]}', "invalid_json", "infinity"),
    ('{"id": 1, "joints": [0,0,0,0,0,0,4]}', "out_of_limits", "joints[0][6] (joint7) = 4"),
    ('{"id": 1, "joints": [0,0,0,0,0,0,0], "robot": "ur5"}', "unknown_robot", "'ur5' is not configured"),
    ('{"id": 1, "joints": [0,0,0,0,0,0,0], "colour": "red"}', "invalid_request", "unknown field(s) ['colour']"),
    ('{"id": 1, "joints": [0,0,0,0,0,0,0], "outputs": "all"}', "invalid_request", "outputs"),
    ('{"id": 1, "joints": [0,0,0,0,0,0,0], "tolerances": {"a1": -1, "default": 0}}', "invalid_request", "a1"),
    ('{"id": 1, "joints": [0,0,0,0,0,0,0], "tolerances": {"bogus": 1e-4, "default": 0}}', "invalid_request", "bogus"),
    ('{"id": 1, "joints": [0,0,0,0,0,0,0], "tolerances": {"a1": 1e-4}}', "invalid_request", "no tolerance for"),
    ('{"id": 1, "joints": [0,0,0,0,0,0,0], "tolerances": "current"}', "invalid_request", "no budget"),
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


def test_out_of_limits_can_be_allowed_and_is_reported(service):
    r = ask(service, {"id": 2, "joints": [Q, [0, 0, 0, 0, 0, 0, 4]], "allow_out_of_limits": True})
    assert r["ok"] and r["out_of_limits"] == [1]


def test_allocate_request_parsing(gao):
    models = {"gao2023_7dof": gao}
    job = parse_allocate_request('{"id": "x", "limit": 0.0014}', models, "gao2023_7dof", Limits())
    assert isinstance(job, AllocationJob) and job.mechanism is gao and job.robot == "gao2023_7dof"
    assert job.cost_model == "min-cost" and job.solver == "active-set" and job.limit == 0.0014
    jsonschema.validate({"id": "x", "limit": 0.0014}, schema("allocate_tolerances.request"))
    assert parse_allocate_request('{"id": 3, "command": "status"}', models, "gao2023_7dof", Limits()) == \
        Command(3, "status")
    for text, code, needle in [('{"id": 1}', "invalid_request", "limit: required"),
                               ('{"id": 1, "limit": 0}', "invalid_request", "limit"),
                               ('{"id": 1, "limit": 0.001, "solver": "magic"}', "invalid_request", "solver"),
                               ('{"id": 1, "limit": 0.001, "floors": {"angle": -1}}', "invalid_request", "floors.angle"),
                               ('{"id": 1, "limit": 0.001, "robot": "x"}', "unknown_robot", "'x'"),
                               ('{"id": 1, "limit": 0.001, "mc_poses": 10000000}', "too_large", "mc_poses"),
                               ('{"id": 1, "limit": 0.001, "confidence": 0.5}', "invalid_request", "confidence"),
                               ('{"id": 1, "limit": 0.001, "command": "cancel"}', "invalid_request", "command")]:
        with pytest.raises(ContractError) as exc:
            parse_allocate_request(text, models, "gao2023_7dof", Limits())
        assert exc.value.code == code and needle in exc.value.message


def test_run_allocation_and_infeasible(gao):
    models = {"gao2023_7dof": gao}
    job = parse_allocate_request('{"id": "a", "limit": 0.0014, "mc_poses": 500}', models, "gao2023_7dof", Limits())
    resp = run_allocation(job)
    jsonschema.validate(json.loads(json.dumps(resp)), schema("allocate_tolerances.response"))
    assert resp["status"] == "done" and resp["budget"]["limit"]["position"] == pytest.approx(0.0014)
    assert resp["supremum_m"]["paper"] <= 0.0014
    job = parse_allocate_request('{"id": "b", "limit": 0.0014, "criterion": "worst-case"}', models, "gao2023_7dof",
                                 Limits())
    with pytest.raises(InfeasibleError) as exc:
        run_allocation(job)
    assert error_response("b", exc.value)["error"]["code"] == "infeasible"


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
