"""JSON encoding shared by the command line and the nodes: numpy values become plain JSON, and
non-finite floats become ``null`` (standard JSON has no NaN or Infinity).

Compact arrays (opt-in for large answers): ``encode_arrays`` replaces every numpy array by
``{"dtype": "<f8", "shape": [...], "data": "<base64 of the little-endian bytes, C order>"}`` and
``decode_arrays`` turns such objects back into numpy arrays.
"""
from __future__ import annotations

import base64
import json
import math

import numpy as np

try:
    import orjson
except ImportError:  # pragma: no cover - orjson is an install requirement; json is the fallback
    orjson = None


def to_jsonable(obj):
    """Recursively convert numpy arrays/scalars, tuples and non-finite floats to plain JSON values."""
    if isinstance(obj, dict):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        if obj.dtype.kind == "f" and np.all(np.isfinite(obj)):
            return obj.tolist()
        return to_jsonable(obj.tolist())
    if isinstance(obj, (np.bool_,)):
        return bool(obj)
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        f = float(obj)
        return f if math.isfinite(f) else None
    return obj


def dumps(obj, indent=None) -> str:
    """Strict JSON text (``allow_nan=False``) of ``obj`` after ``to_jsonable``."""
    return json.dumps(to_jsonable(obj), indent=indent, allow_nan=False)


def dumps_fast(obj) -> str:
    """Compact strict JSON, fast for large numpy arrays (orjson when installed); NaN/inf become null. An
    int beyond 64 bits, which orjson refuses, is written by the standard library's path instead."""
    if orjson is not None:
        try:
            return orjson.dumps(obj, option=orjson.OPT_SERIALIZE_NUMPY | orjson.OPT_NON_STR_KEYS,
                                default=_default).decode()
        except orjson.JSONEncodeError as exc:
            if "64-bit" not in str(exc):
                raise
    return json.dumps(to_jsonable(obj), allow_nan=False, separators=(",", ":"))


def _default(obj):
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return to_jsonable(obj)
    if isinstance(obj, (set, frozenset)):
        return sorted(obj)
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")


def _reject_constant(name):
    raise ValueError(f"{name} is not valid JSON (use finite numbers)")


def loads_strict(text):
    """Parse JSON text; NaN, Infinity and -Infinity are rejected (ValueError)."""
    if orjson is not None:
        return orjson.loads(text)
    return json.loads(text, parse_constant=_reject_constant)


_ARRAY_KEYS = {"dtype", "shape", "data"}
try:  # the C base64 of pybase64: 8-30x the standard library's speed (bench/bench_service.py); the same text
    import pybase64 as _b64
except ImportError:  # pragma: no cover - pybase64 is a dependency; a ROS install without it still works
    _b64 = base64


def b64encode(data) -> str:
    """Standard base64 (with padding) of the bytes of a C-contiguous array or bytes-like object, as str."""
    raw = np.frombuffer(data, dtype=np.uint8) if not isinstance(data, np.ndarray) else data.reshape(-1).view(np.uint8)
    return _b64.b64encode(raw).decode("ascii")


def b64decode(text) -> np.ndarray:
    """The bytes (a uint8 array) of base64 text, as ``base64.b64decode`` reads it (characters outside the
    alphabet are discarded; binascii.Error for bad padding)."""
    return np.frombuffer(_b64.b64decode(text), dtype=np.uint8)


def compact_array(arr: np.ndarray) -> dict:
    """The compact base64 object of one numpy array (as float64, or int64 for integers and booleans)."""
    arr = np.ascontiguousarray(arr, dtype="<i8" if arr.dtype.kind in "iub" else "<f8")
    return {"dtype": arr.dtype.str, "shape": list(arr.shape), "data": b64encode(arr)}


def encode_arrays(obj):
    """``obj`` with every numpy array replaced by its compact base64 object (float64 or int64)."""
    if isinstance(obj, dict):
        return {k: encode_arrays(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [encode_arrays(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return compact_array(obj)
    return obj


def decode_arrays(obj):
    """``obj`` with every compact array object turned back into a numpy array (see ``encode_arrays``)."""
    if isinstance(obj, dict):
        if obj.keys() == _ARRAY_KEYS and obj["dtype"] in ("<f8", "<i8"):
            return b64decode(obj["data"]).view(obj["dtype"]).reshape(obj["shape"])
        return {k: decode_arrays(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [decode_arrays(v) for v in obj]
    return obj
