"""JSON contracts of the two services, shared by the ROS nodes and tests (ROS-free).

Every request is a JSON object with an ``id`` (string or integer) that the response echoes; every
response has ``ok``. Failures carry ``error: {code, message}`` with a stable ``code``:

- ``invalid_json``     the text is not JSON (NaN and Infinity are not JSON either);
- ``invalid_request``  a field is missing, unknown, of the wrong type or length, or not finite;
- ``unknown_robot``    the robot is not one of the configured models;
- ``out_of_limits``    a joint is outside its limits (set ``allow_out_of_limits`` to accept);
- ``too_large``        the request exceeds the configured size cap (bytes or poses);
- ``infeasible``       an allocation problem that has no solution (the message says which constraint);
- ``busy``             the allocator queue is full;
- ``internal``         anything else (a bug; the message says what happened).
The message names the offending field, e.g. ``joints[3]: expected 7 values (joint1..joint7), got 6``.
Units are SI (m, rad) in both directions.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np

from .budget import BudgetError, budget_from_dict
from .errors import CRITERIA, LIMIT_CRITERIA
from .errors import criterion_bound
from .jsonio import dumps_fast, loads_strict
from .models.base import ModelError

CODES = ("invalid_json", "invalid_request", "unknown_robot", "out_of_limits", "too_large", "infeasible", "busy",
         "internal")


class ContractError(Exception):
    """A request that cannot be served; ``code`` is one of CODES."""

    def __init__(self, code: str, message: str):
        super().__init__(message)
        self.code = code
        self.message = message


@dataclass
class Limits:
    """Size caps of a service (configurable per node)."""

    max_bytes: int = 1_000_000
    max_poses: int = 10_000


def error_response(request_id, exc) -> dict:
    """Response dict for an exception (ContractError keeps its code; others are 'internal')."""
    if isinstance(exc, ContractError):
        return {"id": request_id, "ok": False, "error": {"code": exc.code, "message": exc.message}}
    return {"id": request_id, "ok": False, "error": {"code": "internal", "message": f"{type(exc).__name__}: {exc}"}}


def parse_request(text, fields: dict, limits: Limits) -> dict:
    """Parse and check the envelope: size, JSON, object, ``id``, known fields and their JSON types.

    fields : name -> (types tuple, required bool).
    """
    size = len(text.encode() if isinstance(text, str) else text)
    if size > limits.max_bytes:
        raise ContractError("too_large", f"request of {size} bytes exceeds the cap of {limits.max_bytes} bytes")
    try:
        req = loads_strict(text)
    except (ValueError, TypeError) as exc:
        raise ContractError("invalid_json", f"not valid JSON: {exc}") from None
    if not isinstance(req, dict):
        raise ContractError("invalid_request", f"expected a JSON object, got {type(req).__name__}")
    rid = req.get("id")
    if rid is None or isinstance(rid, bool) or not isinstance(rid, (str, int)):
        raise ContractError("invalid_request", "id: required, a string or an integer")
    unknown = sorted(set(req) - set(fields) - {"id"})
    if unknown:
        raise ContractError("invalid_request", f"unknown field(s) {unknown}; allowed: {sorted(fields)}")
    for name, (types, required) in fields.items():
        if name not in req:
            if required:
                raise ContractError("invalid_request", f"{name}: required")
            continue
        v = req[name]
        if isinstance(v, bool) and bool not in types:
            raise ContractError("invalid_request", f"{name}: expected {_names(types)}, got a boolean")
        if not isinstance(v, types):
            raise ContractError("invalid_request", f"{name}: expected {_names(types)}, got {type(v).__name__}")
    return req


def _names(types):
    m = {str: "a string", int: "an integer", float: "a number", list: "a list", dict: "an object", bool: "a boolean",
         type(None): "null"}
    return " or ".join(m.get(t, t.__name__) for t in types)


_ID = re.compile(r'"id"\s*:\s*(?:"((?:[^"\\]|\\.)*)"|(-?\d+)\b)')


def request_id_of(text):
    """Best-effort id of a request that failed to parse (for the error response), else None."""
    try:
        req = loads_strict(text)
        rid = req.get("id") if isinstance(req, dict) else None
        return rid if isinstance(rid, (str, int)) and not isinstance(rid, bool) else None
    except Exception:
        m = _ID.search(text if isinstance(text, str) else text.decode(errors="replace"))
        if not m:
            return None
        return m.group(1) if m.group(1) is not None else int(m.group(2))


def select_robot(req, models: dict, default: str):
    name = req.get("robot", default)
    if name not in models:
        raise ContractError("unknown_robot", f"robot: {name!r} is not configured; available: {sorted(models)}")
    return name, models[name]


def parse_joints(value, model, limits: Limits, allow_out_of_limits: bool) -> np.ndarray:
    """(n, dof) joints from one configuration (list of numbers) or many (list of lists)."""
    if not isinstance(value, list) or not value:
        raise ContractError("invalid_request", "joints: expected a non-empty list (one configuration) or a list of lists")
    rows = value if isinstance(value[0], list) else [value]
    if len(rows) > limits.max_poses:
        raise ContractError("too_large", f"joints: {len(rows)} configurations exceed the cap of {limits.max_poses}")
    dof = model.dof
    for i, r in enumerate(rows):
        if not isinstance(r, list) or len(r) != dof:
            got = len(r) if isinstance(r, list) else type(r).__name__
            raise ContractError("invalid_request", f"joints[{i}]: expected {dof} values ({', '.join(model.joint_names)}), "
                                                   f"got {got}")
        for j, v in enumerate(r):
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                raise ContractError("invalid_request", f"joints[{i}][{j}]: expected a number, got {v!r}")
    q = np.array(rows, dtype=float)
    bad = np.argwhere(~np.isfinite(q))
    if bad.size:
        i, j = bad[0]
        raise ContractError("invalid_request", f"joints[{i}][{j}]: not a finite number")
    out = model.out_of_limits(q)
    if out.any() and not allow_out_of_limits:
        i, j = np.argwhere(out)[0]
        lo, hi = model.joint_limits[j]
        raise ContractError("out_of_limits", f"joints[{i}][{j}] ({model.joint_names[j]}) = {q[i, j]:.6g} is outside "
                                             f"[{lo:.6g}, {hi:.6g}] ({int(out.any(axis=1).sum())} configuration(s) "
                                             f"affected); set allow_out_of_limits to accept")
    return q


def parse_tolerances(value, model, current_budget=None) -> tuple:
    """(delta (p,), criterion default) from ``"current"`` (the latest budget) or a tolerance object in SI:
    ``{"a1": 1e-4, ...}`` or ``{"tolerances": {...}, "free": [...], "default": 0}``."""
    if value == "current":
        if current_budget is None:
            raise ContractError("invalid_request", "tolerances: 'current' requested, but no budget has been received "
                                                   "on tolerance_budget yet")
        budget = current_budget
    elif isinstance(value, dict):
        special = ("tolerances", "free", "default")
        data = {"tolerances": value.get("tolerances", {k: v for k, v in value.items() if k not in special}),
                **{k: value[k] for k in ("free", "default") if k in value}}
        bad = [k for k, v in data.get("tolerances", {}).items()
               if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v)]
        if bad:
            raise ContractError("invalid_request", f"tolerances.{bad[0]}: expected a finite number (m or rad)")
        try:
            budget = budget_from_dict(data, dict(zip(model.param_names, model.param_kinds)), "tolerances.")
        except BudgetError as exc:
            raise ContractError("invalid_request", str(exc)) from None
    else:
        raise ContractError("invalid_request", "tolerances: expected an object of parameter -> tolerance (SI) or 'current'")
    try:
        return budget.vector_for(model), budget.criterion
    except BudgetError as exc:
        raise ContractError("invalid_request", str(exc)) from None


JACOBIAN_FIELDS = {"robot": ((str,), False), "joints": ((list,), True), "outputs": ((str,), False),
                   "tolerances": ((dict, str), False), "criteria": ((list,), False),
                   "allow_out_of_limits": ((bool,), False), "include_jacobian": ((bool,), False)}


class ErrorModelService:
    """Logic of ``compute_error_jacobian``: text request in, response dict out; never raises."""

    def __init__(self, models: dict, default_robot: str, limits: Limits | None = None):
        if default_robot not in models:
            raise ValueError(f"default robot {default_robot!r} is not among the models {sorted(models)}")
        self.models = models
        self.default_robot = default_robot
        self.limits = limits or Limits()
        self.current_budget = None

    def handle(self, text) -> dict:
        rid = None
        try:
            req = parse_request(text, JACOBIAN_FIELDS, self.limits)
            rid = req["id"]
            return self._serve(req)
        except (ContractError, Exception) as exc:  # every failure becomes a response
            return error_response(rid if rid is not None else request_id_of(text), exc)

    def handle_text(self, text) -> str:
        return dumps_fast(self.handle(text))

    def bound_at(self, names, positions, criterion=None):
        """(robot, criterion, position bound m, orientation bound rad) of the current budget at a joint
        state (names in any order), or None without a budget or when joints are missing."""
        budget = self.current_budget
        if budget is None or budget.robot not in self.models:
            return None
        model = self.models[budget.robot]
        names = list(names)
        try:
            q = np.array([[positions[names.index(n)] for n in model.joint_names]], dtype=float)
        except ValueError:
            return None
        if not np.all(np.isfinite(q)):
            return None
        crit = criterion or budget.criterion
        EJ = model.error_jacobian(q)
        delta = budget.vector_for(model)
        return (budget.robot, crit, float(criterion_bound(EJ.position, delta, crit)[0]),
                float(criterion_bound(EJ.orientation, delta, crit)[0]))

    def _serve(self, req) -> dict:
        name, model = select_robot(req, self.models, self.default_robot)
        outputs = req.get("outputs", "pose")
        if outputs not in ("position", "pose"):
            raise ContractError("invalid_request", f"outputs: expected 'position' or 'pose', got {outputs!r}")
        q = parse_joints(req["joints"], model, self.limits, req.get("allow_out_of_limits", False))
        try:
            T, EJ = model.fk_and_jacobian(q)
        except ModelError as exc:
            raise ContractError("invalid_request", f"joints: {exc}") from None
        rows = 3 if outputs == "position" else 6
        J = EJ.J[:, :rows]
        resp = {"id": req["id"], "ok": True, "robot": name, "n": int(len(q)), "joint_names": list(model.joint_names),
                "parameters": list(EJ.names), "units": list(EJ.units),
                "rows": ["dx", "dy", "dz", "drx", "dry", "drz"][:rows], "poses": T,
                "sensitivity": np.sqrt(np.einsum("nkp,nkp->np", J[:, :3], J[:, :3])),
                "out_of_limits": np.flatnonzero(model.out_of_limits(q).any(axis=1)).tolist()}
        if req.get("include_jacobian", True):
            resp["jacobian"] = np.ascontiguousarray(J)
        if "tolerances" in req:
            delta, default_criterion = parse_tolerances(req["tolerances"], model, self.current_budget)
            criteria = req.get("criteria", ["paper", "rss", "per-axis"])
            bad = [c for c in criteria if c not in CRITERIA]
            if bad:
                raise ContractError("invalid_request", f"criteria: unknown {bad}; allowed: {list(CRITERIA)}")
            resp["bounds"] = {"position": {c: criterion_bound(EJ.position, delta, c) for c in criteria}}
            if outputs == "pose":
                resp["bounds"]["orientation"] = {c: criterion_bound(EJ.orientation, delta, c) for c in criteria}
            resp["bounds"]["budget_criterion"] = default_criterion
        return resp


ALLOCATE_FIELDS = {"command": ((str,), False), "robot": ((str,), False), "limit": ((int, float), False),
                   "orientation_limit": ((int, float, type(None)), False), "model": ((str,), False),
                   "solver": ((str,), False), "criterion": ((str,), False), "confidence": ((int, float, type(None)), False),
                   "floors": ((dict,), False), "seed": ((int,), False), "mc_poses": ((int,), False),
                   "ga_tol": ((int,), False), "ga_rounds": ((int,), False)}


def parse_allocate_request(text, models: dict, default_robot: str, limits: Limits) -> dict:
    """Validated allocation job (SI) or a 'status' query; raises ContractError naming the field."""
    from .synthesis import MODELS, SOLVERS
    req = parse_request(text, ALLOCATE_FIELDS, limits)
    command = req.get("command", "allocate")
    if command not in ("allocate", "status"):
        raise ContractError("invalid_request", f"command: expected 'allocate' or 'status', got {command!r}")
    if command == "status":
        return {"id": req["id"], "command": "status"}
    name, model = select_robot(req, models, default_robot)
    if "limit" not in req:
        raise ContractError("invalid_request", "limit: required (position limit in m)")
    job = {"id": req["id"], "command": "allocate", "robot": name, "model_name": model,
           "limit": float(req["limit"]), "orientation_limit": req.get("orientation_limit"),
           "model": req.get("model", "min-cost"), "solver": req.get("solver", "active-set"),
           "criterion": req.get("criterion", "paper"), "confidence": req.get("confidence"),
           "floors": req.get("floors"), "seed": req.get("seed", 0), "mc_poses": req.get("mc_poses", 10000),
           "ga_tol": req.get("ga_tol", 1000), "ga_rounds": req.get("ga_rounds", 50)}
    for field, allowed in (("model", MODELS), ("solver", SOLVERS), ("criterion", LIMIT_CRITERIA)):
        if job[field] not in allowed:
            raise ContractError("invalid_request", f"{field}: expected one of {list(allowed)}, got {job[field]!r}")
    for field in ("limit", "orientation_limit", "confidence"):
        v = job[field]
        if v is not None and not (math.isfinite(v) and v > 0):
            raise ContractError("invalid_request", f"{field}: must be a positive finite number (SI)")
    if job["confidence"] is not None and not 0.785 <= job["confidence"] < 1:
        raise ContractError("invalid_request", "confidence: expected a value in [0.785, 1)")
    for field in ("mc_poses", "ga_tol", "ga_rounds"):
        if job[field] < 1:
            raise ContractError("invalid_request", f"{field}: must be >= 1")
    if job["mc_poses"] > limits.max_poses * 10:
        raise ContractError("too_large", f"mc_poses: {job['mc_poses']} exceeds the cap of {limits.max_poses * 10}")
    floors = job["floors"] or {}
    for k, v in floors.items():
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
            raise ContractError("invalid_request", f"floors.{k}: expected a positive number (m or rad)")
    return job


def run_allocation(job, progress=None) -> dict:
    """Solve an allocation job; the response dict carries the budget (SI) and its verification."""
    from .errors import k_for_confidence
    from .synthesis import SynthesisError, allocate
    model = job["model_name"]
    try:
        k = k_for_confidence(job["confidence"]) if job["confidence"] is not None else 3.0
        res = allocate(model, job["limit"], job["model"], job["solver"], job["criterion"], job["orientation_limit"],
                       job["floors"], k, seed=job["seed"], n_mc=job["mc_poses"], progress=progress,
                       ga_options={"tol_runs": job["ga_tol"], "max_rounds": job["ga_rounds"]}
                       if job["solver"] == "ga" else None)
    except SynthesisError as exc:
        msg = str(exc)
        code = "infeasible" if "infeasible" in msg or "floors above ceilings" in msg else "invalid_request"
        raise ContractError(code, msg) from None
    budget = res.budget(source=f"allocate_tolerances request {job['id']}")
    ver = res.verification
    return {"id": job["id"], "ok": True, "status": "done", "success": res.success, "robot": job["robot"],
            "message": res.message, "time_s": res.time_s, "cost_index": res.cost, "index_I_mm": res.index_I,
            "budget": budget.to_dict(), "warnings": res.warnings,
            "supremum_m": {c: v["position"]["value"] for c, v in ver["supremum"].items()},
            "monte_carlo": {"distribution": ver["monte_carlo"]["distribution"],
                            "pass_rate": ver["monte_carlo"]["position_m"]["pass_rate"],
                            "max_m": ver["monte_carlo"]["position_m"]["max"]}}
