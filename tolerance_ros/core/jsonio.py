"""JSON encoding shared by the command line and the nodes: numpy values become plain JSON, and
non-finite floats become ``null`` (standard JSON has no NaN or Infinity)."""
from __future__ import annotations

import json
import math

import numpy as np


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
