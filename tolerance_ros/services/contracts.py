"""The JSON envelope shared by the services: safe parsing, error codes, size caps, budget messages.

Every request is a JSON object with an ``id`` (a string of at most 256 characters, or a 64-bit integer)
that the response echoes; every response has ``ok``. Failures carry ``error: {code, message}`` with a
stable ``code`` (``CODES``):

- ``invalid_json``     the text is not JSON (NaN and Infinity are not JSON either), not UTF-8, or nested
                       deeper than ``MAX_DEPTH``;
- ``invalid_request``  a field is missing, unknown, of the wrong type or length, not finite or out of range;
- ``unknown_robot``    the robot is not one of the node's models (or robot_description has not arrived);
- ``out_of_limits``    a joint is outside its limits (set ``allow_out_of_limits`` to accept);
- ``too_large``        the request exceeds a size cap (bytes, poses, or the work of a criterion);
- ``infeasible``       an allocation problem that has no solution (the message says which constraint);
- ``busy``             the allocator queue is full;
- ``cancelled``        the allocation was cancelled on request;
- ``timeout``          the allocation reached its wall-clock limit (the best verified result comes with it);
- ``internal``         anything else (a bug; the message says what happened).
The message names the offending field, e.g. ``joints[3]: expected 7 values (joint1..joint7), got 6``.
Units are SI (m, rad) in both directions.

Nothing here trusts the text: its size is checked before it is decoded, its nesting depth before it
is parsed (no recursive parser sees a deep document), and the id of a request that cannot be parsed
is recovered from its first 64 KB without parsing it.
"""
from __future__ import annotations

import json
import math
import re
import uuid
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

from ..core.budget import Budget, BudgetError, budget_from_dict
from ..core.errors import LIMIT_CRITERIA
from ..core.ingest import IngestError
from ..core.jsonio import loads_strict
from ..core.models.base import ModelError
from ..core.synthesis.problem import InfeasibleError, SynthesisError
from ..core.units import UnitError

CODES = ("invalid_json", "invalid_request", "unknown_robot", "out_of_limits", "too_large", "infeasible", "busy",
         "cancelled", "timeout", "internal")
MAX_DEPTH = 16          # nesting of arrays and objects in a request
MAX_ID_CHARS = 256
MAX_MESSAGE_CHARS = 500
MAX_TOLERANCE = {"length": 1.0, "angle": math.pi}  # the largest tolerance that makes physical sense, m and rad
_INT64 = 2 ** 63


class ContractError(Exception):
    """A request that cannot be served; ``code`` is one of CODES."""

    def __init__(self, code: str, message: str):
        super().__init__(message)
        self.code = code
        self.message = message


@dataclass
class Limits:
    """Size caps of a service (configurable per node): request bytes, configurations per request,
    configurations per request with the 'worst-case' criterion (O(p^3) per pose), and the targets of a
    ``compensate`` request given as joints or as tool poses (each pose is first solved from 9 starts);
    the compensate caps apply within ``max_poses``."""

    max_bytes: int = 1_000_000
    max_poses: int = 10_000
    max_worst_case_poses: int = 1_000
    max_compensate_joints: int = 1_000
    max_compensate_poses: int = 100


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
    """Response dict for an exception, with the code of ``error_code`` and a bounded message."""
    code = error_code(exc)
    message = exc.message if isinstance(exc, ContractError) else str(exc)
    if code == "internal":
        message = f"{type(exc).__name__}: {exc}"
    if len(message) > MAX_MESSAGE_CHARS:
        message = message[:MAX_MESSAGE_CHARS] + "..."
    return {"id": request_id if valid_id(request_id) else None, "ok": False, "error": {"code": code, "message": message}}


def request_id() -> str:
    """A fresh request id for a client: a uuid4 in hex, unique across processes and hosts (not the process id:
    in containers every process may be PID 1, and two clients would take each other's answers)."""
    return uuid.uuid4().hex


def valid_id(rid) -> bool:
    """True for a request id the response can echo: a short UTF-8 string or a 64-bit integer."""
    if isinstance(rid, bool):
        return False
    if isinstance(rid, int):
        return -_INT64 <= rid < _INT64
    if isinstance(rid, str) and len(rid) <= MAX_ID_CHARS:
        if rid.isascii():
            return True
        try:
            rid.encode("utf-8")
        except UnicodeEncodeError:
            return False
        return True
    return False


def _text(text) -> str:
    """The request as str: bytes must be UTF-8, and a str must be encodable as UTF-8 (no lone surrogates)."""
    if isinstance(text, (bytes, bytearray, memoryview)):
        try:
            return bytes(text).decode("utf-8")
        except UnicodeDecodeError as exc:
            raise ContractError("invalid_json", f"not UTF-8 text: byte {exc.start} is invalid") from None
    return text


def _utf8_size(text: str) -> int:
    try:
        return len(text.encode("utf-8"))
    except UnicodeEncodeError as exc:
        raise ContractError("invalid_json", f"not UTF-8 text: character {exc.start} is a lone surrogate") from None


_STRING = re.compile(r'"(?:[^"\\]|\\.)*"', re.S)
_NOT_BRACKET = bytes(sorted(set(range(256)) - set(b"[]{}")))
_STEPS = bytes.maketrans(b"[{]}", b"\x01\x01\xff\xff")
_NOT_MARK = bytes(sorted(set(range(256)) - set(b'[]{}"\\')))
_SQUARE = bytes.maketrans(b"{}", b"[]")


def nesting_depth(text: str) -> int:
    """Deepest nesting of arrays and objects in JSON text (brackets inside strings do not count; up to
    MAX_DEPTH the count of opening brackets may stand for it, a bound that decides the same), found
    without parsing, in C-speed passes (``bytes.translate`` keeps the brackets and quotes, the strings between
    pairs of quotes are dropped, or with escapes a regular expression drops them, then a cumulative sum)."""
    if len(text) <= 256:
        opening = text.count("[") + text.count("{")
        if opening <= MAX_DEPTH:
            return opening
    marks = text.encode("utf-8", "surrogatepass").translate(None, _NOT_MARK)  # brackets, quotes, backslashes
    if b"\\" not in marks and marks.count(b'"') % 2 == 0:  # the strings are the text between pairs of quotes
        brackets = b"".join(marks.split(b'"')[::2])
    else:
        brackets = "".join(_STRING.split(text)).encode("utf-8", "surrogatepass").translate(None, _NOT_BRACKET)
    if not brackets:
        return 0
    if len(brackets) - brackets.count(b"]") - brackets.count(b"}") <= MAX_DEPTH:  # the openings bound the depth
        return len(brackets) - brackets.count(b"]") - brackets.count(b"}")
    # Balanced brackets: each pass drops the innermost pairs, so a depth of d empties in d passes.
    pairs = brackets.translate(_SQUARE)
    for depth in range(1, MAX_DEPTH + 2):
        shorter = pairs.replace(b"[]", b"")
        if not shorter:
            return depth
        if len(shorter) == len(pairs):
            break  # unbalanced (not JSON): the exact count below
        pairs = shorter
    steps = np.frombuffer(brackets.translate(_STEPS), dtype=np.int8)  # +1 for [ and {, -1 for ] and }
    return int(np.cumsum(steps, dtype=np.int64).max())


def loads(text, limits: "Limits") -> object:
    """Parse a request text safely: its type (text), size, UTF-8, nesting depth, then strict JSON (ContractError
    on any)."""
    if not isinstance(text, (str, bytes, bytearray, memoryview)):
        raise ContractError("invalid_request", f"expected the request as text (str, or bytes of UTF-8), got "
                                               f"{type(text).__name__}")
    size = len(text)
    if type(text) is str and text.isascii():  # the common case: one byte per character, nothing to decode
        if size > limits.max_bytes:
            raise ContractError("too_large", f"request of more than {limits.max_bytes} bytes exceeds the cap")
    else:
        if size > limits.max_bytes or (isinstance(text, str) and size * 4 > limits.max_bytes
                                       and _utf8_size(text) > limits.max_bytes):
            raise ContractError("too_large", f"request of more than {limits.max_bytes} bytes exceeds the cap")
        text = _text(text)
        _utf8_size(text)
    if nesting_depth(text) > MAX_DEPTH:
        raise ContractError("invalid_json", f"nested deeper than {MAX_DEPTH} levels")
    try:
        return loads_strict(text)
    except (ValueError, TypeError, RecursionError) as exc:
        raise ContractError("invalid_json", f"not valid JSON: {str(exc)[:200]}") from None


def parse_request(text, fields: dict, limits: Limits) -> dict:
    """Parse and check the envelope: size, JSON, object, ``id``, known fields and their JSON types.

    fields : name -> (types tuple, required bool).
    """
    if (type(text) is str and len(text) <= limits.max_bytes and text.isascii()
            and nesting_depth(text) <= MAX_DEPTH):  # the checks of ``loads``, for ASCII text within the cap
        try:
            req = loads_strict(text)
        except (ValueError, TypeError, RecursionError):
            req = None  # ``loads`` says why
        else:
            if _envelope_fits(req, fields):
                return req
    req = loads(text, limits)
    if _envelope_fits(req, fields):
        return req
    rid = req.get("id") if isinstance(req, dict) else None
    with answering(rid if valid_id(rid) else None):
        _check_envelope(req, fields)
    return req


_FIELD_TABLES = {}


def _envelope_fits(req, fields) -> bool:
    """True when ``_check_envelope`` would accept ``req``: the same checks, over the request's own fields
    (usually a few) instead of every allowed one; False lets ``_check_envelope`` find the first failure and
    name it, in its order."""
    table = _FIELD_TABLES.get(id(fields))
    if table is None or table[0] is not fields:
        if len(_FIELD_TABLES) > 64:
            _FIELD_TABLES.clear()
        types = {name: t for name, (t, _) in fields.items()}
        table = _FIELD_TABLES[id(fields)] = (fields, types, tuple(name for name, (_, req) in fields.items() if req))
    _, types, required = table
    if type(req) is not dict:
        return False
    rid = req.get("id")
    if type(rid) is str:
        if len(rid) > MAX_ID_CHARS or not rid.isascii():
            return False
    elif type(rid) is not int or not -_INT64 <= rid < _INT64:
        return False
    for name, v in req.items():
        t = types.get(name)
        if t is None:
            if name == "id":
                continue
            return False
        if not isinstance(v, t) or (type(v) is bool and bool not in t) or (type(v) is float and not math.isfinite(v)):
            return False
    for name in required:
        if name not in req:
            return False
    return True


def _check_envelope(req, fields):
    if not isinstance(req, dict):
        raise ContractError("invalid_request", f"expected a JSON object, got {_kind(req)}")
    rid = req.get("id")
    if rid is None or isinstance(rid, bool) or not isinstance(rid, (str, int)):
        raise ContractError("invalid_request", "id: required, a string or an integer")
    if not valid_id(rid):
        raise ContractError("invalid_request", f"id: a string of at most {MAX_ID_CHARS} characters (UTF-8) or a "
                                               f"64-bit integer")
    unknown = sorted(set(req) - set(fields) - {"id"})
    if unknown:
        raise ContractError("invalid_request", f"unknown field(s) {[u[:40] for u in unknown[:10]]}; "
                                               f"allowed: {sorted(fields)}")
    for name, (types, required) in fields.items():
        if name not in req:
            if required:
                raise ContractError("invalid_request", f"{name}: required")
            continue
        v = req[name]
        if isinstance(v, bool) and bool not in types:
            raise ContractError("invalid_request", f"{name}: expected {_names(types)}, got a boolean")
        if not isinstance(v, types):
            raise ContractError("invalid_request", f"{name}: expected {_names(types)}, got {_kind(v)}")
        if isinstance(v, float) and not math.isfinite(v):
            raise ContractError("invalid_request", f"{name}: not a finite number")


@contextmanager
def answering(request_id):
    """Within the body, an exception raised about a parsed request carries ``request_id`` (the id its answer
    echoes, ``answer_id``), unless it already carries one."""
    try:
        yield
    except Exception as exc:
        if not hasattr(exc, "request_id"):
            try:
                exc.request_id = request_id
            except AttributeError:  # an exception type without a __dict__; its answer gets the id from the text
                pass
        raise


def answer_id(exc, text):
    """The id the answer to a failed request echoes: the parsed request's own top-level id (None when it has
    no valid one), or for text that could not be parsed the best guess of ``request_id_of``."""
    if hasattr(exc, "request_id"):
        return exc.request_id
    return request_id_of(text)


def _names(types):
    m = {str: "a string", int: "an integer", float: "a number", list: "a list", dict: "an object", bool: "a boolean",
         type(None): "null"}
    return " or ".join(m.get(t, t.__name__) for t in types)


def _kind(v) -> str:
    """A short description of a JSON value for messages (never its whole repr)."""
    return {dict: "an object", list: "a list", str: "a string", bool: "a boolean", int: "an integer",
            float: "a number", type(None): "null"}.get(type(v), type(v).__name__)


def number(value, field: str, lo: float | None = None, hi: float | None = None, integer: bool = False):
    """A JSON number within [lo, hi] (ContractError 'invalid_request' naming the field otherwise)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or (integer and not isinstance(value, int)):
        raise ContractError("invalid_request", f"{field}: expected {'an integer' if integer else 'a number'}, "
                                               f"got {_kind(value)}")
    if isinstance(value, float) and not math.isfinite(value):
        raise ContractError("invalid_request", f"{field}: not a finite number")
    if (lo is not None and value < lo) or (hi is not None and value > hi):
        bounds = f"{'(-inf' if lo is None else f'[{lo:g}'}, {'inf)' if hi is None else f'{hi:g}]'}"
        raise ContractError("invalid_request", f"{field}: {value:.6g} is outside {bounds}")
    return value


_ID = re.compile(r'\s*:\s*(?:"((?:[^"\\]|\\.){0,256})"|(-?\d{1,19})(?![\d.eE]))')
_TOKEN = re.compile(r'"(?:[^"\\]|\\.)*"|[\[\]{}]')


def request_id_of(text):
    """Best-effort id of a request that could not be parsed, from its first 64 KB (never parsed), else None:
    the value of an ``"id"`` key of the top-level object only (an ``"id"`` inside a nested object is another
    object's)."""
    try:
        head = text[:65536]
        if not isinstance(head, str):
            head = bytes(head).decode("utf-8", errors="replace")
        depth = 0
        for token in _TOKEN.finditer(head):
            t = token.group()
            if t in "[{":
                depth += 1
            elif t in "]}":
                depth -= 1
            elif depth == 1 and t == '"id"':
                m = _ID.match(head, token.end())
                if m:
                    rid = json.loads(f'"{m.group(1)}"') if m.group(1) is not None else int(m.group(2))
                    return rid if valid_id(rid) else None
    except (ValueError, TypeError, KeyError):  # KeyError: a dict (slices are hashable from Python 3.12)
        return None
    return None


def budget_from_message(text, models: dict):
    """(robot name, Budget) from a ``tolerance_budget`` message (JSON ``{"robot", "budget", ...}``, SI),
    checked against its robot's parameters, each tolerance within ``MAX_TOLERANCE``.

    ``models`` maps robot names to models; a budget for another robot raises ContractError
    'unknown_robot', a malformed or incomplete one 'invalid_json' or 'invalid_request'.
    """
    doc = loads(text, Limits())
    if not isinstance(doc, dict) or not isinstance(doc.get("budget"), dict):
        raise ContractError("invalid_request", "budget message: expected an object with 'robot' and 'budget'")
    robot = doc.get("robot")
    if not isinstance(robot, str) or robot not in models:
        shown = robot[:80] if isinstance(robot, str) else _kind(robot)
        raise ContractError("unknown_robot", f"budget message for robot {shown!r}, not one of {sorted(models)}")
    model = models[robot]
    try:
        budget = budget_from_dict(doc["budget"], dict(zip(model.param_names, model.param_kinds)), "budget.")
    except BudgetError as exc:
        raise ContractError("invalid_request", str(exc)[:MAX_MESSAGE_CHARS]) from None
    budget.robot = budget.robot or robot
    check_budget(budget, model)
    return robot, budget


def check_budget(budget, model) -> np.ndarray:
    """The (p,) tolerances (SI) of a budget a service is given for ``model``, once, when it arrives: a Budget
    for that robot, a criterion of ``LIMIT_CRITERIA``, limits that are None or finite and > 0, every
    tolerance finite within [0, ``MAX_TOLERANCE``]. ContractError 'invalid_request' naming the field
    otherwise (so that nothing fails later at every bound)."""
    if not isinstance(budget, Budget):
        raise ContractError("invalid_request", f"budget: expected a Budget, got {type(budget).__name__}")
    if budget.robot is not None and budget.robot != model.name:
        shown = budget.robot[:80] if isinstance(budget.robot, str) else _kind(budget.robot)
        raise ContractError("invalid_request", f"budget.robot: the budget is for robot {shown!r}, not {model.name!r}")
    if not isinstance(budget.criterion, str) or budget.criterion not in LIMIT_CRITERIA:
        shown = budget.criterion[:40] if isinstance(budget.criterion, str) else _kind(budget.criterion)
        raise ContractError("invalid_request", f"budget.criterion: expected one of {list(LIMIT_CRITERIA)}, got "
                                               f"{shown!r}")
    for name in ("limit_position", "limit_orientation"):
        value = getattr(budget, name)
        if value is not None and (isinstance(value, bool) or not isinstance(value, (int, float))
                                  or not math.isfinite(value) or value <= 0):
            raise ContractError("invalid_request", f"budget.{name}: expected None or a finite number > 0, got "
                                                   f"{value!r:.40}")
    try:
        delta = np.asarray(budget.vector_for(model), dtype=float)
    except BudgetError as exc:
        raise ContractError("invalid_request", str(exc)[:MAX_MESSAGE_CHARS]) from None
    except (TypeError, ValueError):
        raise ContractError("invalid_request", "budget.tolerances: expected numbers") from None
    for name, kind, value in zip(model.param_names, model.param_kinds, delta):
        if not 0 <= value <= MAX_TOLERANCE[kind]:  # False for NaN too
            raise ContractError("invalid_request", f"budget.tolerances.{name}: {value:.6g} is outside "
                                                   f"[0, {MAX_TOLERANCE[kind]:g}]")
    problem = budget.problem_for(model, "budget: ")
    if problem:
        raise ContractError("invalid_request", problem[:MAX_MESSAGE_CHARS])
    return delta
