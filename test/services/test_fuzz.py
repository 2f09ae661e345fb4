"""Fuzzed services (the logic the nodes run): no request escapes, every answer is strict JSON that
validates against the shipped schema, bad input never gets 'internal', and every answer is quick.
bench/bench_fuzz.py runs the same corpus longer and prints the table of the robustness issue."""
import json
import time

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fuzz_corpus import ENCODINGS, allocate_request, encode, jacobian_request
from schemas_helpers import validator
from tolerance_ros.core import interrupt
from tolerance_ros.core.jsonio import loads_strict
from tolerance_ros.services.allocation import AllocatorService, Command, parse_allocate_request, run_allocation
from tolerance_ros.services.contracts import CODES, ContractError, Limits, error_code, error_response, request_id_of
from tolerance_ros.services.error_model import ErrorModelService
from tolerance_ros.services.robots import RobotSet

RESPONSE = validator("compute_error_jacobian.response")
ALLOCATED = validator("allocate_tolerances.response")


@pytest.fixture(scope="module")
def service(gao):
    return ErrorModelService({"gao2023_7dof": gao}, "gao2023_7dof")


@pytest.fixture(scope="module")
def robots(gao):
    return RobotSet([gao], gao)


@settings(max_examples=1000, deadline=None, suppress_health_check=list(HealthCheck))
@given(request=jacobian_request(), how=st.sampled_from(ENCODINGS))
def test_compute_error_jacobian_answers_everything(service, request, how):
    text = encode(request, how)
    t0 = time.perf_counter()
    answer = service.handle_text(text)
    assert time.perf_counter() - t0 < 1.0
    doc = loads_strict(answer)
    RESPONSE.validate(doc)
    if not doc["ok"]:
        assert doc["error"]["code"] in CODES and doc["error"]["code"] != "internal", doc


@settings(max_examples=1000, deadline=None, suppress_health_check=list(HealthCheck))
@given(request=allocate_request(), how=st.sampled_from(ENCODINGS))
def test_allocate_requests_are_parsed_or_refused_with_a_code(robots, request, how):
    text = encode(request, how)
    try:
        job = parse_allocate_request(text, robots, Limits(max_bytes=100_000))
    except ContractError as exc:
        doc = error_response(request_id_of(text), exc)
        json.loads(json.dumps(doc))
        ALLOCATED.validate(doc)
        assert doc["error"]["code"] != "internal"
        return
    assert isinstance(job, Command) or job.limit > 0


@settings(max_examples=6, deadline=None, suppress_health_check=list(HealthCheck))
@given(request=allocate_request(), seed=st.integers(0, 10))
def test_an_accepted_allocation_is_served(robots, request, seed):
    """A request that passes validation can be served: solved, or answered with a documented code."""
    request = {**request, "command": "allocate", "id": "a", "mc_poses": 200, "time_limit": 2.0,
               "limit": request.get("limit") if isinstance(request.get("limit"), float) and request["limit"] > 0
               else 0.0014, "seed": seed}
    try:
        job = parse_allocate_request(json.dumps(request, default=str), robots, Limits())
    except ContractError:
        return
    try:  # under the request's time_limit, as the allocator service runs it
        with interrupt.watching(interrupt.StopToken(job.time_limit_s)):
            doc = run_allocation(job)
    except interrupt.Interrupted as exc:
        doc = error_response(job.id, ContractError("timeout", str(exc)))
    except Exception as exc:
        doc = error_response(job.id, exc)
    ALLOCATED.validate(json.loads(json.dumps(doc)))
    assert doc["ok"] or error_code_of(doc) in ("infeasible", "invalid_request", "timeout"), doc


def error_code_of(doc):
    return doc["error"]["code"]


def test_the_allocator_service_keeps_serving_hostile_text(robots):
    answers = []
    service = AllocatorService(robots, lambda kind, doc: answers.append(doc))
    try:
        corpus = [encode({"id": i, "limit": x}, how) for i, (x, how) in
                  enumerate([(float("nan"), "loose"), (1e308, "strict"), ("x", "strict"), (0.001, "deep"),
                             (0.001, "bytes"), (0.001, "huge"), (0.001, "truncated")])]
        for text in corpus:
            service.handle(text)
        assert len(answers) == len(corpus) and all(not a["ok"] for a in answers)
        assert all(a["error"]["code"] in ("invalid_json", "invalid_request", "too_large") for a in answers)
        service.handle('{"id": "s", "command": "status"}')
        assert answers[-1]["status"] == "status"
    finally:
        service.close()


def test_internal_is_only_for_bugs():
    assert error_code(ZeroDivisionError()) == "internal"
