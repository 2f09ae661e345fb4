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

import math
from dataclasses import dataclass

from ..core.budget import limits_problem
from ..core.errors import DEFAULT_LIMIT_CRITERION, LIMIT_CRITERIA, k_for_confidence
from ..core.models.base import Mechanism
from ..core.synthesis import MODELS, PHYSICAL, SOLVERS, allocate
from .contracts import ContractError, Limits, answering, number, parse_request
from .jobs import JobService, command_of

ALLOCATE_FIELDS = {"command": ((str,), False), "robot": ((str,), False), "limit": ((int, float), False),
                   "orientation_limit": ((int, float, type(None)), False), "model": ((str,), False),
                   "solver": ((str,), False), "criterion": ((str,), False), "confidence": ((int, float, type(None)), False),
                   "floors": ((dict,), False), "seed": ((int,), False), "mc_poses": ((int,), False),
                   "ga_tol": ((int,), False), "ga_rounds": ((int,), False), "time_limit": ((int, float), False),
                   "target": ((str, int), False)}
MAX_LIMIT = {"length": 10.0, "angle": math.pi}   # the largest design limits accepted, m and rad
MAX_GA_TOL, MAX_GA_ROUNDS = 10_000, 200
DEFAULT_TIME_LIMIT_S, MIN_TIME_LIMIT_S, MAX_TIME_LIMIT_S = 300.0, 0.1, 3600.0

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
    criterion: str = DEFAULT_LIMIT_CRITERION
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
    command = command_of(req, "allocate")
    if command is not None:
        return command
    name, mechanism = robots.select(req.get("robot"))
    if "limit" not in req:
        raise ContractError("invalid_request", "limit: required (position limit in m)")
    job = AllocationJob(req["id"], name, mechanism,
                        number(req["limit"], "limit", 0.0, MAX_LIMIT["length"]),
                        req.get("orientation_limit"), req.get("model", "min-cost"), req.get("solver", "active-set"),
                        req.get("criterion", DEFAULT_LIMIT_CRITERION), req.get("confidence"), req.get("floors"),
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
    problem = limits_problem(mechanism, job.limit, job.orientation_limit)
    if problem:
        raise ContractError("invalid_request", problem)
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
            "supremum_m": res.position_suprema(),
            "limit_check": res.limit_check(),
            "monte_carlo": {"distribution": ver["monte_carlo"]["distribution"],
                            "pass_rate": ver["monte_carlo"]["position_m"]["pass_rate"],
                            "max_m": ver["monte_carlo"]["position_m"]["max"]}}


class AllocatorService(JobService):
    """Queue, worker and answers of the allocator (see the module docstring and ``jobs.JobService``); ROS-free.

    robots : RobotSet.  emit(kind, doc) : called from the caller's thread, the worker's and the watchdog's.
    save(job, response) -> path or None : stores a finished budget (its path goes into the response).
    """

    KIND = "allocation"

    def __init__(self, robots, emit, limits: Limits | None = None, max_queue: int = 4, save=None,
                 max_time_limit_s: float = MAX_TIME_LIMIT_S):
        self.robots, self.save = robots, save
        self.limits = limits or Limits(max_bytes=100_000)
        self.max_time_limit_s = max_time_limit_s
        super().__init__(emit, max_queue)

    def parse(self, text):
        return parse_allocate_request(text, self.robots, self.limits, self.max_time_limit_s)

    def run(self, job, progress) -> dict:
        return run_allocation(job, progress)

    def deliver(self, job, resp):
        """Save a finished job's budget; put it in force (``budget``) when it meets its limit."""
        if self.save is not None:
            try:
                resp["budget_file"] = str(self.save(job, resp))
            except OSError as exc:
                resp["warnings"].append(f"the budget could not be saved: {exc}")
        if resp["success"]:  # a budget that misses its limit is saved (and says so), not put in force
            self.emit("budget", {"id": job.id, "robot": job.robot, "file": resp.get("budget_file"),
                                 "budget": resp["budget"]})
