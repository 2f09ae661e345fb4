"""The accuracy monitor's campaign log, read back.

Campaign log of the accuracy monitor (JSON Lines of events, SI)::

    {"event": "measurement", "seq": 7, "stamp": 12.5, "frame": "tracker", "position": [x, y, z],
     "quaternion": [qx, qy, qz, qw] | null, "target": "A"}  # written the moment it arrives (quaternion
                                                           # null for a measured point; target if named)
    {"event": "paired", "seq": 7, "joint_stamp": 12.49, "joint_names": [...], "joints": [...],
     "pose": "P1" | null, "verdict": "within", ...}           # written when its joint state is known
    {"event": "unpaired", "seq": 8, "reason": "..."}

``seq`` counts from 0 again after each ``{"event": "start", ...}`` (the monitor restarted and appends
to the same log). A second measurement, pairing or non-pairing of one ``seq``, a pairing before its
measurement, a number given as a string, a NaN or Infinity and a line nested deeper than ``MAX_DEPTH``
(checked before the JSON parser sees it) are errors.
"""
from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np

from ...ingest import IngestError, JointOrder, pose_from_values, stamp_seconds
from ...resources import not_a_file
from .csv_format import MAX_POSE, MAX_TARGET
from .measurements import MeasurementError, Measurements
from .text import _check_text, _cut, _lines, _not_utf8, _show

_JSON_TOKEN = re.compile(r'\\.|["\[\]{}]')


MAX_DEPTH = 64      # nesting of one campaign log line



def read_log(path, skip_bad=False) -> Measurements:
    """Measurements (with joints) rebuilt from the accuracy monitor's campaign log (JSON Lines of events:
    ``measurement`` as it arrived, then ``paired`` or ``unpaired``; ``seq`` counts from 0 again after each
    ``start``). Unpaired, rejected and undecided measurements are listed in ``skipped`` with their line and
    reason; a malformed line is an error naming it, or with ``skip_bad`` is listed there too."""
    path = Path(path)
    source = str(path)
    if not path.is_file():
        raise MeasurementError(f"{source}: {not_a_file(path)}")
    meas, pairs, logged, decided, skipped, kinds = {}, {}, {}, {}, [], []
    order, session = None, 0
    with path.open(encoding="utf-8", errors="surrogateescape", newline="") as fh:
        for lineno, line in _lines(fh):
            try:
                bad = _check_text(line)
                if bad is not None:
                    raise MeasurementError(_not_utf8(line, bad))
                if not line.strip():
                    continue
                rec = _json_object(line)
                ev = rec.get("event")
                if ev == "start":
                    session += 1
                    continue
                if ev in ("budget", "calibration", "contact"):   # contacts: ``contact_csv.read_contact_log``
                    continue
                if ev not in ("measurement", "paired", "unpaired"):
                    raise MeasurementError(f"event: expected start, budget, calibration, measurement, paired or "
                                           f"unpaired, got {_brief(ev)}")
                seq = rec.get("seq")
                if type(seq) is not int or seq < 0:
                    raise MeasurementError(f"seq: expected a non-negative integer, got {_brief(seq)}")
                key = (session, seq)
                if ev == "measurement":
                    if key in logged:
                        raise MeasurementError(f"seq: measurement {seq} already logged on line {logged[key][0]}")
                    if "rejected" in rec:
                        logged[key] = (lineno, "rejected")
                        skipped.append({"line": lineno, "seq": seq, "reason": f"rejected: {rec['rejected']}"})
                        continue
                    stamp = stamp_seconds(_number(rec, "stamp"))
                    point = rec.get("quaternion", ()) is None
                    T = pose_from_values(_numbers(rec, "position", 3),
                                         (0.0, 0.0, 0.0, 1.0) if point else _numbers(rec, "quaternion", 4))
                    if kinds and point != kinds[0]:
                        raise MeasurementError("quaternion: points and poses mixed in one log (measurement "
                                               f"{'without' if point else 'with'} an orientation)")
                    kinds.append(point)
                    target = rec.get("target", "")
                    if not isinstance(target, str) or len(target) > MAX_TARGET:
                        raise MeasurementError(f"target: expected a name of at most {MAX_TARGET} characters, got "
                                               f"{_brief(target)}")
                    logged[key] = (lineno, "measured")
                    meas[key] = (stamp, T, target)
                    continue
                if key not in logged:
                    raise MeasurementError(f"seq: no measurement {seq} logged before this {ev} event")
                if logged[key][1] == "rejected":
                    raise MeasurementError(f"seq: measurement {seq} was rejected (line {logged[key][0]})")
                if key in decided:
                    raise MeasurementError(f"seq: measurement {seq} already {decided[key][1]} on line "
                                           f"{decided[key][0]}")
                if ev == "unpaired":
                    decided[key] = (lineno, ev)
                    skipped.append({"line": lineno, "seq": seq, "reason": f"unpaired: {rec.get('reason')}"})
                    continue
                names = rec.get("joint_names")
                if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
                    raise MeasurementError(f"joint_names: expected a list of names, got {_brief(names)}")
                joints = _numbers(rec, "joints", len(names))
                pose = rec.get("pose")
                if pose is not None and (not isinstance(pose, str) or len(pose) > MAX_POSE):
                    raise MeasurementError(f"pose: expected a test pose name of at most {MAX_POSE} characters or "
                                           f"null, got {_brief(pose)}")
                order = order or JointOrder(names)
                try:
                    q = order(names, joints)
                except IngestError as exc:
                    raise MeasurementError(f"joints: {exc}") from None
                decided[key] = (lineno, ev)
                pairs[key] = (q, pose or "")
            except (MeasurementError, IngestError) as exc:
                if not skip_bad:
                    raise MeasurementError(f"{source}, line {lineno}: {exc}") from None
                skipped.append({"line": lineno, "reason": str(exc)})
    for key in meas:
        if key not in decided:
            skipped.append({"line": logged[key][0], "seq": key[1],
                            "reason": "pairing not decided before the log ended"})
    keys = [k for k in meas if k in pairs]
    if not keys:
        raise MeasurementError(f"{source}: no paired measurements"
                               + (f" ({len(skipped)} skipped, the first on line {skipped[0]['line']}: "
                                  f"{skipped[0]['reason']})" if skipped else ""))
    skipped.sort(key=lambda s: s["line"])
    T = np.array([meas[k][1] for k in keys])
    targets = np.array([meas[k][2] for k in keys], dtype=object)
    return Measurements(np.array([meas[k][0] for k in keys]), T, np.array([pairs[k][0] for k in keys]),
                        order.joint_names, np.array([pairs[k][1] for k in keys], dtype=object), np.full(len(keys), -1),
                        not kinds[0], source, skipped, targets if any(targets) else None,
                        np.array([logged[k][0] for k in keys], int))


def _brief(value):
    """A JSON value as a short text for a message."""
    if isinstance(value, (dict, list)):
        return f"a JSON {'object' if isinstance(value, dict) else 'array'}"
    if isinstance(value, str):
        return _show(value)
    return _cut(json.dumps(value))


class _Constant(str):
    """NaN, Infinity or -Infinity in a log line: not JSON, and never a number here."""


def _no_duplicate_keys(pairs):
    obj = {}
    for k, v in pairs:
        if k in obj:
            raise MeasurementError(f"{k}: appears twice in one object")
        obj[k] = v
    return obj


def _nesting(line):
    """Deepest nesting of arrays and objects in a line of JSON (brackets inside strings do not count),
    found without parsing; stops counting past MAX_DEPTH."""
    depth = deepest = 0
    in_string = False
    for m in _JSON_TOKEN.finditer(line):
        t = m.group()
        if t == '"':
            in_string = not in_string
        elif in_string or t[0] == "\\":
            continue
        elif t in "[{":
            depth += 1
            deepest = max(deepest, depth)
            if deepest > MAX_DEPTH:
                break
        else:
            depth -= 1
    return deepest


def _json_object(line):
    """One log line as a dict. Nesting deeper than MAX_DEPTH is rejected before the (recursive) parser
    sees it; NaN and Infinity, repeated keys and anything but an object are errors naming the field."""
    if line.count("[") + line.count("{") > MAX_DEPTH and _nesting(line) > MAX_DEPTH:
        raise MeasurementError(f"nested deeper than {MAX_DEPTH} levels")
    try:
        rec = json.loads(line, parse_constant=_Constant, object_pairs_hook=_no_duplicate_keys)
    except MeasurementError:
        raise
    except json.JSONDecodeError as exc:
        raise MeasurementError(f"not valid JSON ({exc.msg} at character {exc.pos + 1})") from None
    except ValueError as exc:
        raise MeasurementError(f"not valid JSON ({exc})") from None
    if not isinstance(rec, dict):
        raise MeasurementError(f"expected a JSON object, got {_brief(rec)}")
    if "NaN" in line or "Infinity" in line:
        for k, v in rec.items():
            name = next(_constants(v), None)
            if name is not None:
                raise MeasurementError(f"{k}: {name} is not valid JSON (numbers must be finite)")
    return rec


def _constants(value):
    if isinstance(value, _Constant):
        yield str(value)
    elif isinstance(value, (list, dict)):
        for v in (value.values() if isinstance(value, dict) else value):
            yield from _constants(v)


def _field(rec, key):
    if key not in rec:
        raise MeasurementError(f"{key}: missing")
    return rec[key]


def _number(rec, key):
    """A finite JSON number (not a string, not a boolean) of a log record, as a float."""
    v = _field(rec, key)
    if type(v) not in (int, float):
        raise MeasurementError(f"{key}: expected a number, got {_brief(v)}")
    return _finite(key, [v])[0]


def _numbers(rec, key, n):
    """A list of ``n`` finite JSON numbers (not strings, not booleans) of a log record, as floats."""
    v = _field(rec, key)
    if not isinstance(v, list):
        raise MeasurementError(f"{key}: expected a list of {n} numbers, got {_brief(v)}")
    bad = [x for x in v if type(x) not in (int, float)]
    if bad:
        raise MeasurementError(f"{key}: expected numbers, got {_brief(bad[0])}")
    if len(v) != n:
        raise MeasurementError(f"{key}: expected {n} numbers, got {len(v)}")
    return _finite(key, v)


def _finite(key, values):
    try:
        out = [float(x) for x in values]
    except OverflowError:
        out = [math.inf]
    if not all(map(math.isfinite, out)):
        raise MeasurementError(f"{key}: a number beyond the range of a float (not finite)")
    return out

