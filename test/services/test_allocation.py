"""allocate_tolerances: the typed job, its validation, the solve, and the allocator's queue, cancel and timeout."""
import json
import threading
import time

import jsonschema
import pytest

from tolerance_ros.testing.schemas import schema
from tolerance_ros.core.synthesis import InfeasibleError
from tolerance_ros.services.allocation import (AllocationJob, AllocatorService, parse_allocate_request,
                                               run_allocation)
from tolerance_ros.services.contracts import ContractError, Limits, error_response
from tolerance_ros.services.jobs import Command
from tolerance_ros.services.robots import RobotSet


@pytest.fixture(scope="module")
def robots(gao):
    return RobotSet([gao], gao)


def parse(text, robots):
    return parse_allocate_request(text, robots, Limits())


def test_allocate_request_parsing(robots, gao):
    job = parse('{"id": "x", "limit": 0.0014}', robots)
    assert isinstance(job, AllocationJob) and job.mechanism is gao and job.robot == "gao2023_7dof"
    assert job.cost_model == "min-cost" and job.solver == "active-set" and job.limit == 0.0014
    assert job.criterion == "worst-case"  # the one that guarantees the limit; the paper's only by name
    assert job.time_limit_s == 300.0
    assert parse_allocate_request('{"id": "x", "limit": 0.0014}', robots, Limits(), 5.0).time_limit_s == 5.0
    jsonschema.validate({"id": "x", "limit": 0.0014}, schema("allocate_tolerances.request"))
    assert parse('{"id": 3, "command": "status"}', robots) == Command(3, "status")
    assert parse('{"id": 4, "command": "cancel", "target": "x"}', robots) == Command(4, "cancel", "x")


@pytest.mark.parametrize("text, code, needle", [
    ('{"id": 1}', "invalid_request", "limit: required"),
    ('{"id": 1, "limit": 0}', "invalid_request", "limit"),
    ('{"id": 1, "limit": 1e308}', "invalid_request", "limit: 1e+308 is outside [0, 10]"),
    ('{"id": 1, "limit": 0.001, "solver": "magic"}', "invalid_request", "solver"),
    ('{"id": 1, "limit": 0.001, "floors": {"angle": -1}}', "invalid_request", "floors.angle"),
    ('{"id": 1, "limit": 0.001, "floors": {"length": 1e-300, "angle": 1e-300}}', "invalid_request", "floors.length"),
    ('{"id": 1, "limit": 0.001, "floors": {"length": 5e-324}}', "invalid_request", "floors.length"),
    ('{"id": 1, "limit": 0.001, "floors": {"wheel": 1e-5}}', "invalid_request", "floors.wheel"),
    ('{"id": 1, "limit": 0.001, "robot": "x"}', "unknown_robot", "'x'"),
    ('{"id": 1, "limit": 0.001, "mc_poses": 10000000}', "too_large", "mc_poses"),
    ('{"id": 1, "limit": 0.001, "mc_poses": 0}', "invalid_request", "mc_poses: 0 is outside [1, inf)"),
    ('{"id": 1, "limit": 0.001, "confidence": 0.5}', "invalid_request", "confidence"),
    ('{"id": 1, "limit": 0.001, "command": "cancel"}', "invalid_request", "target: required"),
    ('{"id": 1, "limit": 0.001, "command": "pause"}', "invalid_request", "command"),
    ('{"id": 1, "limit": 0.001, "seed": -1}', "invalid_request", "seed: -1 is outside"),
    ('{"id": 1, "limit": 0.001, "ga_rounds": 1000000000}', "invalid_request", "ga_rounds"),
    ('{"id": 1, "limit": 0.001, "ga_tol": 1000000000}', "invalid_request", "ga_tol"),
    ('{"id": 1, "limit": 0.001, "time_limit": 1e9}', "invalid_request", "time_limit"),
    ('{"id": 1, "limit": 0.001, "time_limit": 4.9e-324}', "invalid_request",
     "time_limit: 4.94066e-324 is outside [0.1, 3600]"),
    ('{"id": 1, "limit": 0.001, "time_limit": 0}', "invalid_request", "time_limit: 0 is outside [0.1, 3600]"),
    ('{"id": 1, "limit": 0.001, "solver": "ga", "orientation_limit": 0.001}', "invalid_request", "GA handles"),
    ('{"id": 1, "limit": 3.0}', "invalid_request", "a length unit off"),
    ('{"id": 1, "limit": 0.001, "orientation_limit": 1.5}', "invalid_request", "an angle unit off"),
])
def test_bad_requests_are_refused_before_any_work(robots, text, code, needle):
    with pytest.raises(ContractError) as exc:
        parse(text, robots)
    assert exc.value.code == code and needle in exc.value.message


def test_run_allocation_and_infeasible(robots):
    # The 'rss' criterion: the 'paper' one on this arm is solved by test_gao2023 and test_active_set.
    resp = run_allocation(parse('{"id": "a", "limit": 0.0014, "mc_poses": 500, "criterion": "rss"}', robots))
    jsonschema.validate(json.loads(json.dumps(resp)), schema("allocate_tolerances.response"))
    assert resp["status"] == "done" and resp["success"] and resp["budget"]["limit"]["position"] == pytest.approx(0.0014)
    assert resp["supremum_m"]["rss"] <= 0.0014 and resp["shortfalls"] == []
    chk = resp["limit_check"]  # judged by every criterion beside the limit, whatever its own
    assert chk["criterion"] == "rss" and chk["limit_m"] == 0.0014 and chk["rss_m"] == resp["supremum_m"]["rss"]
    assert chk["worst_case_m"] == resp["supremum_m"]["worst-case"] > 0.0014 and chk["worst_case_within"] is False
    assert chk["monte_carlo_pass_rate"] == resp["monte_carlo"]["pass_rate"] and chk["monte_carlo_poses"] == 500
    assert any("'worst-case' criterion" in w and "exceeds the limit 1.4 mm" in w for w in resp["warnings"])
    with pytest.raises(InfeasibleError) as exc:
        run_allocation(parse('{"id": "b", "limit": 0.0014, "criterion": "worst-case"}', robots))
    assert error_response("b", exc.value)["error"]["code"] == "infeasible"


class Outbox:
    """What an AllocatorService emits, with a way to wait for an answer."""

    def __init__(self):
        self.items, self.cond = [], threading.Condition()

    def __call__(self, kind, doc):
        with self.cond:
            self.items.append((kind, doc))
            self.cond.notify_all()

    def wait(self, predicate, timeout=30.0):
        deadline = time.monotonic() + timeout
        with self.cond:
            while True:
                found = [doc for kind, doc in self.items if kind == "response" and predicate(doc)]
                if found:
                    return found[0]
                left = deadline - time.monotonic()
                if left <= 0:
                    raise AssertionError(f"no such answer; got {[d for _, d in self.items]}")
                self.cond.wait(left)


def test_allocator_queues_answers_status_and_cancels_within_a_second(robots):
    out = Outbox()
    service = AllocatorService(robots, out, max_queue=1)
    try:
        service.handle('{"id": "slow", "limit": 0.0014, "mc_poses": 100000}')
        assert wait_running(service, "slow")
        service.handle('{"id": "waiting", "limit": 0.0014}')
        service.handle('{"id": "extra", "limit": 0.0014}')
        assert out.wait(lambda d: d["id"] == "extra")["error"]["code"] == "busy"
        assert out.wait(lambda d: d["id"] == "slow")["status"] == "accepted"
        service.handle('{"id": "s", "command": "status"}')
        status = out.wait(lambda d: d["id"] == "s")
        assert status["running"] == "slow" and status["queued"] == 1
        service.handle('{"id": "c1", "command": "cancel", "target": "waiting"}')
        assert out.wait(lambda d: d["id"] == "waiting" and not d["ok"])["status"] == "cancelled"
        assert out.wait(lambda d: d["id"] == "c1")["target"] == "waiting"
        t0 = time.monotonic()
        service.handle('{"id": "c2", "command": "cancel", "target": "slow"}')
        job = out.wait(lambda d: d["id"] == "slow" and not d["ok"], 5)
        assert time.monotonic() - t0 < 1.0
        assert job["error"]["code"] == "cancelled" and out.wait(lambda d: d["id"] == "c2")["status"] == "cancelled"
        service.handle('{"id": "c3", "command": "cancel", "target": "nothing"}')
        assert out.wait(lambda d: d["id"] == "c3")["error"]["code"] == "invalid_request"
        assert not any(kind == "budget" for kind, _ in out.items)
    finally:
        service.close()


def wait_running(service, job_id, timeout=20.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if service.running is not None and service.running[0].id == job_id:
            return True
        time.sleep(0.01)
    return False


def test_a_timeout_answers_with_the_best_verified_result_so_far(robots, monkeypatch):
    """The solve is held after its first verified result until its time_limit passes (a machine fast enough
    finished this allocation within the limit): the timeout answer carries that result."""
    from tolerance_ros.core import interrupt
    record = interrupt.record_best

    def record_then_wait(result):
        record(result)
        for _ in range(3000):                      # until check() raises at the deadline (30 s at most)
            interrupt.check()
            time.sleep(0.01)
    monkeypatch.setattr(interrupt, "record_best", record_then_wait)
    out = Outbox()
    service = AllocatorService(robots, out)
    try:
        service.handle('{"id": "t", "limit": 0.0014, "criterion": "paper", "time_limit": 3}')
        answer = out.wait(lambda d: d["id"] == "t" and d.get("status") != "accepted", 20)
        assert answer["ok"] is False and answer["status"] == "timeout" and answer["error"]["code"] == "timeout"
        best = answer["best"]
        assert best["verified_by"].startswith("the joint-space search") and best["budget"]["robot"] == "gao2023_7dof"
        assert best["cost_index"] > 0
    finally:
        service.close()


def test_a_request_that_cannot_be_parsed_never_escapes(robots):
    out = Outbox()
    service = AllocatorService(robots, out)
    try:
        for text in ('{"id": "\\ud800", "limit": 1}', '{"a":' * 52500 + '0' + '}' * 52500, b"\xff\xfe",
                     '{"id": 18446744073709551616, x}', '{"id": ' + '9' * 4301 + ', x}', "x" * 200_000):
            service.handle(text)
        answers = [d for k, d in out.items if k == "response"]
        assert len(answers) == 6 and all(not d["ok"] and d["error"]["code"] in ("invalid_json", "too_large",
                                                                                 "invalid_request") for d in answers)
        assert [d["id"] for d in answers] == [None] * 6
    finally:
        service.close()


def test_the_answer_carries_the_top_level_id_never_a_nested_one(robots):
    out = Outbox()
    service = AllocatorService(robots, out)
    try:
        for text in ('{"floors": {"id": "inner", "zz": 1}, "id": "abc", "limit": 0.0014}',
                     '{"zz": {"id": "inner"}, "id": "abc", "limit": 0.0014}', None):
            service.handle(text)
        answers = [d for k, d in out.items if k == "response"]
        assert [(d["id"], d["error"]["code"]) for d in answers] == [("abc", "invalid_request")] * 2 + \
            [(None, "invalid_request")]
    finally:
        service.close()


def test_the_time_limit_holds_for_a_job_that_waits_and_for_a_long_solver_step(robots):
    """From its acceptance, each job is answered within 0.5 s of its time_limit: one queued behind a longer
    job (it waited for the worker), and a worst-case allocation whose check-sample evaluation is one long
    step (it was answered 4 s late)."""
    out = Outbox()
    service = AllocatorService(robots, out)
    try:
        t0 = time.monotonic()
        service.handle('{"id": "long", "limit": 0.005, "criterion": "worst-case", "mc_poses": 200, "time_limit": 3}')
        service.handle('{"id": "queued", "limit": 0.0014, "time_limit": 1}')
        answer = out.wait(lambda d: d["id"] == "queued" and d.get("status") != "accepted", 10)
        assert answer["status"] == "timeout" and "while it waited in the queue" in answer["error"]["message"]
        assert time.monotonic() - t0 < 1.5
        answer = out.wait(lambda d: d["id"] == "long" and d.get("status") != "accepted", 20)
        assert answer["status"] in ("timeout", "done") and time.monotonic() - t0 < 3.5
    finally:
        service.close()


def test_the_finished_jobs_kept_are_bounded(robots):
    from tolerance_ros.services.jobs import MAX_FINISHED
    out = Outbox()
    service = AllocatorService(robots, out, max_queue=MAX_FINISHED + 50)
    try:
        for i in range(MAX_FINISHED + 50):
            service.handle(json.dumps({"id": i, "limit": 0.0014, "time_limit": 0.1}))
        out.wait(lambda d: d["id"] == MAX_FINISHED + 49 and d.get("status") == "timeout", 20)
        assert len(service.done) == MAX_FINISHED and service.done[-1]["id"] == MAX_FINISHED + 49
        service.handle('{"id": "s", "command": "status"}')
        assert len(out.wait(lambda d: d["id"] == "s")["finished"]) == 10
    finally:
        service.close()


def test_the_outbox_holds_each_jobs_latest_progress_and_every_answer_in_order():
    """A publisher that falls behind (the node's timer) holds one progress per job, not every iteration's."""
    from tolerance_ros.services.jobs import Outbox
    box = Outbox()
    box("response", {"id": "a", "status": "accepted"})
    for k in range(10_000):
        box("progress", {"id": "a" if k % 2 else 1, "fraction": k / 10_000})
    box("budget", {"id": "a"})
    box("response", {"id": "a", "status": "done"})
    assert len(box) == 5
    out = box.drain()
    assert [(k, d["id"]) for k, d in out] == [("progress", 1), ("progress", "a"), ("response", "a"), ("budget", "a"),
                                              ("response", "a")]
    assert out[1][1]["fraction"] == 0.9999 and box.drain() == []


def test_no_progress_goes_out_once_a_job_is_answered(robots, monkeypatch):
    """A solve still stopping after its timeout or cancel answer (a long step) says nothing more."""
    from tolerance_ros.core import interrupt
    from tolerance_ros.services import jobs

    def solve(job, progress):
        progress(1, 3)
        entry.answered = True  # the watchdog or a cancel answered meanwhile
        progress(2, 3)
        return {"id": job.id, "ok": True, "status": "done"}

    out = Outbox()
    service = AllocatorService(robots, out)
    try:
        monkeypatch.setattr(service, "run", solve)   # this service's only: an earlier test's worker may still solve
        job = parse('{"id": "p", "limit": 0.0014}', robots)
        entry = jobs._Entry(job, interrupt.StopToken(5.0))
        service._solve(entry)
        assert [d["fraction"] for kind, d in out.items if kind == "progress"] == [1 / 3]
    finally:
        service.close()

