"""Logic of the ``allocate_tolerances`` service: request -> typed job -> solved, verified budget (SI).

Request fields: ``limit`` (m, required), ``orientation_limit`` (rad), ``robot``, ``model`` ('min-cost'
| 'optimal-precision'), ``solver`` ('active-set' | 'ga'), ``criterion``, ``confidence``, ``floors``,
``seed``, ``mc_poses``, ``ga_tol``, ``ga_rounds``; or ``{"command": "status"}``. See
``schemas/allocate_tolerances.*.json``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from ..core.errors import LIMIT_CRITERIA, k_for_confidence
from ..core.models.base import Mechanism
from ..core.synthesis import MODELS, SOLVERS, allocate
from .contracts import ContractError, Limits, parse_request, select_robot

COMMANDS = ("allocate", "status")
ALLOCATE_FIELDS = {"command": ((str,), False), "robot": ((str,), False), "limit": ((int, float), False),
                   "orientation_limit": ((int, float, type(None)), False), "model": ((str,), False),
                   "solver": ((str,), False), "criterion": ((str,), False), "confidence": ((int, float, type(None)), False),
                   "floors": ((dict,), False), "seed": ((int,), False), "mc_poses": ((int,), False),
                   "ga_tol": ((int,), False), "ga_rounds": ((int,), False)}


@dataclass(frozen=True)
class Command:
    """A request that is not an allocation: ``command`` is 'status'."""

    id: object
    command: str


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


def parse_allocate_request(text, models: dict, default_robot: str, limits: Limits):
    """An AllocationJob or a Command; raises ContractError naming the field."""
    req = parse_request(text, ALLOCATE_FIELDS, limits)
    command = req.get("command", "allocate")
    if command not in COMMANDS:
        raise ContractError("invalid_request", f"command: expected one of {list(COMMANDS)}, got {command!r}")
    if command != "allocate":
        return Command(req["id"], command)
    name, mechanism = select_robot(req, models, default_robot)
    if "limit" not in req:
        raise ContractError("invalid_request", "limit: required (position limit in m)")
    job = AllocationJob(req["id"], name, mechanism, float(req["limit"]), req.get("orientation_limit"),
                        req.get("model", "min-cost"), req.get("solver", "active-set"), req.get("criterion", "paper"),
                        req.get("confidence"), req.get("floors"), req.get("seed", 0), req.get("mc_poses", 10000),
                        req.get("ga_tol", 1000), req.get("ga_rounds", 50))
    for field, value, allowed in (("model", job.cost_model, MODELS), ("solver", job.solver, SOLVERS),
                                  ("criterion", job.criterion, LIMIT_CRITERIA)):
        if value not in allowed:
            raise ContractError("invalid_request", f"{field}: expected one of {list(allowed)}, got {value!r}")
    for field in ("limit", "orientation_limit", "confidence"):
        v = getattr(job, field)
        if v is not None and not (math.isfinite(v) and v > 0):
            raise ContractError("invalid_request", f"{field}: must be a positive finite number (SI)")
    if job.confidence is not None and not 0.785 <= job.confidence < 1:
        raise ContractError("invalid_request", "confidence: expected a value in [0.785, 1)")
    for field in ("mc_poses", "ga_tol", "ga_rounds"):
        if getattr(job, field) < 1:
            raise ContractError("invalid_request", f"{field}: must be >= 1")
    if job.mc_poses > limits.max_poses * 10:
        raise ContractError("too_large", f"mc_poses: {job.mc_poses} exceeds the cap of {limits.max_poses * 10}")
    for k, v in (job.floors or {}).items():
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
            raise ContractError("invalid_request", f"floors.{k}: expected a positive number (m or rad)")
    return job


def run_allocation(job: AllocationJob, progress=None) -> dict:
    """Solve an allocation job; the response dict carries the budget (SI) and its verification.

    Raises the solver's exceptions (their type gives the response code, ``contracts.error_code``).
    """
    k = k_for_confidence(job.confidence) if job.confidence is not None else 3.0
    res = allocate(job.mechanism, job.limit, job.cost_model, job.solver, job.criterion, job.orientation_limit,
                   job.floors, k, seed=job.seed, n_mc=job.mc_poses, progress=progress,
                   ga_options={"tol_runs": job.ga_tol, "max_rounds": job.ga_rounds} if job.solver == "ga" else None)
    budget = res.budget(source=f"allocate_tolerances request {job.id}")
    ver = res.verification
    return {"id": job.id, "ok": True, "status": "done", "success": res.success, "robot": job.robot,
            "message": res.message, "time_s": res.time_s, "cost_index": res.cost, "index_I_m": res.index_I,
            "budget": budget.to_dict(), "warnings": res.warnings,
            "supremum_m": {c: v["position"]["value"] for c, v in ver["supremum"].items()},
            "monte_carlo": {"distribution": ver["monte_carlo"]["distribution"],
                            "pass_rate": ver["monte_carlo"]["position_m"]["pass_rate"],
                            "max_m": ver["monte_carlo"]["position_m"]["max"]}}
