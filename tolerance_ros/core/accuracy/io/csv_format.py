"""The documented measurement CSV, read (checked, chunked) and written.

CSV format: optional ``#`` comment lines, then a header naming each column with its unit in brackets::

    stamp[s],pose,cycle,x[mm],y[mm],z[mm],roll[deg],pitch[deg],yaw[deg],joint:joint1[rad],...

``x y z`` is the measured tool position, ``roll pitch yaw`` its orientation (``R = Rz(yaw) Ry(pitch)
Rx(roll)``; optional, or ``qx qy qz qw`` quaternion columns instead), ``pose`` the test pose name and
``cycle`` its 0-based cycle (both optional), ``target`` the reflector or marker the row measured (a name;
optional: without it every row measures one target; several targets of one visit are rows of the same
stamp), ``joint:<name>`` the joint reading at the measurement (rad or deg for revolute, m or mm for
prismatic), ``load:fx load:fy load:fz`` the force applied at the tool (N or kN, base frame; optional, all
three: ISO 9283 static compliance) and ``load:mx load:my load:mz`` the torque (Nm or kNm; optional, with the
force). Lengths: m, mm, um; angles: rad, deg, mrad; the stamp's unit (s, ms, us, ns) is required.
Any other column is an error naming it (``tolerance-ros import`` maps a file's own columns).
The orientation columns come all three or all four, never some of them. A number is what ``float()``
reads from ASCII digits, sign, point and exponent (no ``1_000``, no other digits, no nan or inf), and
must be finite; stamps must not decrease. Files are UTF-8. A row that repeats an earlier row field for
field (the same stamp, pose, target and values, numbers compared by value: a measurement written twice)
is an error naming both lines.

Every problem is a ``MeasurementError`` naming the file, the line and the column or field. With
``skip_bad`` a bad row or line is skipped instead and listed in ``skipped`` with its reason (a bad
header still stops the read); nothing is dropped silently. A line longer than ``MAX_LINE`` characters
is never held in memory.
"""
from __future__ import annotations

import csv
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ...geometry import quat_to_matrices, rpy_from_matrix, rpy_to_matrices
from ...ingest import MAX_POSITION_M
from ...resources import not_a_file
from ...units import ANGLE_UNITS, FORCE_UNITS, LENGTH_UNITS, TORQUE_UNITS
from .measurements import MeasurementError, Measurements, concat
from .text import _check_text, _lines, _not_utf8, _show

_COL = re.compile(r"^\s*([A-Za-z_][\w:.\-/]*)\s*(?:\[\s*([^\]]*)\s*\])?\s*$")


_NOT_NUMERIC = re.compile(r"[^0-9eE.+\- \t]")  # a number is what float() takes from these characters



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


def separator_hint(header) -> str:
    """The words to add when a header (its fields split at commas) is one field holding another separator."""
    if len(header) == 1:
        for sep, name in ((";", "semicolons"), ("\t", "tabs")):
            if sep in header[0]:
                return (f" (the file is separated by {name}; this format's separator is the comma, and its decimal mark "
                        f"the point: export it so)")
    return ""


def _parse_header(header, source):
    cols = {}
    for i, h in enumerate(header):
        m = _COL.match(h)
        if not m:
            raise MeasurementError(f"{source}: header column {i + 1} {_show(h)} is not 'name[unit]'"
                                   f"{separator_hint(header)}")
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


_TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
_RPY, _QUAT = ("roll", "pitch", "yaw"), ("qx", "qy", "qz", "qw")
_LOAD = ("load:fx", "load:fy", "load:fz")
_TORQUE = ("load:mx", "load:my", "load:mz")
_KNOWN = ("stamp", "pose", "cycle", "target", "x", "y", "z") + _RPY + _QUAT + _LOAD + _TORQUE
MAX_TARGET = 100  # characters of a target name
MAX_POSE = 100    # characters of a test pose's name


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
    loads: int = 0            # the last columns are the load's: 3 (forces) or 6 (forces, torques)

    def rotations_and_joints(self, A):
        """(n, 3, 3) rotations (None without orientation; ValueError for a zero quaternion) and (n, dof)
        joint values of numeric rows ``A`` in SI."""
        end = A.shape[1] - self.loads
        if self.orientation == "rpy":
            return rpy_to_matrices(A[:, 4:7]), A[:, 7:end]
        if self.orientation == "quat":
            return quat_to_matrices(A[:, 4:8]), A[:, 8:end]
        return None, A[:, 4:end]

    def load(self, A):
        """(n, 3) forces (N) of numeric rows ``A`` in SI, or None without load columns."""
        return A[:, -self.loads:] if self.loads else None


def _spec_from_header(header, source):
    cols = _parse_header(header, source)
    unknown = [c for c in cols if c not in _KNOWN and not c.startswith("joint:")]
    if "contact" in unknown and "x" not in cols:
        raise MeasurementError(f"{source}: a contact campaign (its contact column), not measured poses: calibrate and "
                               f"validate read it (calibration without a tracker, docs/calibration.md); report and "
                               f"path-report need a tracker's measurements")
    if unknown:
        raise MeasurementError(f"{source}: column {unknown[0]!r} is not a measurement column (known: "
                               f"{', '.join(_KNOWN)}, joint:<name>); convert a file with columns of its own with "
                               f"'tolerance-ros import', which maps them")
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
        raise MeasurementError(f"{source}: column 'stamp' needs a time unit in brackets (s, ms, us, ns), "
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
    loads = [c for c in _LOAD + _TORQUE if c in cols]
    torques = [c for c in _TORQUE if c in cols]
    group = _LOAD + _TORQUE if torques else _LOAD
    if loads and len(loads) < len(group):
        raise MeasurementError(f"{source}: the load needs all of {', '.join(group)}; missing column(s) "
                               f"{[c for c in group if c not in cols]}")
    for c in loads:
        units = TORQUE_UNITS if c in _TORQUE else FORCE_UNITS
        if cols[c][1] not in units:
            raise MeasurementError(f"{source}: column {c!r} needs a {'torque' if c in _TORQUE else 'force'} unit in "
                                   f"brackets ({', '.join(units)}), got {cols[c][1]!r}")
        scale.append(units[cols[c][1]])
    names += loads
    return _Spec(len(header), cols, "rpy" if rpy else "quat" if quat else None, [cols[c][0] for c in names],
                 names, np.array(scale), tuple(c[len("joint:"):] for c in joints), len(loads))


def _read_csv_chunks(path, skip_bad, chunk_rows):
    source = str(path)
    if not path.is_file():
        raise MeasurementError(f"{source}: {not_a_file(path)}")
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
        stamp = _field_value(row[self.stamp_col]) if len(row) > self.stamp_col else None
        if stamp != self.stamp:
            self.stamp, self.seen = stamp, {}
        key = tuple(map(_field_value, row))
        first = self.seen.get(key)
        if first is not None:
            raise MeasurementError(f"the same record as line {first} (a measurement written twice)")
        if len(self.seen) < self.keep:
            self.seen[key] = lineno


def _field_value(text):
    """A field as it compares with another: a number by its value (``1.0`` is ``1.00``), else its text."""
    s = text.strip()
    if s and not _NOT_NUMERIC.search(s):
        try:
            return float(s)
        except ValueError:
            pass
    return s


def _convert(raw, spec, last, skip_bad, source):
    """Rows -> a _Block, the rows skipped and the last stamp. Fast path: the numeric columns of a clean
    chunk converted by numpy in one go; any problem falls back to row-by-row parsing, which names the
    line (or skips and lists it)."""
    if raw:
        block = _convert_fast([r for _, r in raw], spec, last)
        if block is not None:
            block.lines = np.array([n for n, _ in raw], int)
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
    if not np.all(np.abs(A[:, 1:4]) <= MAX_POSITION_M):
        return None
    stamps = A[:, 0]
    if stamps[0] < last or np.any(np.diff(stamps) < 0):
        return None
    try:
        cycles = [_cycle(c) for c in by_col[spec.cols["cycle"][0]]] if "cycle" in spec.cols else [-1] * len(rows)
        R, joints = spec.rotations_and_joints(A)
    except ValueError:
        return None
    poses = [p.strip() for p in by_col[spec.cols["pose"][0]]] if "pose" in spec.cols else [""] * len(rows)
    if any(len(p) > MAX_POSE for p in poses):
        return None
    targets = None
    if "target" in spec.cols:
        targets = [t.strip() for t in by_col[spec.cols["target"][0]]]
        if not all(0 < len(t) <= MAX_TARGET for t in targets):
            return None
    return _Block(stamps, A[:, 1:4], R, poses, np.array(cycles, int), joints, targets, spec.load(A))


def _convert_slow(raw, spec, last, skip_bad, source):
    buf, skipped, lines = [], [], []
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
        lines.append(lineno)
    A = np.array([r[0] for r in buf], float).reshape(len(buf), len(spec.num_cols))
    R, joints = spec.rotations_and_joints(A)
    block = _Block(A[:, 0], A[:, 1:4], R, [r[1] for r in buf], np.array([r[2] for r in buf], int), joints,
                   [r[3] for r in buf] if "target" in spec.cols else None, spec.load(A))
    block.lines = np.array(lines, int)
    return block, skipped, last


class _Block:
    """Parsed rows of one chunk, column-wise (SI); ``R`` is None without orientation columns, ``targets``
    None without a target column."""

    def __init__(self, stamps, pos, R, poses, cycles, joints, targets=None, load=None):
        self.stamps, self.pos, self.R, self.poses, self.cycles, self.joints = stamps, pos, R, poses, cycles, joints
        self.targets, self.load = targets, load
        self.lines = None


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
    """(numeric values in SI, pose label, cycle, target) of one row; MeasurementError names the column."""
    vals = [_num(row[i], name) * s for i, name, s in zip(spec.num_cols, spec.num_names, spec.scale)]
    for name, v, text in zip(spec.num_names[1:4], vals[1:4], [row[i] for i in spec.num_cols[1:4]]):
        if not abs(v) <= MAX_POSITION_M:
            raise MeasurementError(f"{name}: {_show(text)} lies {abs(v):.3g} m from the tracker's origin, beyond "
                                   f"{MAX_POSITION_M:g} m: not a measured point")
    if spec.orientation == "quat":
        try:
            quat_to_matrices(vals[4:8])
        except ValueError as exc:
            raise MeasurementError(f"qx, qy, qz, qw: {exc}") from None
    pose = row[spec.cols["pose"][0]].strip() if "pose" in spec.cols else ""
    if len(pose) > MAX_POSE:
        raise MeasurementError(f"pose: a name of {len(pose):,} characters ({_show(pose)}); at most {MAX_POSE}")
    cycle = _cycle(row[spec.cols["cycle"][0]]) if "cycle" in spec.cols else -1
    target = _target(row[spec.cols["target"][0]]) if "target" in spec.cols else ""
    return vals, pose, cycle, target


def _target(text):
    """A target name: not empty, at most MAX_TARGET characters."""
    t = text.strip()
    if not t:
        raise MeasurementError("target: empty (in a file with a target column every row names its target)")
    if len(t) > MAX_TARGET:
        raise MeasurementError(f"target: {_show(t)} is longer than {MAX_TARGET} characters")
    return t


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
    targets = np.array(block.targets, dtype=object) if block.targets is not None else None
    return Measurements(block.stamps, T, joints, spec.joint_names, np.array(block.poses, dtype=object),
                        np.asarray(block.cycles, dtype=int), spec.orientation is not None, source, list(skipped),
                        targets, block.lines, block.load)


def write_csv(path, m: Measurements, comments=(), length_unit="mm", angle_unit="deg", joint_units=None) -> Path:
    """Write measurements in the CSV format above (positions and angles in the given units; orientation
    columns only for measurements that have one, a target column for named targets). Joints are written in
    SI, labelled with ``joint_units`` ('rad' or 'm' per joint; default 'rad')."""
    path = Path(path)
    ls, as_ = LENGTH_UNITS[length_unit], ANGLE_UNITS[angle_unit]
    rpy = rpy_from_matrix(m.T[:, :3, :3]) / as_ if m.has_orientation else np.zeros((len(m), 0))
    pos = m.T[:, :3, 3] / ls
    named = m.target is not None
    path.parent.mkdir(parents=True, exist_ok=True)
    header = ["stamp[s]", "pose", "cycle"] + (["target"] if named else []) + [f"{c}[{length_unit}]" for c in "xyz"] + \
        ([f"{c}[{angle_unit}]" for c in ("roll", "pitch", "yaw")] if m.has_orientation else []) + \
        [f"joint:{n}[{u}]" for n, u in zip(m.joint_names, joint_units or ["rad"] * len(m.joint_names))] + \
        ([f"{c}[N]" for c in _LOAD] if m.load is not None else []) + \
        ([f"{c}[Nm]" for c in _TORQUE] if m.load is not None and m.load.shape[1] == 6 else [])
    with path.open("w", newline="") as fh:
        for c in comments:
            fh.write(f"# {c}\n")
        w = csv.writer(fh)
        w.writerow(header)
        for i in range(len(m)):
            row = [f"{m.stamps[i]:.6f}", m.pose[i] if m.pose is not None else "",
                   int(m.cycle[i]) if m.cycle is not None and m.cycle[i] >= 0 else ""] + ([m.target[i]] if named else [])
            row += [f"{v:.6f}" for v in pos[i]] + [f"{v:.7f}" for v in rpy[i]]
            if m.joints is not None:
                row += [f"{v:.9f}" for v in m.joints[i]]
            if m.load is not None:
                row += [f"{v:.6g}" for v in m.load[i]]
            w.writerow(row)
    return path

