"""Fuzzed services (the logic the nodes run) and file readers: no request escapes, every answer is strict JSON
that validates against the shipped schema, bad input never gets 'internal', and every answer is quick; every
file reader answers a hostile file with its own error naming the file; the monitor, the budget messages, the
predicted bound, the tracker, robot_description and the joint-state source take or refuse every input.
bench/bench_fuzz.py runs the same corpus longer and prints the figures of the README's Robustness section."""
import json
import time

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tolerance_ros.testing.fuzz_corpus import (ENCODINGS, NESTED_ID, PAYLOADS, UNKNOWN, allocate_request, budget_messages, encode,
                         expected_id, jacobian_request, joint_states, measured_poses, must_refuse, names_twice,
                         json_values, readers, urdf_text)
from helpers import example_urdf
from tolerance_ros.testing.schemas import validator
from tolerance_ros.core import interrupt
from tolerance_ros.core.jsonio import dumps_fast, loads_strict
from tolerance_ros.core.models import ModelError, warm_up_kernels
from tolerance_ros.services.allocation import AllocatorService, parse_allocate_request, run_allocation
from tolerance_ros.services.contracts import CODES, ContractError, Limits, answer_id, error_code, error_response
from tolerance_ros.services.jobs import Command
from tolerance_ros.services.error_model import ErrorModelService
from tolerance_ros.services.robots import RobotSet

RESPONSE = validator("compute_error_jacobian.response")
ALLOCATED = validator("allocate_tolerances.response")


@pytest.fixture(scope="module", autouse=True)
def warm_kernels():
    """The compiled kernels loaded once, as every node does at start: the first call of a fresh process is not
    what the 1 s bound of an answer is about."""
    warm_up_kernels()


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
    assert doc["id"] != NESTED_ID and expected_id(text) in (UNKNOWN, doc["id"]), (doc["id"], text[:200])


@settings(max_examples=1000, deadline=None, suppress_health_check=list(HealthCheck))
@given(request=allocate_request(), how=st.sampled_from(ENCODINGS))
def test_allocate_requests_are_parsed_or_refused_with_a_code(robots, request, how):
    text = encode(request, how)
    try:
        job = parse_allocate_request(text, robots, Limits(max_bytes=100_000))
    except ContractError as exc:
        doc = error_response(answer_id(exc, text), exc)
        json.loads(json.dumps(doc))
        ALLOCATED.validate(doc)
        assert doc["error"]["code"] != "internal"
        assert doc["id"] != NESTED_ID and expected_id(text) in (UNKNOWN, doc["id"]), (doc["id"], text[:200])
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


# ------------------------------------------------------------------ every file reader

READERS = readers()


@pytest.mark.parametrize("name", sorted(READERS))
def test_every_file_reader_answers_hostile_files_with_its_own_error_naming_the_file(name, tmp_path_factory):
    """Mutated files (depth, size, aliases, encodings, wrong types, YAML 1.1 numbers, URDF trees): each is read
    or refused with the reader's own error naming the file, within 1 s; what is read has finite numbers."""
    reader = READERS[name]
    path = tmp_path_factory.mktemp("fuzz") / f"input{reader.suffix}"

    @settings(max_examples=40, deadline=None, suppress_health_check=list(HealthCheck), database=None)
    @given(data=reader.files)
    def fuzz(data):
        path.write_bytes(data)
        t0 = time.perf_counter()
        try:
            result = reader.read(path)
        except reader.error as exc:
            assert str(path) in str(exc), str(exc)
        else:
            assert reader.refuse(data) is None, f"accepted {reader.refuse(data)}"
            reader.check(result)
        assert time.perf_counter() - t0 < 1.0

    fuzz()


# ------------------------------------------------------------------ the other entry points of the services

@pytest.fixture(scope="module")
def budget_doc(gao):
    from tolerance_ros.core.budget import load_budget
    return load_budget("gao2023_delta2", gao).to_dict()


def test_the_monitor_takes_or_refuses_every_joint_state_and_measurement(gao, tmp_path):
    """Joint states with names None, repeated or not text, measurements with lone surrogates in the frame,
    odd stamps and numbers: each is taken or refused and counted; the campaign log stays strict JSON."""
    from tolerance_ros.core.budget import load_budget
    from tolerance_ros.services.monitor import MonitorLogic
    log = tmp_path / "log.jsonl"
    mon = MonitorLogic(gao, load_budget("gao2023_delta2", gao), None, slop=0.05, max_wait=0.0, log_path=log)

    @settings(max_examples=300, deadline=None, suppress_health_check=list(HealthCheck), database=None)
    @given(state=joint_states(), pose=measured_poses())
    def fuzz(state, pose):
        taken, states = mon.counts["joint_states"], mon.counts["joint_states"] + mon.counts["joint_states_rejected"]
        mon.on_joint_state(*state)
        mon.on_pose(*pose)
        mon.resolve()
        c = mon.counts
        assert c["joint_states"] + c["joint_states_rejected"] == states + 1
        assert not (names_twice(state[1]) and c["joint_states"] > taken), "took a joint state naming a joint twice"
        assert c["received"] == c["paired"] + c["unpaired"] + c["rejected"] + len(mon.pending)

    fuzz()
    mon.diagnostic()
    json.loads(dumps_fast(mon.report()))
    mon.close()
    # JSON Lines are split at "\n" only: a frame_id may hold U+2028 or U+0085, which splitlines() also splits at
    assert all(json.loads(line) for line in log.read_text(encoding="utf-8").split("\n") if line)


@settings(max_examples=200, deadline=None, suppress_health_check=list(HealthCheck), database=None)
@given(data=st.data(), state=joint_states())
def test_budget_messages_are_taken_or_refused_when_they_arrive_then_every_bound_works(gao, service, budget_doc, data,
                                                                                     state):
    from tolerance_ros.services.contracts import budget_from_message, check_budget
    from tolerance_ros.services.monitor import MonitorLogic
    text = data.draw(budget_messages(budget_doc))
    try:
        _, budget = budget_from_message(text, service.models)
    except ContractError as exc:
        assert exc.code in CODES and exc.code != "internal"
        return
    check_budget(budget, gao)
    service.current_budget = budget
    MonitorLogic(gao, None, None).set_budget(budget)
    bound = service.bound_at(*state[1:], stamp=state[0])
    if bound is not None:
        assert np.isfinite([bound["position_bound_m"], bound["orientation_bound_rad"], bound["stamp"]]).all()
    service.current_budget = None


@settings(max_examples=200, deadline=None, suppress_health_check=list(HealthCheck), database=None)
@given(state=joint_states())
def test_the_tracker_measures_or_refuses_every_joint_state(gao, state):
    from tolerance_ros.core.ingest import IngestError
    from tolerance_ros.services.tracker import SimulatedTracker
    try:
        T = SimulatedTracker(gao, np.full(gao.n_params, 1e-5)).on_joint_state(state[1], state[2])
    except IngestError:
        return
    assert np.isfinite(T).all() and not names_twice(state[1])


@settings(max_examples=40, deadline=None, suppress_health_check=list(HealthCheck), database=None)
@given(text=urdf_text(example_urdf("ur5_robot.urdf").read_text()))
def test_every_robot_description_is_taken_or_refused_quickly_as_the_same_text_from_a_file(text, tmp_path_factory):
    from tolerance_ros.core.models import URDFChain
    same = tmp_path_factory.mktemp("urdf") / "same.urdf"
    same.write_text(text, encoding="utf-8", errors="surrogatepass")
    try:
        from_file = URDFChain(same, tip_link="tool0") is not None
    except ModelError:
        from_file = False
    robots = RobotSet(["robot_description"], "robot_description", tip_link="tool0")
    t0 = time.perf_counter()
    try:
        robots.on_description(text)
    except (ModelError, ContractError):
        assert robots.single() is None and not from_file
    else:
        assert np.isfinite(robots.single().fk(robots.single().joint_limits.mean(axis=1)[None])).all()
        assert from_file and must_refuse(text.encode("utf-8", "surrogatepass"), "urdf") is None
    assert time.perf_counter() - t0 < 1.0


@pytest.mark.parametrize("payload", PAYLOADS, ids=lambda p: type(p).__name__)
def test_a_payload_that_is_not_text_never_gets_internal(service, robots, payload):
    doc = loads_strict(service.handle_text(payload))
    RESPONSE.validate(doc)
    assert doc["error"]["code"] in ("invalid_request", "invalid_json")
    answers = []
    allocator = AllocatorService(robots, lambda kind, d: answers.append(d))
    try:
        allocator.handle(payload)
    finally:
        allocator.close()
    assert [a["error"]["code"] in ("invalid_request", "invalid_json") for a in answers] == [True]


@settings(max_examples=200, deadline=None, suppress_health_check=list(HealthCheck), database=None)
@given(t=st.floats(allow_nan=False, allow_infinity=False))
def test_the_joint_state_source_gives_a_finite_state_at_every_finite_time(gao, t):
    from tolerance_ros.services.joint_source import JointStateSequence
    step, _, q, _ = JointStateSequence(gao, "random", count=5, dwell=0.5, loop=t > 0).at(t)
    assert 0 <= step < 5 and np.isfinite(q).all()



@pytest.fixture(scope="module")
def contact_monitor(gao):
    """A monitor with a joint state to latch, on a clock that stands still (the state never goes stale)."""
    from tolerance_ros.services.monitor import MonitorLogic
    mon = MonitorLogic(gao, None, None, clock=lambda: 0.0)
    mon.on_joint_state(1.0, list(gao.joint_names), [0.1] * gao.dof)
    return mon


@settings(max_examples=300, deadline=None, suppress_health_check=list(HealthCheck), database=None)
@given(doc=st.dictionaries(st.sampled_from(["contact", "targets", "session", "pose", "id", "speed"]),
                           st.one_of(json_values(), st.sampled_from(["plane:t", "point:p1", "plane:", "line:x"]),
                                     st.lists(st.sampled_from(["A", "B", "", "A,B", "\x00"]), max_size=4),
                                     st.dictionaries(st.sampled_from(["A", "B"]),
                                                     st.lists(st.floats(allow_nan=True), max_size=4)))),
       raw=st.sampled_from(["json", "json", "text"]))
def test_every_contact_request_is_latched_or_answered_with_a_code(contact_monitor, doc, raw):
    """Mutated tolerance/contact requests: each latches rows or is answered invalid_request with the field; the
    monitor keeps taking requests (a valid one afterwards is latched)."""
    ans = contact_monitor.on_contact(json.dumps(doc) if raw == "json" else str(doc))
    assert ans["ok"] or (ans["error"] == "invalid_request" and ans["message"]), ans
    assert contact_monitor.on_contact('{"contact": "plane:t", "targets": ["A"]}')["ok"]
