"""Measurements in and out: CSV files, the accuracy monitor's campaign log (JSON Lines) and rosbag2
recordings (sqlite3 or mcap, read with the ``rosbags`` package).

CSV format: optional ``#`` comment lines, then a header naming each column with its unit in brackets::

    stamp[s],pose,cycle,x[mm],y[mm],z[mm],roll[deg],pitch[deg],yaw[deg],joint:joint1[rad],...

``x y z`` is the measured tool position, ``roll pitch yaw`` its orientation (``R = Rz(yaw) Ry(pitch)
Rx(roll)``; optional, or ``qx qy qz qw`` quaternion columns instead), ``pose`` the test pose name and
``cycle`` its 0-based cycle (both optional), ``joint:<name>`` the joint reading at the measurement
(rad or deg for revolute, m or mm for prismatic). Lengths: m, mm, um; angles: rad, deg, mrad.
The orientation columns come all three or all four, never some of them. A number is what ``float()``
reads from ASCII digits, sign, point and exponent (no ``1_000``, no other digits, no nan or inf), and
must be finite; stamps must not decrease. Files are UTF-8. A row that repeats an earlier row field for
field (the same stamp, pose and values: a measurement written twice) is an error naming both lines.

Every problem is a ``MeasurementError`` naming the file, the line and the column or field. With
``skip_bad`` a bad row or line is skipped instead and listed in ``skipped`` with its reason (a bad
header still stops the read); nothing is dropped silently. A line longer than ``MAX_LINE`` characters
is never held in memory.

Campaign log of the accuracy monitor (JSON Lines of events, SI)::

    {"event": "measurement", "seq": 7, "stamp": 12.5, "frame": "tracker", "position": [x, y, z],
     "quaternion": [qx, qy, qz, qw]}                        # written the moment it arrives
    {"event": "paired", "seq": 7, "joint_stamp": 12.49, "joint_names": [...], "joints": [...],
     "pose": "P1" | null, "verdict": "within", ...}           # written when its joint state is known
    {"event": "unpaired", "seq": 8, "reason": "..."}

``seq`` counts from 0 again after each ``{"event": "start", ...}`` (the monitor restarted and appends
to the same log). A second measurement, pairing or non-pairing of one ``seq``, a pairing before its
measurement, a number given as a string, a NaN or Infinity and a line nested deeper than ``MAX_DEPTH``
(checked before the JSON parser sees it) are errors.
"""
from __future__ import annotations

import csv
import json
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..geometry import matrices_to_quat, quat_to_matrices, rpy_from_matrix, rpy_to_matrices
from ..ingest import IngestError, JointOrder, pair_by_stamp, pose_from_values, stamp_seconds
from ..units import ANGLE_UNITS, LENGTH_UNITS

_COL = re.compile(r"^\s*([A-Za-z_][\w:.\-/]*)\s*(?:\[\s*([^\]]*)\s*\])?\s*$")
_NOT_NUMERIC = re.compile(r"[^0-9eE.+\- \t]")  # a number is what float() takes from these characters
_UNDECODED = re.compile("[\udc80-\udcff]")       # a byte that is not UTF-8, as surrogateescape decodes it
_JSON_TOKEN = re.compile(r'\\.|["\[\]{}]')

MAX_LINE = 1 << 20  # characters in one line of a CSV file or a campaign log
MAX_DEPTH = 64      # nesting of one campaign log line


class MeasurementError(ValueError):
    """A measurement file or message that cannot be read; the message gives its position."""


@dataclass
class Measurements:
    """Measured tool poses (SI) with their stamps, optional joints and test-pose labels."""

    stamps: np.ndarray
    T: np.ndarray
    joints: np.ndarray | None = None
    joint_names: tuple = ()
    pose: np.ndarray | None = None
    cycle: np.ndarray | None = None
    has_orientation: bool = True
    source: str = ""
    skipped: list = field(default_factory=list)

    def __len__(self):
        return len(self.stamps)


def _show(text, n=40):
    """repr of ``text``, cut to about ``n`` characters."""
    return repr(text) if len(text) <= n else repr(text[:n]) + f"... ({len(text)} characters)"


def _cut(text, n=40):
    return text if len(text) <= n else text[:n] + "..."


def _lines(fh):
    """(line number, text) of each line of a text file opened with ``errors="surrogateescape"``; the text
    is None for a line longer than MAX_LINE characters, which is not kept in memory."""
    lineno = 0
    while True:
        line = fh.readline(MAX_LINE + 1)
        if not line:
            return
        lineno += 1
        if len(line) > MAX_LINE:
            while line and line[-1] not in "\r\n":
                line = fh.readline(MAX_LINE)
            yield lineno, None
            continue
        if lineno == 1 and line.startswith("\ufeff"):
            line = line[1:]
        yield lineno, line


def _check_text(line):
    """Index of the first character of ``line`` that stands for a byte that is not UTF-8, or None;
    MeasurementError for a line that was too long (None)."""
    if line is None:
        raise MeasurementError(f"line longer than {MAX_LINE} characters")
    if not line.isascii():
        bad = _UNDECODED.search(line)
        if bad:
            return bad.start()
    return None


def _not_utf8(line, pos):
    return f"byte 0x{ord(line[pos]) - 0xdc00:02x} at character {pos + 1} is not UTF-8"


def _csv_row(line, spec):
    """Fields of one CSV line (split at commas when nothing is quoted)."""
    if '"' not in line:
        return line.rstrip("\r\n").split(",")
    try:
        return next(csv.reader([line]))
    except csv.Error as exc:
        limit = csv.field_size_limit()
        k = next((i for i, f in enumerate(line.split(",")) if len(f) > limit), None)
        if k is None:
            raise MeasurementError(f"not a CSV row ({exc})") from None
        name = next((n for n, (i, _) in spec.cols.items() if i == k), None) if spec else None
        raise MeasurementError(f"{name or f'column {k + 1}'}: longer than {limit} characters") from None


def _parse_header(header, source):
    cols = {}
    for i, h in enumerate(header):
        m = _COL.match(h)
        if not m:
            raise MeasurementError(f"{source}: header column {i + 1} {_show(h)} is not 'name[unit]'")
        name, unit = m.group(1), (m.group(2) or "").strip()
        if name in cols:
            raise MeasurementError(f"{source}: column {name!r} appears twice")
        cols[name] = (i, unit)
    return cols


def _scale(name, unit, kinds, source):
    if kinds == "length":
        if unit not in LENGTH_UNITS:
            raise MeasurementError(f"{source}: column {name!r} needs a length unit in brackets "
                                   f"({', '.join(sorted(LENGTH_UNITS))}), got {unit!r}")
        return LENGTH_UNITS[unit]
    if kinds == "angle":
        if unit not in ANGLE_UNITS:
            raise MeasurementError(f"{source}: column {name!r} needs an angle unit in brackets "
                                   f"({', '.join(sorted(ANGLE_UNITS))}), got {unit!r}")
        return ANGLE_UNITS[unit]
    raise MeasurementError(f"{source}: column {name!r}: unknown quantity")


def read_csv(path, skip_bad: bool = False, chunk_rows: int | None = None):
    """Measurements from a CSV file (see the module docstring).

    With ``chunk_rows`` it yields ``Measurements`` of at most that many rows (constant memory);
    otherwise it returns one ``Measurements``.
    """
    gen = _read_csv_chunks(Path(path), skip_bad, chunk_rows or 0)
    if chunk_rows:
        return gen
    parts = list(gen)
    m = concat(parts) if parts else None
    if m is None or len(m) == 0:
        bad = m.skipped if m is not None else []
        raise MeasurementError(f"{path}: no measurements"
                               + (f" ({len(bad)} bad row(s) skipped, the first on line {bad[0]['line']}: "
                                  f"{bad[0]['reason']})" if bad else ""))
    return m


_TIME_UNITS = {"": 1.0, "s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
_RPY, _QUAT = ("roll", "pitch", "yaw"), ("qx", "qy", "qz", "qw")


@dataclass
class _Spec:
    """What the header says: column indices and the scale of each numeric column to SI."""

    ncols: int
    cols: dict
    orientation: str | None   # 'rpy', 'quat' or None
    num_cols: list            # stamp, x, y, z, then the orientation and joint columns
    num_names: list
    scale: np.ndarray
    joint_names: tuple

    def rotations_and_joints(self, A):
        """(n, 3, 3) rotations (None without orientation; ValueError for a zero quaternion) and (n, dof)
        joint values of numeric rows ``A`` in SI."""
        if self.orientation == "rpy":
            return rpy_to_matrices(A[:, 4:7]), A[:, 7:]
        if self.orientation == "quat":
            return quat_to_matrices(A[:, 4:8]), A[:, 8:]
        return None, A[:, 4:]


def _spec_from_header(header, source):
    cols = _parse_header(header, source)
    missing = [c for c in ("stamp", "x", "y", "z") if c not in cols]
    if missing:
        raise MeasurementError(f"{source}: missing column(s) {missing}; header is {header}")
    rpy, quat = [c for c in _RPY if c in cols], [c for c in _QUAT if c in cols]
    for have, group in ((rpy, _RPY), (quat, _QUAT)):
        if have and len(have) < len(group):
            raise MeasurementError(f"{source}: orientation needs all of {', '.join(group)}; missing column(s) "
                                   f"{[c for c in group if c not in have]}")
    if rpy and quat:
        raise MeasurementError(f"{source}: give the orientation as roll, pitch, yaw or as qx, qy, qz, qw, not both")
    if cols["stamp"][1] not in _TIME_UNITS:
        raise MeasurementError(f"{source}: column 'stamp' needs a time unit (s, ms, us, ns), "
                               f"got {cols['stamp'][1]!r}")
    names = ["stamp", "x", "y", "z"]
    scale = [_TIME_UNITS[cols["stamp"][1]]] + [_scale(c, cols[c][1], "length", source) for c in "xyz"]
    if rpy:
        names += list(_RPY)
        scale += [_scale(c, cols[c][1], "angle", source) for c in _RPY]
    elif quat:
        names += list(_QUAT)
        scale += [1.0] * 4
    joints = [c for c in cols if c.startswith("joint:")]
    for c in joints:
        unit = cols[c][1]
        kind = "angle" if unit in ANGLE_UNITS else "length" if unit in LENGTH_UNITS else None
        if kind is None:
            raise MeasurementError(f"{source}: column {c!r} needs a unit (rad, deg, m, mm), got {unit!r}")
        scale.append(_scale(c, unit, kind, source))
    names += joints
    return _Spec(len(header), cols, "rpy" if rpy else "quat" if quat else None, [cols[c][0] for c in names],
                 names, np.array(scale), tuple(c[len("joint:"):] for c in joints))


def _read_csv_chunks(path, skip_bad, chunk_rows):
    source = str(path)
    if not path.is_file():
        raise MeasurementError(f"{source}: file not found")
    with path.open(encoding="utf-8", errors="surrogateescape", newline="") as fh:
        header, spec, copies = None, None, None
        raw, skipped, last = [], [], -np.inf
        for lineno, line in _lines(fh):
            try:
                bad = _check_text(line)
                if bad is not None:
                    k = len(_csv_row(line[:bad], None)) - 1 if line[:bad].strip() else 0
                    name = next((n for n, (i, _) in spec.cols.items() if i == k), None) if spec else None
                    raise MeasurementError((f"{name}: " if name else "") + _not_utf8(line, bad))
                if not line.strip() or line.lstrip().startswith("#"):
                    continue
                row = _csv_row(line, spec)
                if copies is not None:
                    copies.check(row, lineno)
            except MeasurementError as exc:
                before_header = header is None and (line is None or not line.lstrip().startswith("#"))
                if not skip_bad or before_header:
                    raise MeasurementError(f"{source}, line {lineno}: {exc}") from None
                skipped.append({"line": lineno, "reason": str(exc)})
                continue
            if header is None:
                header = row
                try:
                    spec = _spec_from_header(header, "header")
                except MeasurementError as exc:
                    raise MeasurementError(f"{source}, line {lineno}: {exc}") from None
                copies = _Copies(spec.num_cols[0])
                continue
            raw.append((lineno, row))
            if chunk_rows and len(raw) >= chunk_rows:
                block, bad_rows, last = _convert(raw, spec, last, skip_bad, source)
                yield _pack(block, spec, source, sorted(skipped + bad_rows, key=lambda s: s["line"]))
                raw, skipped = [], []
        if header is None:
            raise MeasurementError(f"{source}: empty file (no header)")
        if raw or skipped:
            block, bad_rows, last = _convert(raw, spec, last, skip_bad, source)
            yield _pack(block, spec, source, sorted(skipped + bad_rows, key=lambda s: s["line"]))


class _Copies:
    """Refuses a row equal, field for field, to an earlier one. Stamps do not decrease, so a copy comes
    among the rows of its original's stamp: only those are kept (at most ``keep`` of them)."""

    def __init__(self, stamp_col: int, keep: int = 10000):
        self.stamp_col, self.keep = stamp_col, keep
        self.stamp, self.seen = None, {}

    def check(self, row, lineno):
        stamp = row[self.stamp_col].strip() if len(row) > self.stamp_col else None
        if stamp != self.stamp:
            self.stamp, self.seen = stamp, {}
        key = tuple(f.strip() for f in row)
        first = self.seen.get(key)
        if first is not None:
            raise MeasurementError(f"the same record as line {first} (a measurement written twice)")
        if len(self.seen) < self.keep:
            self.seen[key] = lineno


def _convert(raw, spec, last, skip_bad, source):
    """Rows -> a _Block, the rows skipped and the last stamp. Fast path: the numeric columns of a clean
    chunk converted by numpy in one go; any problem falls back to row-by-row parsing, which names the
    line (or skips and lists it)."""
    if raw:
        block = _convert_fast([r for _, r in raw], spec, last)
        if block is not None:
            return block, [], float(block.stamps[-1])
    return _convert_slow(raw, spec, last, skip_bad, source)


def _convert_fast(rows, spec, last):
    """The rows of a clean chunk as a _Block, or None when any row is not clean."""
    if any(len(r) != spec.ncols for r in rows):
        return None
    by_col = list(zip(*rows))
    if _NOT_NUMERIC.search("".join(["".join(by_col[i]) for i in spec.num_cols])):
        return None
    A = np.empty((len(rows), len(spec.num_cols)))
    try:
        for j, i in enumerate(spec.num_cols):
            A[:, j] = np.fromiter(map(float, by_col[i]), float, len(rows))
    except ValueError:
        return None
    if not np.all(np.isfinite(A)):
        return None
    A *= spec.scale
    stamps = A[:, 0]
    if stamps[0] < last or np.any(np.diff(stamps) < 0):
        return None
    try:
        cycles = [_cycle(c) for c in by_col[spec.cols["cycle"][0]]] if "cycle" in spec.cols else [-1] * len(rows)
        R, joints = spec.rotations_and_joints(A)
    except ValueError:
        return None
    poses = [p.strip() for p in by_col[spec.cols["pose"][0]]] if "pose" in spec.cols else [""] * len(rows)
    return _Block(stamps, A[:, 1:4], R, poses, np.array(cycles, int), joints)


def _convert_slow(raw, spec, last, skip_bad, source):
    buf, skipped = [], []
    for lineno, row in raw:
        try:
            if len(row) != spec.ncols:
                raise MeasurementError(f"expected {spec.ncols} columns, got {len(row)}")
            rec = _parse_row(row, spec)
            if rec[0][0] < last:
                raise MeasurementError(f"stamp {rec[0][0]:.9g} s is earlier than the previous row's {last:.9g} s "
                                       f"(stamps must not decrease)")
        except MeasurementError as exc:
            if not skip_bad:
                raise MeasurementError(f"{source}, line {lineno}: {exc}") from None
            skipped.append({"line": lineno, "reason": str(exc)})
            continue
        last = rec[0][0]
        buf.append(rec)
    A = np.array([r[0] for r in buf], float).reshape(len(buf), len(spec.num_cols))
    R, joints = spec.rotations_and_joints(A)
    block = _Block(A[:, 0], A[:, 1:4], R, [r[1] for r in buf], np.array([r[2] for r in buf], int), joints)
    return block, skipped, last


class _Block:
    """Parsed rows of one chunk, column-wise (SI); ``R`` is None without orientation columns."""

    def __init__(self, stamps, pos, R, poses, cycles, joints):
        self.stamps, self.pos, self.R, self.poses, self.cycles, self.joints = stamps, pos, R, poses, cycles, joints


def _num(text, what):
    """A finite number written in plain ASCII (what ``float()`` takes from digits, sign, point, exponent)."""
    if _NOT_NUMERIC.search(text):
        raise MeasurementError(f"{what}: {_show(text)} is not a number")
    try:
        v = float(text)
    except ValueError:
        raise MeasurementError(f"{what}: {_show(text)} is not a number") from None
    if not np.isfinite(v):
        raise MeasurementError(f"{what}: {_show(text)} is not finite")
    return v


def _parse_row(row, spec):
    """(numeric values in SI, pose label, cycle) of one row; MeasurementError names the column."""
    vals = [_num(row[i], name) * s for i, name, s in zip(spec.num_cols, spec.num_names, spec.scale)]
    if spec.orientation == "quat":
        try:
            quat_to_matrices(vals[4:8])
        except ValueError as exc:
            raise MeasurementError(f"qx, qy, qz, qw: {exc}") from None
    pose = row[spec.cols["pose"][0]].strip() if "pose" in spec.cols else ""
    cycle = _cycle(row[spec.cols["cycle"][0]]) if "cycle" in spec.cols else -1
    return vals, pose, cycle


def _cycle(text):
    """A cycle number (ASCII digits, below 10**9), or -1 for an empty field."""
    t = text.strip(" \t")
    if not t:
        return -1
    if not (t.isascii() and t.isdigit() and len(t) <= 9):
        raise MeasurementError(f"cycle: expected a non-negative integer below 10**9, got {_show(text)}")
    return int(t)


def _pack(block, spec, source, skipped):
    n = len(block.stamps)
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, :3, 3] = block.pos
    if block.R is not None:
        T[:, :3, :3] = block.R
    joints = block.joints if spec.joint_names else None
    return Measurements(block.stamps, T, joints, spec.joint_names, np.array(block.poses, dtype=object),
                        np.asarray(block.cycles, dtype=int), spec.orientation is not None, source, list(skipped))


def concat(parts) -> Measurements:
    """One Measurements from several chunks of the same source."""
    parts = list(parts)
    first = parts[0]
    return Measurements(np.concatenate([p.stamps for p in parts]), np.concatenate([p.T for p in parts]),
                        None if first.joints is None else np.concatenate([p.joints for p in parts]),
                        first.joint_names,
                        np.concatenate([p.pose for p in parts]) if first.pose is not None else None,
                        np.concatenate([p.cycle for p in parts]) if first.cycle is not None else None,
                        first.has_orientation, first.source, [s for p in parts for s in p.skipped])


def write_csv(path, m: Measurements, comments=(), length_unit="mm", angle_unit="deg") -> Path:
    """Write measurements in the CSV format above (positions and angles in the given units)."""
    path = Path(path)
    ls, as_ = LENGTH_UNITS[length_unit], ANGLE_UNITS[angle_unit]
    rpy = rpy_from_matrix(m.T[:, :3, :3]) / as_
    pos = m.T[:, :3, 3] / ls
    header = ["stamp[s]", "pose", "cycle"] + [f"{c}[{length_unit}]" for c in "xyz"] + \
        [f"{c}[{angle_unit}]" for c in ("roll", "pitch", "yaw")] + \
        [f"joint:{n}[rad]" for n in m.joint_names]
    with path.open("w", newline="") as fh:
        for c in comments:
            fh.write(f"# {c}\n")
        w = csv.writer(fh)
        w.writerow(header)
        for i in range(len(m)):
            row = [f"{m.stamps[i]:.6f}", m.pose[i] if m.pose is not None else "",
                   int(m.cycle[i]) if m.cycle is not None and m.cycle[i] >= 0 else ""]
            row += [f"{v:.6f}" for v in pos[i]] + [f"{v:.7f}" for v in rpy[i]]
            if m.joints is not None:
                row += [f"{v:.9f}" for v in m.joints[i]]
            w.writerow(row)
    return path


def read_log(path, skip_bad=False) -> Measurements:
    """Measurements (with joints) rebuilt from the accuracy monitor's campaign log (JSON Lines of events:
    ``measurement`` as it arrived, then ``paired`` or ``unpaired``; ``seq`` counts from 0 again after each
    ``start``). Unpaired, rejected and undecided measurements are listed in ``skipped`` with their line and
    reason; a malformed line is an error naming it, or with ``skip_bad`` is listed there too."""
    path = Path(path)
    source = str(path)
    if not path.is_file():
        raise MeasurementError(f"{source}: file not found")
    meas, pairs, logged, decided, skipped = {}, {}, {}, {}, []
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
                if ev == "budget":
                    continue
                if ev not in ("measurement", "paired", "unpaired"):
                    raise MeasurementError(f"event: expected start, budget, measurement, paired or unpaired, "
                                           f"got {_brief(ev)}")
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
                    T = pose_from_values(_numbers(rec, "position", 3), _numbers(rec, "quaternion", 4))
                    logged[key] = (lineno, "measured")
                    meas[key] = (stamp, T)
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
                if pose is not None and not isinstance(pose, str):
                    raise MeasurementError(f"pose: expected a test pose name or null, got {_brief(pose)}")
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
    return Measurements(np.array([meas[k][0] for k in keys]), T, np.array([pairs[k][0] for k in keys]),
                        order.joint_names, np.array([pairs[k][1] for k in keys], dtype=object), np.full(len(keys), -1),
                        True, source, skipped)


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


def read_rosbag(path, joint_names=None, pose_topic="/measured_pose", joint_topic="/joint_states",
                slop: float = 0.005, skip_bad: bool = False) -> Measurements:
    """Measurements from a rosbag2 recording (sqlite3 or mcap) of PoseStamped and JointState.

    Each measured pose is paired with the joint state nearest to its header stamp within ``slop`` s.
    Unpaired measurements are an error unless ``skip_bad`` (then listed in ``skipped``).
    """
    from rosbags.highlevel import AnyReader, AnyReaderError
    from rosbags.rosbag2 import ReaderError
    from rosbags.typesys import Stores, get_typestore

    path = Path(path)
    if not path.exists():
        raise MeasurementError(f"{path}: no such bag")
    poses, pstamps, jstates, jstamps = [], [], [], []
    order = None
    skipped = []
    types = {pose_topic: "geometry_msgs/msg/PoseStamped", joint_topic: "sensor_msgs/msg/JointState"}
    try:
        with AnyReader([path], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
            conns = [c for c in reader.connections if c.topic in types]
            if not any(c.topic == pose_topic for c in conns):
                raise MeasurementError(f"{path}: no topic {pose_topic} "
                                       f"(topics: {sorted({c.topic for c in reader.connections})})")
            for c in conns:
                if c.msgtype != types[c.topic]:
                    raise MeasurementError(f"{path}: topic {c.topic} carries {c.msgtype}, expected {types[c.topic]}")
            for k, (conn, _, raw) in enumerate(reader.messages(connections=conns)):
                try:
                    try:
                        msg = reader.deserialize(raw, conn.msgtype)
                    except AnyReaderError as exc:
                        raise IngestError(f"cannot be decoded as {conn.msgtype} ({_cut(str(exc), 80)})") from None
                    st = stamp_seconds(msg.header.stamp)
                    if conn.topic == pose_topic:
                        p, o = msg.pose.position, msg.pose.orientation
                        poses.append(pose_from_values((p.x, p.y, p.z), (o.x, o.y, o.z, o.w)))
                        pstamps.append(st)
                    else:
                        if order is None:
                            order = JointOrder(joint_names or msg.name)
                        jstates.append(order(msg.name, msg.position))
                        jstamps.append(st)
                except IngestError as exc:
                    err = f"message {k} on {conn.topic}: {exc}"
                    if not skip_bad:
                        raise MeasurementError(f"{path}: {err}") from None
                    skipped.append({"message": k, "reason": err})
    except (AnyReaderError, ReaderError, FileNotFoundError) as exc:
        raise MeasurementError(f"{path}: not a readable rosbag2 recording ({exc})") from None
    if not poses:
        raise MeasurementError(f"{path}: no messages on {pose_topic}"
                               + (f" ({len(skipped)} skipped, the first: {skipped[0]['reason']})" if skipped else ""))
    by_time = np.argsort(pstamps, kind="stable")
    pst = np.array(pstamps)[by_time]
    T = np.array(poses)[by_time]
    joints = None
    if jstates:
        pair = pair_by_stamp(pst, jstamps, slop)
        if np.any(pair < 0):
            bad = np.flatnonzero(pair < 0)
            err = (f"{len(bad)} measured pose(s) have no joint state within {slop} s "
                   f"(first at stamp {pst[bad[0]]:.9f} s)")
            if not skip_bad:
                raise MeasurementError(f"{path}: {err}")
            skipped += [{"measurement": int(i), "reason": f"unpaired measurement at stamp {pst[i]:.9f} s"} for i in bad]
            keep = pair >= 0
            pst, T, pair = pst[keep], T[keep], pair[keep]
        joints = np.array(jstates)[pair]
    return Measurements(pst, T, joints, order.joint_names if order else (), np.array([""] * len(pst), dtype=object),
                        np.full(len(pst), -1), True, str(path), skipped)


def write_rosbag(path, m: Measurements, storage="sqlite3", pose_topic="/measured_pose", joint_topic="/joint_states",
                 frame_id="tracker", joint_offset_s=0.0) -> Path:
    """Write measurements as a rosbag2 recording (PoseStamped + JointState, ROS 2 Jazzy types)."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_JAZZY)
    T = ts.types
    Header, Time = T["std_msgs/msg/Header"], T["builtin_interfaces/msg/Time"]
    PoseStamped, Pose = T["geometry_msgs/msg/PoseStamped"], T["geometry_msgs/msg/Pose"]
    Point, Quaternion = T["geometry_msgs/msg/Point"], T["geometry_msgs/msg/Quaternion"]
    JointState = T["sensor_msgs/msg/JointState"]
    plugin = {"sqlite3": StoragePlugin.SQLITE3, "mcap": StoragePlugin.MCAP}[storage]
    quats = matrices_to_quat(m.T[:, :3, :3])

    def stamp(t):
        ns = int(round(t * 1e9))
        return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000), ns

    with Writer(Path(path), version=9, storage_plugin=plugin) as w:
        cp = w.add_connection(pose_topic, PoseStamped.__msgtype__, typestore=ts)
        cj = w.add_connection(joint_topic, JointState.__msgtype__, typestore=ts) if m.joints is not None else None
        for i in range(len(m)):
            if cj is not None:
                tj, ns = stamp(m.stamps[i] + joint_offset_s)
                js = JointState(header=Header(stamp=tj, frame_id=""), name=list(m.joint_names),
                                position=np.asarray(m.joints[i], float), velocity=np.zeros(0), effort=np.zeros(0))
                w.write(cj, ns, ts.serialize_cdr(js, JointState.__msgtype__))
            tp, ns = stamp(m.stamps[i])
            p = m.T[i, :3, 3]
            q = quats[i]
            msg = PoseStamped(header=Header(stamp=tp, frame_id=frame_id),
                              pose=Pose(position=Point(x=p[0], y=p[1], z=p[2]),
                                        orientation=Quaternion(x=q[0], y=q[1], z=q[2], w=q[3])))
            w.write(cp, ns + 1, ts.serialize_cdr(msg, PoseStamped.__msgtype__))
    return Path(path)


def read_measurements(path, joint_names=None, skip_bad=False, slop=0.005):
    """Measurements from a CSV file, a campaign log (.jsonl) or a rosbag2 directory / .db3 / .mcap."""
    p = Path(path)
    if p.is_dir() or p.suffix in (".db3", ".mcap"):
        return read_rosbag(p, joint_names=joint_names, skip_bad=skip_bad, slop=slop)
    if p.suffix in (".jsonl", ".log"):
        return read_log(p, skip_bad=skip_bad)
    return read_csv(p, skip_bad=skip_bad)
