"""Importing measurement exports with their own column names and units into ``Measurements``.

Trackers, motion-capture systems and controllers export tables of their own: CSV or whitespace-separated
text with a header row of column names, or MATLAB ``.mat`` files of arrays. ``read_table`` reads one into
named columns of numbers (a 2-D ``.mat`` array ``q`` gives the columns ``q:0``, ``q:1``, ...; a text
column that is not numeric stays text). ``ColumnMap`` says, explicitly and with units, which columns are
what; ``to_measurements`` applies it, one row per target and export row, in SI.

    ColumnMap(stamp=("t_start_robot", "s"), joints=[("arm_1_joint", "arm_1_joint", "rad"), ...],
              points=[("BL", ("x1", "y1", "z1"), "m"), ...])

A column the map does not name is an error naming it, unless listed in ``ignore``; nothing is dropped
silently. Every number must be finite. SI out: m, rad, s.
"""
from __future__ import annotations

import csv
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ...geometry import quat_to_matrices, rpy_to_matrices
from ...resources import not_a_file
from ...units import ANGLE_UNITS, LENGTH_UNITS, TIME_UNITS
from .measurements import MeasurementError, Measurements

MAX_BYTES = 256 << 20   # a text export read whole is at most this big


def read_table(path, delimiter=None) -> tuple[dict, int]:
    """({column name: (n,) array (float, or object for text)}, rows) of a CSV, whitespace table or .mat file.

    ``delimiter``: ',' or 'whitespace'; by default ',' when the header line has a comma, else whitespace.
    ``#`` lines are comments. ``.mat`` (MATLAB 5-7.2, scipy.io): each numeric array of n rows becomes a
    column (1-D) or the columns ``name:0``, ``name:1``, ... (2-D); all of one length.
    """
    path = Path(path)
    if not path.is_file():
        raise MeasurementError(f"{path}: {not_a_file(path)}")
    if path.suffix.lower() == ".mat":
        return _read_mat(path)
    if path.stat().st_size > MAX_BYTES:
        raise MeasurementError(f"{path}: larger than {MAX_BYTES >> 20} MiB")
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as exc:
        raise MeasurementError(f"{path}: byte {exc.start} is not UTF-8") from None
    lines = [(i + 1, ln) for i, ln in enumerate(text.splitlines()) if ln.strip() and not ln.lstrip().startswith("#")]
    if not lines:
        raise MeasurementError(f"{path}: empty (no header)")
    comma = delimiter == "," or (delimiter is None and "," in lines[0][1])
    if delimiter not in (None, ",", "whitespace"):
        raise MeasurementError(f"delimiter: expected ',' or 'whitespace', got {delimiter!r}")
    split = (lambda s: next(csv.reader([s]))) if comma else str.split
    header = [h.strip() for h in split(lines[0][1])]
    if len(set(header)) != len(header):
        dup = next(h for h in header if header.count(h) > 1)
        raise MeasurementError(f"{path}, line {lines[0][0]}: column {dup!r} appears twice")
    rows = []
    for lineno, ln in lines[1:]:
        fields = [f.strip() for f in split(ln)]
        if len(fields) != len(header):
            raise MeasurementError(f"{path}, line {lineno}: expected {len(header)} fields, got {len(fields)}")
        rows.append(fields)
    cols = {}
    for j, name in enumerate(header):
        values = [r[j] for r in rows]
        try:
            cols[name] = np.array([float(v) for v in values], float)
        except ValueError:
            cols[name] = np.array(values, dtype=object)
    return cols, len(rows)


def _read_mat(path):
    from scipy.io import loadmat
    try:
        data = loadmat(str(path))
    except (ValueError, NotImplementedError, OSError) as exc:
        raise MeasurementError(f"{path}: not a MATLAB file scipy can read (v5-v7.2): {exc}") from None
    cols, n = {}, None
    for name, value in data.items():
        if name.startswith("__") or not isinstance(value, np.ndarray) or value.dtype.kind not in "fiu":
            continue
        a = np.asarray(value, float)
        if a.ndim == 2 and 1 in a.shape and a.size > 1:
            a = a.reshape(-1)
        if a.ndim == 1:
            cols[name] = a
        elif a.ndim == 2:
            cols.update({f"{name}:{k}": a[:, k] for k in range(a.shape[1])})
        else:
            raise MeasurementError(f"{path}: variable {name!r} has {a.ndim} dimensions; expected 1 or 2")
        lengths = {len(v) for v in cols.values()}
        if len(lengths) > 1:
            raise MeasurementError(f"{path}: variable {name!r} has {len(cols[next(reversed(cols))])} rows, the "
                                   f"others {sorted(lengths)}")
        n = lengths.pop()
    if not cols:
        raise MeasurementError(f"{path}: no numeric variable")
    return cols, n


@dataclass
class ColumnMap:
    """Which columns are what, with units.

    stamp : (column, time unit) or None (then ``period`` s between rows).  joints : [(joint name, column,
    unit)].  points : [(target name, (x, y, z columns), length unit)]: one target per entry ('' for one
    unnamed target).  orientation : (columns, unit) of roll, pitch, yaw (3 columns, an angle unit) or of a
    quaternion qx qy qz qw (4 columns, unit ''), for a single point entry.  pose, cycle : columns of the
    test-pose label and cycle, or None.  ignore : columns that are deliberately not imported.
    markers : [(name, (x, y, z) m)]: the measured frame is a rigid body's pose and these are its markers'
    coordinates in the body frame: each row becomes one point per marker, ``p = t + R b`` (the points
    the body's markers were, so the two forms of one campaign are the same measurements).
    """

    joints: list
    points: list
    stamp: tuple | None = None
    period: float = 1.0
    orientation: tuple | None = None
    pose: str | None = None
    cycle: str | None = None
    ignore: list = field(default_factory=list)
    markers: list = field(default_factory=list)

    def used(self) -> list:
        cols = [c for _, c, _ in self.joints] + [c for _, xyz, _ in self.points for c in xyz]
        cols += [c for c in (self.stamp[0] if self.stamp else None, self.pose, self.cycle) if c]
        cols += list(self.orientation[0]) if self.orientation else []
        return cols


def to_measurements(cols: dict, n: int, cmap: ColumnMap, source="") -> Measurements:
    """Measurements (SI) of a table read by ``read_table``, by the map; a MeasurementError names the column."""
    used = cmap.used()
    missing = [c for c in used + list(cmap.ignore) if c not in cols]
    if missing:
        raise MeasurementError(f"{source}: no column {missing[0]!r} (columns: {', '.join(cols)})")
    dup = next((c for c in used if used.count(c) > 1), None)
    if dup:
        raise MeasurementError(f"{source}: column {dup!r} is mapped twice")
    left = [c for c in cols if c not in used and c not in cmap.ignore]
    if left:
        raise MeasurementError(f"{source}: column(s) {left} are not mapped; map them or list them to ignore "
                               f"(nothing is dropped silently)")
    if not cmap.points:
        raise MeasurementError(f"{source}: no measured point is mapped (give the x, y, z columns of a target)")
    if cmap.orientation and len(cmap.points) != 1:
        raise MeasurementError(f"{source}: an orientation belongs to one measured frame; map one point with it")
    if n == 0:
        raise MeasurementError(f"{source}: no rows")

    def number(c, scale):
        v = cols[c]
        if v.dtype == object:
            bad = next(x for x in v if not _is_number(x))
            raise MeasurementError(f"{source}: column {c!r}: {bad!r} is not a number")
        if not np.all(np.isfinite(v)):
            raise MeasurementError(f"{source}: column {c!r}: row {int(np.flatnonzero(~np.isfinite(v))[0]) + 1} is "
                                   f"not finite")
        return v * scale

    stamps = (number(cmap.stamp[0], _unit(cmap.stamp[1], TIME_UNITS, cmap.stamp[0], "time"))
              if cmap.stamp else np.arange(n) * float(cmap.period))
    joints = np.column_stack([number(c, _joint_unit(u, c)) for _, c, u in cmap.joints]) if cmap.joints else None
    K = len(cmap.points)
    T = np.tile(np.eye(4), (n, K, 1, 1))
    for k, (_, xyz, unit) in enumerate(cmap.points):
        if len(xyz) != 3:
            raise MeasurementError(f"{source}: a point takes three columns x, y, z, got {list(xyz)}")
        s = _unit(unit, LENGTH_UNITS, xyz[0], "length")
        T[:, k, :3, 3] = np.column_stack([number(c, s) for c in xyz])
    if cmap.orientation:
        ocols, unit = cmap.orientation
        if len(ocols) == 3:
            s = _unit(unit, ANGLE_UNITS, ocols[0], "angle")
            T[:, 0, :3, :3] = rpy_to_matrices(np.column_stack([number(c, s) for c in ocols]))
        elif len(ocols) == 4:
            try:
                T[:, 0, :3, :3] = quat_to_matrices(np.column_stack([number(c, 1.0) for c in ocols]))
            except ValueError as exc:
                raise MeasurementError(f"{source}: quaternion {list(ocols)}: {exc}") from None
        else:
            raise MeasurementError(f"{source}: orientation: three columns (roll, pitch, yaw) or four (qx, qy, qz, "
                                   f"qw), got {list(ocols)}")
    names = [name for name, _, _ in cmap.points]
    if cmap.markers:
        if not cmap.orientation:
            raise MeasurementError(f"{source}: markers belong to a rigid body's pose: give its orientation too")
        B = np.array([b for _, b in cmap.markers], float).reshape(-1, 3)
        if not np.all(np.isfinite(B)):
            raise MeasurementError(f"{source}: a marker's coordinates are not finite")
        frames = T[:, 0]
        T = np.tile(np.eye(4), (n, len(B), 1, 1))
        T[:, :, :3, 3] = frames[:, None, :3, 3] + np.einsum("nij,mj->nmi", frames[:, :3, :3], B)
        names, K = [name for name, _ in cmap.markers], len(B)
    if len(set(names)) != K or (K > 1 and not all(names)):
        raise MeasurementError(f"{source}: several targets need distinct names, got {names}")
    pose = None if cmap.pose is None else np.array([str(v) for v in cols[cmap.pose]], dtype=object)
    cycle = None
    if cmap.cycle is not None:
        c = number(cmap.cycle, 1.0)
        if np.any(c < 0) or np.any(c != np.round(c)):
            raise MeasurementError(f"{source}: column {cmap.cycle!r}: cycles are non-negative integers")
        cycle = c.astype(int)
    rows = np.repeat(np.arange(n), K)
    return Measurements(stamps[rows], T.reshape(n * K, 4, 4), None if joints is None else joints[rows],
                        tuple(j for j, _, _ in cmap.joints), None if pose is None else pose[rows],
                        np.full(n * K, -1) if cycle is None else cycle[rows],
                        cmap.orientation is not None and not cmap.markers, source, [],
                        np.array(names * n, dtype=object) if K > 1 or names[0] else None)


def _is_number(x) -> bool:
    try:
        float(x)
    except (TypeError, ValueError):
        return False
    return True


def _unit(unit, table, column, kind) -> float:
    if unit not in table:
        raise MeasurementError(f"column {column!r}: needs a {kind} unit ({', '.join(sorted(table))}), got {unit!r}")
    return table[unit]


def _joint_unit(unit, column) -> float:
    if unit in ANGLE_UNITS:
        return ANGLE_UNITS[unit]
    if unit in LENGTH_UNITS:
        return LENGTH_UNITS[unit]
    raise MeasurementError(f"column {column!r}: a joint needs an angle or length unit (rad, deg, m, mm), got {unit!r}")


_SPEC = re.compile(r"^\s*(?:([^=\s]*)=)?\s*([^\[\]=]+?)\s*(?:\[\s*([^\]]*)\s*\])?\s*$")


def parse_spec(text, what) -> tuple:
    """(name or None, [columns], unit or '') of a command-line mapping ``NAME=COL1,COL2[unit]``."""
    m = _SPEC.match(text)
    if not m:
        raise MeasurementError(f"{what}: expected [NAME=]COLUMN[,COLUMN...][unit], got {text!r}")
    name, columns, unit = m.group(1), [c.strip() for c in m.group(2).split(",")], (m.group(3) or "").strip()
    if not all(columns):
        raise MeasurementError(f"{what}: an empty column name in {text!r}")
    return name, columns, unit
