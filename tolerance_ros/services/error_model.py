"""Logic of the ``compute_error_jacobian`` service and of the predicted bound at the current joint state.

Request fields (SI): ``joints`` (one configuration or a list), ``robot``, ``outputs`` ('position' |
'pose'), ``tolerances`` (parameter -> +-tolerance, or 'current' for the latest budget), ``criteria``,
``allow_out_of_limits``, ``include_jacobian``, ``arrays`` ('json' | 'base64'), ``model`` ('nominal' |
'calibrated': the robot's loaded calibration); see ``schemas/compute_error_jacobian.*.json``.
``"command": "compensate"`` (fields ``joints`` or ``poses``, ``seed``, ``match``, ``model``) is served by
``services/compensation.py``. The work of an accepted request is bounded: at most ``Limits.max_poses``
configurations (``max_worst_case_poses`` with the 'worst-case' criterion), duplicate criteria counted
once, tolerances within physical ranges.
"""
from __future__ import annotations

import numpy as np

from ..core.budget import BudgetError, budget_from_dict
from ..core.compat import vecdot
from ..core.errors import CRITERIA, criterion_bound
from ..core.ingest import IngestError, JointOrder, stamp_seconds
from ..core.jsonio import compact_array, dumps_fast, encode_arrays
from ..core.models.base import CompiledChain, ModelError
from .compensation import COMPENSATE_ONLY, MODELS, compensate_request
from .contracts import (MAX_TOLERANCE, ContractError, Limits, answer_id, check_budget, error_response, number,
                        parse_request)
from .requests import _parse_joints
from .robots import RobotSet

ROWS = ("dx", "dy", "dz", "drx", "dry", "drz")
JACOBIAN_FIELDS = {"robot": ((str,), False), "joints": ((list,), False), "outputs": ((str,), False),
                   "tolerances": ((dict, str), False), "criteria": ((list,), False),
                   "allow_out_of_limits": ((bool,), False), "include_jacobian": ((bool,), False),
                   "arrays": ((str,), False), "command": ((str,), False), "model": ((str,), False),
                   "poses": ((list,), False), "seed": ((list,), False), "match": ((str,), False)}
ARRAYS = ("json", "base64")
_COMPENSATE_ONLY = frozenset(COMPENSATE_ONLY)
_COUNT, _FINITE = np.count_nonzero, np.isfinite


def parse_tolerances(value, model, current_budget=None) -> tuple:
    """(delta (p,), criterion default) from ``"current"`` (the latest budget) or a tolerance object in SI:
    ``{"a1": 1e-4, ...}`` or ``{"tolerances": {...}, "free": [...], "default": 0}``."""
    if value == "current":
        if current_budget is None:
            raise ContractError("invalid_request", "tolerances: 'current' requested, but no budget has been received "
                                                   "on tolerance_budget yet")
        if current_budget.robot not in (None, model.name):
            raise ContractError("invalid_request", f"tolerances: the current budget is for robot "
                                                   f"{current_budget.robot!r}, not {model.name!r}")
        budget = current_budget
    elif isinstance(value, dict):
        nested = "tolerances" in value
        tol = value["tolerances"] if nested else {k: v for k, v in value.items() if k not in ("free", "default")}
        if not isinstance(tol, dict):
            raise ContractError("invalid_request", "tolerances.tolerances: expected an object of parameter -> "
                                                   "tolerance (m or rad)")
        if nested and set(value) - {"tolerances", "free", "default"}:
            raise ContractError("invalid_request", "tolerances: with 'tolerances' inside, only 'free' and 'default' "
                                                   "may stand beside it")
        kinds = dict(zip(model.param_names, model.param_kinds))
        for name, v in tol.items():
            kind = kinds.get(name)
            number(v, f"tolerances.{name[:60]}", 0.0, MAX_TOLERANCE[kind] if kind else None)
        free = value.get("free", [])
        if not isinstance(free, list) or not all(isinstance(n, str) for n in free):
            raise ContractError("invalid_request", "tolerances.free: expected a list of parameter names")
        if not tol and not free:
            field = "tolerances.tolerances" if nested else "tolerances"
            raise ContractError("invalid_request", f"{field}: no parameter has a tolerance; give parameter -> "
                                                   f"tolerance (m or rad), with 'default': 0 for the others")
        data = {"tolerances": tol, "free": free}
        if "default" in value:
            data["default"] = number(value["default"], "tolerances.default")
        try:
            budget = budget_from_dict(data, kinds, "tolerances.")
        except BudgetError as exc:
            raise ContractError("invalid_request", str(exc)[:300]) from None
        problem = budget.problem_for(model)
        if problem:
            raise ContractError("invalid_request", problem[:300])
    else:
        raise ContractError("invalid_request", "tolerances: expected an object of parameter -> tolerance (SI) or 'current'")
    try:
        return budget.vector_for(model), budget.criterion
    except BudgetError as exc:
        raise ContractError("invalid_request", str(exc)[:300]) from None


def parse_criteria(value, n_poses: int, limits: Limits) -> list:
    """The named criteria once each, in their order; 'worst-case' only for up to ``max_worst_case_poses``."""
    if not all(isinstance(c, str) for c in value):
        raise ContractError("invalid_request", f"criteria: expected names from {list(CRITERIA)}")
    criteria = list(dict.fromkeys(value))
    bad = [c[:40] for c in criteria if c not in CRITERIA][:5]
    if bad:
        raise ContractError("invalid_request", f"criteria: unknown {bad}; allowed: {list(CRITERIA)}")
    if "worst-case" in criteria and n_poses > limits.max_worst_case_poses:
        raise ContractError("too_large", f"criteria: 'worst-case' for {n_poses} configurations exceeds the cap of "
                                         f"{limits.max_worst_case_poses} for that criterion")
    return criteria


def jacobian_model(req: dict, robots, calibrations: dict):
    """(robot name, model) of a ``compute_error_jacobian`` request: the nominal model, or with
    ``"model": "calibrated"`` the robot's loaded calibration; refuses another command, the fields of
    ``compensate`` and a request without ``joints``."""
    command = req.get("command", "compute_error_jacobian")
    if command != "compute_error_jacobian":
        raise ContractError("invalid_request", f"command: expected 'compute_error_jacobian' or 'compensate', "
                                               f"got {command[:40]!r}")
    if not _COMPENSATE_ONLY.isdisjoint(req):
        stray = [f for f in COMPENSATE_ONLY if f in req]
        raise ContractError("invalid_request", f"{stray[0]}: only with command 'compensate'")
    if "joints" not in req:
        raise ContractError("invalid_request", "joints: required")
    name, model = robots.select(req.get("robot"))
    which = req.get("model", "nominal")
    if which not in MODELS:
        raise ContractError("invalid_request", f"model: expected one of {list(MODELS)}, got {which[:40]!r}")
    if which == "calibrated":
        if name not in calibrations:
            raise ContractError("invalid_request", f"model: no calibration is loaded for robot {name!r} (node "
                                                   f"parameter 'calibration')")
        model = calibrations[name]
    return name, model


class ErrorModelService:
    """Logic of ``compute_error_jacobian``: text request in, response dict out; never raises.

    robots : a RobotSet (or a {name: model} dict with ``default_robot``); calibrations : {robot name:
    calibrated model} served with ``"model": "calibrated"`` and by ``compensate``.
    """

    def __init__(self, robots, default_robot: str | None = None, limits: Limits | None = None, calibrations=None):
        if not isinstance(robots, RobotSet):
            if default_robot not in robots:
                raise ValueError(f"default robot {default_robot!r} is not among the models {sorted(robots)}")
            specs = list(robots.values())
            robots = RobotSet(specs, robots[default_robot])
        self.robots = robots
        self.calibrations = dict(calibrations or {})
        self.limits = limits or Limits()
        self._budget = None
        self.joint_orders = {}
        self._per_model = {}

    @property
    def models(self) -> dict:
        return self.robots.models

    @property
    def current_budget(self):
        """The latest budget (``tolerances: "current"`` and the predicted bound), or None."""
        return self._budget

    @current_budget.setter
    def current_budget(self, budget):
        """Checked when it arrives (``contracts.check_budget`` against its robot, which must be served):
        ContractError 'invalid_request' or 'unknown_robot' otherwise, and the previous budget stays."""
        if budget is not None:
            robot = getattr(budget, "robot", None)
            if robot not in self.models:
                shown = robot[:80] if isinstance(robot, str) else type(robot).__name__
                raise ContractError("unknown_robot", f"budget for robot {shown!r}, not one of {sorted(self.models)}")
            check_budget(budget, self.models[robot])
        self._budget = budget

    def handle(self, text) -> dict:
        rid = None
        try:
            req = parse_request(text, JACOBIAN_FIELDS, self.limits)
            rid = req["id"]
            return self._serve(req)
        except Exception as exc:  # every failure becomes a response
            return error_response(rid if rid is not None else answer_id(exc, text), exc)

    def handle_text(self, text) -> str:
        """The response to a request, as JSON text (arrays as base64 objects when the request asked)."""
        return dumps_fast(self.handle(text))

    def bound_at(self, names, positions, criterion=None, stamp=0.0):
        """The current budget's predicted bound at a joint state (names in any order, stamp s), as the
        ``predicted_bound`` message: {stamp, robot, model, criterion, position_bound_m, orientation_bound_rad},
        from the calibrated robot (at its tool point) when a calibration of the budget's robot is loaded;
        None without a budget or when the state is unusable (missing joints, non-finite values)."""
        if criterion is not None and criterion not in CRITERIA:
            raise ValueError(f"criterion: expected one of {list(CRITERIA)}, got {criterion!r:.40}")
        budget = self.current_budget
        if budget is None or budget.robot not in self.models:
            return None
        model = self.models[budget.robot]
        order = self.joint_orders.get(budget.robot)
        if order is None or order.joint_names != model.joint_names:
            order = self.joint_orders[budget.robot] = JointOrder(model.joint_names)
        try:
            q = order(names, positions)[None]
            t = stamp_seconds(stamp)
        except IngestError:
            return None
        crit = criterion or budget.criterion
        calibrated = self.calibrations.get(budget.robot)
        EJ = (calibrated or model).error_jacobian(q)
        delta = budget.vector_for(model)
        return {"stamp": t, "robot": budget.robot, "model": "nominal" if calibrated is None else "calibrated",
                "criterion": crit,
                "position_bound_m": float(criterion_bound(EJ.position, delta, crit)[0]),
                "orientation_bound_rad": float(criterion_bound(EJ.orientation, delta, crit)[0])}

    def bound_at_message(self, msg, criterion=None):
        """``bound_at`` for a duck-typed sensor_msgs/JointState."""
        return self.bound_at(msg.name, msg.position, criterion, msg.header.stamp)

    def _serve(self, req) -> dict:
        arrays = req.get("arrays", "json")
        if arrays not in ARRAYS:
            raise ContractError("invalid_request", f"arrays: expected one of {list(ARRAYS)}, got {arrays[:40]!r}")
        if req.get("command") == "compensate":
            resp = compensate_request(req, self.robots, self.calibrations, self.limits)
            return {**(encode_arrays(resp) if arrays == "base64" else resp), "arrays": arrays}
        name, model = jacobian_model(req, self.robots, self.calibrations)
        outputs = req.get("outputs", "pose")
        if outputs not in ("position", "pose"):
            raise ContractError("invalid_request", f"outputs: expected 'position' or 'pose', got {outputs[:40]!r}")
        static = self._static(model)
        q, out = _parse_joints(req["joints"], model, self.limits, req.get("allow_out_of_limits", False),
                               static["bounds"])
        criteria = None
        if "tolerances" in req:
            delta, default_criterion = parse_tolerances(req["tolerances"], model, self.current_budget)
            criteria = parse_criteria(req.get("criteria", ["paper", "rss", "per-axis"]), len(q), self.limits)
        try:
            T, EJ = model.fk_and_jacobian(q)
        except ModelError as exc:
            raise ContractError("invalid_request", f"joints: {str(exc)[:300]}") from None
        rows = 3 if outputs == "position" else 6
        J = EJ.J if rows == 6 else EJ.J[:, :rows]
        P = J[:, :3]
        # the same sums of squares: vecdot costs less per call, einsum less per pose
        sens = np.sqrt(vecdot(P, P, axis=1) if len(q) <= 8 else np.einsum("nip,nip->np", P, P))
        # a serial chain gives finite poses for joints within finite limits; anything else is checked
        if not (out is None and static["finite_chain"]) and (_COUNT(_FINITE(T)) != T.size or
                                                               _COUNT(_FINITE(J)) != J.size):
            raise ContractError("invalid_request", "joints: the configurations give non-finite poses (values too "
                                                   "large for this robot)")
        resp = {"id": req["id"], "ok": True, "robot": name, "n": len(q), "joint_names": list(static["joint_names"]),
                "parameters": list(EJ.names), "units": list(EJ.units), "rows": list(ROWS[:rows]), "poses": T,
                "sensitivity": sens, "out_of_limits": [] if out is None else np.flatnonzero(out.any(axis=1)).tolist()}
        if req.get("include_jacobian", True):
            resp["jacobian"] = J if rows == 6 else np.ascontiguousarray(J)
        if criteria is not None:
            resp["bounds"] = {"position": {c: criterion_bound(EJ.position, delta, c) for c in criteria}}
            if outputs == "pose":
                resp["bounds"]["orientation"] = {c: criterion_bound(EJ.orientation, delta, c) for c in criteria}
            resp["bounds"]["budget_criterion"] = default_criterion
        if arrays == "base64":  # the arrays only: the lists of names need no walk
            for key in ("poses", "sensitivity", "jacobian"):
                if key in resp:
                    resp[key] = compact_array(resp[key])
            for side in ("position", "orientation"):
                if side in resp.get("bounds", ()):
                    resp["bounds"][side] = {c: compact_array(v) for c, v in resp["bounds"][side].items()}
        resp["arrays"] = arrays
        return resp

    def _static(self, model) -> dict:
        """What every request to ``model`` shares, computed once per model object: the joint names, the
        limits widened by 1e-12 (as ``Mechanism.out_of_limits``), as arrays and as lists, and whether it is a
        serial chain with finite parameters and limits (whose poses and Jacobians are finite within them)."""
        entry = self._per_model.get(id(model))
        if entry is None or entry[0] is not model or entry[1] is not model.joint_limits:
            if len(self._per_model) > 32:  # models replaced over time (robot_description) are dropped
                self._per_model.clear()
            lim = model.joint_limits
            lo, hi = lim[:, 0] - 1e-12, lim[:, 1] + 1e-12
            entry = (model, lim, {"joint_names": tuple(model.joint_names),
                                  "bounds": (lo, hi, lo.tolist(), hi.tolist()),
                                  "finite_chain": isinstance(model, CompiledChain) and bool(np.all(np.abs(lim) <= 1e6))
                                  and bool(np.all(np.isfinite(model.nominal)))})
            self._per_model[id(model)] = entry
        return entry[2]
