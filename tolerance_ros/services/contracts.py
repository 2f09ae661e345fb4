"""The JSON envelope shared by the services: request parsing, error codes, size caps, budget messages.

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

import json
import re
from dataclasses import dataclass

from ..core.budget import BudgetError, budget_from_dict
from ..core.ingest import IngestError
from ..core.jsonio import loads_strict
from ..core.models.base import ModelError
from ..core.synthesis.problem import InfeasibleError, SynthesisError
from ..core.units import UnitError

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


def error_code(exc) -> str:
    """The response code of an exception, from its type: a ContractError keeps its own; an infeasible
    allocation is 'infeasible'; an invalid model, budget, unit or synthesis input is 'invalid_request';
    anything else is 'internal' (a bug)."""
    if isinstance(exc, ContractError):
        return exc.code
    if isinstance(exc, InfeasibleError):
        return "infeasible"
    if isinstance(exc, (ModelError, BudgetError, UnitError, SynthesisError, IngestError)):
        return "invalid_request"
    return "internal"


def error_response(request_id, exc) -> dict:
    """Response dict for an exception, with the code of ``error_code``."""
    code = error_code(exc)
    message = exc.message if isinstance(exc, ContractError) else str(exc)
    if code == "internal":
        message = f"{type(exc).__name__}: {exc}"
    return {"id": request_id, "ok": False, "error": {"code": code, "message": message}}


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


def budget_from_message(text, models: dict):
    """(robot name, Budget) from a ``tolerance_budget`` message (JSON ``{"robot", "budget", ...}``, SI).

    ``models`` maps robot names to models; a budget for another robot raises ContractError
    'unknown_robot', a malformed one 'invalid_json' or 'invalid_request'.
    """
    try:
        doc = json.loads(text)
    except ValueError as exc:
        raise ContractError("invalid_json", f"budget message is not JSON: {exc}") from None
    if not isinstance(doc, dict) or not isinstance(doc.get("budget"), dict):
        raise ContractError("invalid_request", "budget message: expected an object with 'robot' and 'budget'")
    robot = doc.get("robot")
    if not isinstance(robot, str) or robot not in models:
        raise ContractError("unknown_robot", f"budget message for robot {robot!r}, not one of {sorted(models)}")
    model = models[robot]
    try:
        return robot, budget_from_dict(doc["budget"], dict(zip(model.param_names, model.param_kinds)), "budget.")
    except BudgetError as exc:
        raise ContractError("invalid_request", str(exc)) from None
