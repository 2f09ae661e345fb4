"""Logic of the ``compute_error_jacobian`` service and of the predicted bound at the current joint state.

Request fields (SI): ``joints`` (one configuration or a list), ``robot``, ``outputs`` ('position' |
'pose'), ``tolerances`` (parameter -> +-tolerance, or 'current' for the latest budget), ``criteria``,
``allow_out_of_limits``, ``include_jacobian``, ``model`` ('nominal' | 'calibrated': the robot's loaded
calibration); see ``schemas/compute_error_jacobian.*.json``. ``"command": "compensate"`` (fields
``joints`` or ``poses``, ``seed``, ``match``, ``model``) is served by ``services/compensation.py``.
"""
from __future__ import annotations

import math

import numpy as np

from ..core.budget import BudgetError, budget_from_dict
from ..core.errors import CRITERIA, criterion_bound
from ..core.ingest import IngestError, JointOrder, stamp_seconds
from ..core.jsonio import dumps_fast
from ..core.models.base import ModelError
from .contracts import ContractError, Limits, error_response, parse_request, request_id_of


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


JACOBIAN_FIELDS = {"robot": ((str,), False), "joints": ((list,), False), "outputs": ((str,), False),
                   "tolerances": ((dict, str), False), "criteria": ((list,), False),
                   "allow_out_of_limits": ((bool,), False), "include_jacobian": ((bool,), False),
                   "command": ((str,), False), "model": ((str,), False), "poses": ((list,), False),
                   "seed": ((list,), False), "match": ((str,), False)}


class ErrorModelService:
    """Logic of ``compute_error_jacobian``: text request in, response dict out; never raises."""

    def __init__(self, models: dict, default_robot: str, limits: Limits | None = None, calibrations=None):
        if default_robot not in models:
            raise ValueError(f"default robot {default_robot!r} is not among the models {sorted(models)}")
        self.models = models
        self.calibrations = dict(calibrations or {})  # robot -> calibrated Mechanism
        self.default_robot = default_robot
        self.limits = limits or Limits()
        self.current_budget = None
        self.joint_orders = {}

    def handle(self, text) -> dict:
        rid = None
        try:
            req = parse_request(text, JACOBIAN_FIELDS, self.limits)
            rid = req["id"]
            return self._serve(req)
        except Exception as exc:  # every failure becomes a response
            return error_response(rid if rid is not None else request_id_of(text), exc)

    def handle_text(self, text) -> str:
        return dumps_fast(self.handle(text))

    def bound_at(self, names, positions, criterion=None, stamp=0.0):
        """The current budget's predicted bound at a joint state (names in any order, stamp s), as the
        ``predicted_bound`` message: {stamp, robot, criterion, position_bound_m, orientation_bound_rad};
        None without a budget or when the state is unusable (missing joints, non-finite values)."""
        budget = self.current_budget
        if budget is None or budget.robot not in self.models:
            return None
        model = self.models[budget.robot]
        order = self.joint_orders.setdefault(budget.robot, JointOrder(model.joint_names))
        try:
            q = order(names, positions)[None]
            t = stamp_seconds(stamp)
        except IngestError:
            return None
        crit = criterion or budget.criterion
        EJ = model.error_jacobian(q)
        delta = budget.vector_for(model)
        return {"stamp": t, "robot": budget.robot, "criterion": crit,
                "position_bound_m": float(criterion_bound(EJ.position, delta, crit)[0]),
                "orientation_bound_rad": float(criterion_bound(EJ.orientation, delta, crit)[0])}

    def bound_at_message(self, msg, criterion=None):
        """``bound_at`` for a duck-typed sensor_msgs/JointState."""
        return self.bound_at(msg.name, msg.position, criterion, msg.header.stamp)

    def _serve(self, req) -> dict:
        from .compensation import compensate_request, jacobian_model
        if req.get("command") == "compensate":
            return compensate_request(req, self.models, self.calibrations, self.default_robot, self.limits)
        name, model = jacobian_model(req, self.models, self.calibrations, self.default_robot)
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
