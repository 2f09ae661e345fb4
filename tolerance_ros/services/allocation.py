"""Logic of the ``allocate_tolerances`` service: request -> typed job -> solved, verified budget (SI).

Request fields: ``limit`` (m, required), ``orientation_limit`` (rad), ``robot``, ``model`` ('min-cost'
| 'optimal-precision'), ``solver`` ('active-set' | 'ga'), ``criterion``, ``confidence``, ``floors``,
``seed``, ``mc_poses``, ``ga_tol``, ``ga_rounds``, ``time_limit`` (s); or ``{"command": "status"}``, or
``{"command": "cancel", "target": <id>}``. See ``schemas/allocate_tolerances.*.json``.

``AllocatorService`` runs the jobs one at a time in a worker thread, with the numerical libraries
capped to one thread: requests are acknowledged at once (``status: accepted``) and queued, ``status``
and ``cancel`` are answered at once, a job is answered ``timeout`` when its ``time_limit`` (in
[``MIN_TIME_LIMIT_S``, the node's maximum], counted from its acceptance) has passed, waiting or running,
and everything it says goes out through ``emit(kind, doc)`` (kind 'response', 'progress' or 'budget').
"""
from __future__ import annotations

import json
import math
import threading
import time
from collections import deque
from dataclasses import dataclass

from ..core import interrupt, threads
from ..core.errors import LIMIT_CRITERIA, k_for_confidence
from ..core.models.base import Mechanism
from ..core.synthesis import MODELS, PHYSICAL, SOLVERS, allocate
from .contracts import ContractError, Limits, answer_id, answering, error_response, number, parse_request, valid_id

COMMANDS = ("allocate", "status", "cancel")
ALLOCATE_FIELDS = {"command": ((str,), False), "robot": ((str,), False), "limit": ((int, float), False),
                   "orientation_limit": ((int, float, type(None)), False), "model": ((str,), False),
                   "solver": ((str,), False), "criterion": ((str,), False), "confidence": ((int, float, type(None)), False),
                   "floors": ((dict,), False), "seed": ((int,), False), "mc_poses": ((int,), False),
                   "ga_tol": ((int,), False), "ga_rounds": ((int,), False), "time_limit": ((int, float), False),
                   "target": ((str, int), False)}
MAX_LIMIT = {"length": 10.0, "angle": math.pi}   # the largest design limits accepted, m and rad
MAX_GA_TOL, MAX_GA_ROUNDS = 10_000, 200
DEFAULT_TIME_LIMIT_S, MIN_TIME_LIMIT_S, MAX_TIME_LIMIT_S = 300.0, 0.1, 3600.0
MAX_FINISHED = 100  # finished jobs the status answer can list (it shows the last 10)


@dataclass(frozen=True)
class Command:
    """A request that is not an allocation: ``command`` is 'status' or 'cancel' (of job ``target``)."""

    id: object
    command: str
    target: object = None


@dataclass(frozen=True)
class AllocationJob:
    """A validated allocation request (SI): the robot's name and its mechanism, the limits and options."""

    id: object
    robot: str
    mechanism: Mechanism
    limit: float
    orientation_limit: float | None = None
    cost_model: str = "min-cost"
    solver: str = "active-set"
    criterion: str = "paper"
    confidence: float | None = None
    floors: dict | None = None
    seed: int = 0
    mc_poses: int = 10000
    ga_tol: int = 1000
    ga_rounds: int = 50
    time_limit_s: float = DEFAULT_TIME_LIMIT_S


def parse_allocate_request(text, robots, limits: Limits, max_time_limit_s: float = MAX_TIME_LIMIT_S):
    """An AllocationJob or a Command; raises ContractError naming the field. ``robots`` is a RobotSet.
    A request without ``time_limit`` gets the default, or ``max_time_limit_s`` when that is smaller."""
    req = parse_request(text, ALLOCATE_FIELDS, limits)
    with answering(req["id"]):
        return _job(req, robots, limits, max_time_limit_s)


def _job(req, robots, limits, max_time_limit_s):
    command = req.get("command", "allocate")
    if command not in COMMANDS:
        raise ContractError("invalid_request", f"command: expected one of {list(COMMANDS)}, got {command[:40]!r}")
    if command == "cancel":
        if "target" not in req or not valid_id(req["target"]):
            raise ContractError("invalid_request", "target: required with command 'cancel': the id of the job")
        return Command(req["id"], command, req["target"])
    if command != "allocate":
        return Command(req["id"], command)
    name, mechanism = robots.select(req.get("robot"))
    if "limit" not in req:
        raise ContractError("invalid_request", "limit: required (position limit in m)")
    job = AllocationJob(req["id"], name, mechanism,
                        number(req["limit"], "limit", 0.0, MAX_LIMIT["length"]),
                        req.get("orientation_limit"), req.get("model", "min-cost"), req.get("solver", "active-set"),
                        req.get("criterion", "paper"), req.get("confidence"), req.get("floors"),
                        number(req.get("seed", 0), "seed", 0, 2 ** 32 - 1, integer=True),
                        number(req.get("mc_poses", 10000), "mc_poses", 1, None, integer=True),
                        number(req.get("ga_tol", 1000), "ga_tol", 1, MAX_GA_TOL, integer=True),
                        number(req.get("ga_rounds", 50), "ga_rounds", 1, MAX_GA_ROUNDS, integer=True),
                        number(req.get("time_limit", min(DEFAULT_TIME_LIMIT_S, max_time_limit_s)), "time_limit",
                               MIN_TIME_LIMIT_S, max_time_limit_s))
    for field, value, allowed in (("model", job.cost_model, MODELS), ("solver", job.solver, SOLVERS),
                                  ("criterion", job.criterion, LIMIT_CRITERIA)):
        if value not in allowed:
            raise ContractError("invalid_request", f"{field}: expected one of {list(allowed)}, got {value[:40]!r}")
    if job.limit <= 0:
        raise ContractError("invalid_request", "limit: must be > 0")
    if job.orientation_limit is not None:
        number(job.orientation_limit, "orientation_limit", 0.0, MAX_LIMIT["angle"])
        if job.orientation_limit <= 0:
            raise ContractError("invalid_request", "orientation_limit: must be > 0 (rad)")
        if job.solver == "ga":
            raise ContractError("invalid_request", "orientation_limit: the paper's GA handles a position limit "
                                                   "only; use the active-set solver")
    if job.confidence is not None:
        number(job.confidence, "confidence", 0.785, 1.0)
        if job.confidence >= 1:
            raise ContractError("invalid_request", "confidence: expected a value in [0.785, 1)")
    if job.mc_poses > limits.max_poses * 10:
        raise ContractError("too_large", f"mc_poses: {job.mc_poses} exceeds the cap of {limits.max_poses * 10}")
    kinds = dict(zip(mechanism.param_names, mechanism.param_kinds))
    for k, v in (job.floors or {}).items():
        kind = k if k in PHYSICAL else kinds.get(k)
        if kind is None:
            raise ContractError("invalid_request", f"floors.{k[:60]}: not 'length', 'angle' or a parameter of "
                                                   f"robot {name!r}")
        number(v, f"floors.{k}", *PHYSICAL[kind])
    return job


def run_allocation(job: AllocationJob, progress=None) -> dict:
    """Solve an allocation job; the response dict carries the budget (SI) and its verification.

    Raises the solver's exceptions (their type gives the response code, ``contracts.error_code``).
    """
    k = k_for_confidence(job.confidence) if job.confidence is not None else 3.0
    res = allocate(job.mechanism, job.limit, job.cost_model, job.solver, job.criterion, job.orientation_limit,
                   job.floors, k, seed=job.seed, n_mc=job.mc_poses, progress=progress,
                   solver_options={"tol_runs": job.ga_tol, "max_rounds": job.ga_rounds} if job.solver == "ga" else None)
    budget = res.budget(source=f"allocate_tolerances request {job.id}")
    ver = res.verification
    return {"id": job.id, "ok": True, "status": "done", "success": res.success, "shortfalls": res.shortfalls(),
            "robot": job.robot, "message": res.message, "time_s": res.time_s, "cost_index": res.cost,
            "index_I_m": res.index_I, "budget": budget.to_dict(), "warnings": res.warnings,
            "supremum_m": {c: v["position"]["value"] for c, v in ver["supremum"].items()},
            "monte_carlo": {"distribution": ver["monte_carlo"]["distribution"],
                            "pass_rate": ver["monte_carlo"]["position_m"]["pass_rate"],
                            "max_m": ver["monte_carlo"]["position_m"]["max"]}}


class Outbox:
    """What an AllocatorService emits, held for a publisher that drains it periodically (the node's timer):
    every response and budget, in order, and of the progress only each job's latest, so that a publisher that
    falls behind holds one progress message per job, not the history of every solver iteration."""

    def __init__(self):
        self._lock = threading.Lock()
        self._items = deque()
        self._progress = {}

    def __call__(self, kind, doc):
        with self._lock:
            if kind == "progress":
                self._progress[json.dumps(doc["id"])] = doc
            else:
                self._items.append((kind, doc))

    def __len__(self):
        with self._lock:
            return len(self._items) + len(self._progress)

    def drain(self) -> list:
        """[(kind, doc)] held since the last drain: the latest progress of each job, then the rest in order."""
        with self._lock:
            out = [("progress", doc) for doc in self._progress.values()] + list(self._items)
            self._progress.clear()
            self._items.clear()
        return out


@dataclass(eq=False)
class _Entry:
    """An accepted job, its stop token (deadline counted from acceptance) and whether its final answer is out."""

    job: AllocationJob
    token: interrupt.StopToken
    answered: bool = False


class AllocatorService:
    """Queue, worker and answers of the allocator (see the module docstring); ROS-free.

    robots : RobotSet.  emit(kind, doc) : called from the caller's thread, the worker's and the watchdog's.
    save(job, response) -> path or None : stores a finished budget (its path goes into the response).

    A job's ``time_limit`` counts from its acceptance, and a watchdog thread answers ``timeout`` at that
    moment (with the best verified result so far) whether the job still waits in the queue or its solve
    is inside a long step; a cancel is answered at once. The worker drops the result of a job that was
    answered meanwhile. What is kept per job ends with the job; the finished list keeps the last
    ``MAX_FINISHED``.
    """

    def __init__(self, robots, emit, limits: Limits | None = None, max_queue: int = 4, save=None,
                 max_time_limit_s: float = MAX_TIME_LIMIT_S):
        self.robots, self.emit, self.save = robots, emit, save
        self.limits = limits or Limits(max_bytes=100_000)
        self.max_time_limit_s = max_time_limit_s
        self.max_queue = int(max_queue)
        self.lock = threading.Condition(threading.RLock())  # emit may call back into the service
        self.queue = deque()      # _Entry of the jobs waiting
        self.current = None       # _Entry of the solve under way
        self.done = deque(maxlen=MAX_FINISHED)
        self.closed = False
        self.worker = threading.Thread(target=self._work, name="allocator", daemon=True)
        self.watchdog = threading.Thread(target=self._watch, name="allocator-watchdog", daemon=True)
        self.worker.start()
        self.watchdog.start()

    @property
    def running(self):
        """(job, StopToken) of the solve under way, or None."""
        entry = self.current
        return None if entry is None else (entry.job, entry.token)

    def busy(self) -> bool:
        """True while a job runs or waits."""
        with self.lock:
            return self.current is not None or bool(self.queue)

    def handle(self, text):
        """Answer one request text (never raises)."""
        try:
            job = parse_allocate_request(text, self.robots, self.limits, self.max_time_limit_s)
        except Exception as exc:  # every failure becomes a response
            self.emit("response", error_response(answer_id(exc, text), exc))
            return
        if isinstance(job, Command):
            self._command(job)
            return
        with self.lock:
            if len(self.queue) >= self.max_queue:
                self.emit("response", error_response(job.id, ContractError(
                    "busy", f"allocator queue is full ({self.max_queue} waiting); retry later")))
                return
            self.queue.append(_Entry(job, interrupt.StopToken(job.time_limit_s)))
            self.emit("response", {"id": job.id, "ok": True, "status": "accepted", "queued": len(self.queue),
                                   "running": self._running_id()})
            self.lock.notify_all()

    def _command(self, cmd: Command):
        with self.lock:
            if cmd.command == "status":
                self.emit("response", {"id": cmd.id, "ok": True, "status": "status", "running": self._running_id(),
                                       "queued": len(self.queue), "finished": list(self.done)[-10:]})
                return
            for entry in ([self.current] if self.current else []) + list(self.queue):
                if entry.job.id == cmd.target and not entry.answered:
                    entry.token.cancel()
                    if entry is not self.current:
                        self.queue.remove(entry)
                    self._finish(entry, {**error_response(entry.job.id, ContractError(
                        "cancelled", f"cancelled by request {cmd.id!r}")), "status": "cancelled"})
                    self.emit("response", {"id": cmd.id, "ok": True, "status": "cancelled", "target": entry.job.id})
                    return
        self.emit("response", error_response(cmd.id, ContractError(
            "invalid_request", f"target: no queued or running allocation has id {cmd.target!r}")))

    def _running_id(self):
        """Id of the job being solved, None when there is none or it is already answered (still stopping)."""
        entry = self.current
        return entry.job.id if entry is not None and not entry.answered else None

    def _finish(self, entry, resp):
        """Send the final answer of a job once (the caller holds the lock)."""
        entry.answered = True
        self.done.append({"id": entry.job.id, "ok": resp["ok"], "status": resp.get("status", "error")})
        self.emit("response", resp)

    def _work(self):
        while True:
            with self.lock:
                while not self.queue and not self.closed:
                    self.lock.wait()
                if self.closed:
                    return
                entry = self.queue.popleft()
                if entry.answered:
                    continue
                self.current = entry
            resp = self._solve(entry)
            with self.lock:
                self.current = None
                if not entry.answered and resp is not None:
                    self._deliver(entry, resp)
                self.lock.notify_all()

    def _deliver(self, entry, resp):
        """Save and publish a finished job's budget and answer it (the caller holds the lock)."""
        job = entry.job
        if resp.get("status") == "done":
            if self.save is not None:
                try:
                    resp["budget_file"] = str(self.save(job, resp))
                except OSError as exc:
                    resp["warnings"].append(f"the budget could not be saved: {exc}")
            if resp["success"]:  # a budget that misses its limit is saved (and says so), not put in force
                self.emit("budget", {"id": job.id, "robot": job.robot, "file": resp.get("budget_file"),
                                     "budget": resp["budget"]})
        self._finish(entry, resp)

    def _watch(self):
        """Answer 'timeout' for every job whose time_limit has passed, waiting or running, on time."""
        with self.lock:
            while not self.closed:
                now = time.monotonic()
                entries = ([self.current] if self.current else []) + list(self.queue)
                for entry in entries:
                    if not entry.answered and entry.token.deadline <= now:
                        waiting = entry is not self.current
                        if waiting:
                            self.queue.remove(entry)
                        where = " while it waited in the queue" if waiting else ""
                        self._finish(entry, {**error_response(entry.job.id, ContractError(
                            "timeout", f"stopped at the wall-clock limit of {entry.job.time_limit_s:g} s{where} "
                                       f"(time_limit)")), "status": "timeout", "best": entry.token.best})
                left = [e.token.deadline for e in entries if not e.answered]
                self.lock.wait(max(0.0, min(left) - time.monotonic()) if left else None)

    def _solve(self, entry):
        """The response to a job; a timeout answer when its solve stopped at the deadline; None when cancelled.
        No progress goes out once the job is answered (while its solve stops)."""
        job, token = entry.job, entry.token
        start = time.perf_counter()

        def progress(done, total):
            if not entry.answered:
                self.emit("progress", {"id": job.id, "fraction": min(1.0, done / max(total, 1)),
                                       "elapsed_s": time.perf_counter() - start})

        try:
            with threads.limited(1), interrupt.watching(token):
                return run_allocation(job, progress)
        except interrupt.Interrupted as exc:
            if exc.reason == "cancelled":
                return None
            return {**error_response(job.id, ContractError("timeout", f"{exc} (time_limit)")), "status": "timeout",
                    "best": token.best}
        except Exception as exc:  # every failure becomes a response; the worker keeps serving
            return error_response(job.id, exc)

    def close(self):
        """Stop the worker and the watchdog: cancel what runs, drop what waits."""
        with self.lock:
            self.closed = True
            if self.current:
                self.current.token.cancel()
            self.queue.clear()
            self.lock.notify_all()
