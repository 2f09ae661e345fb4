"""Joint states as a robot controller logs them, and a tracker's point stream, as CSV (fast, vectorised).

Joint states::

    # optional comment lines
    stamp[s],joint:joint1[rad],joint:joint2[deg],...,joint:slide[mm]

``stamp`` needs its unit (s, ms, us, ns); the rows are kept as logged (repeated stamps, rows out of order and
a clock that jumps are the path report's to put in order and say: ``streams.tidy``); every joint column its unit (rad, deg,
mrad for revolute joints, m, mm for prismatic ones). Every joint of the robot must have a column; other
columns are an error naming them. A row that is not numbers stops the read with its line number.

A point stream is the measurement CSV of ``csv_format`` with the columns ``stamp``, ``x``, ``y``, ``z`` only
(what ``write_points`` writes); ``read_points`` reads one at numpy's speed (with the same checks: units,
numbers; stamps as logged) and any other measurement file through
``read_measurements``.
"""
from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from ...ingest import MAX_POSITION_M
from ...resources import not_a_file
from ...units import ANGLE_UNITS, LENGTH_UNITS, TIME_UNITS
from .csv_format import _COL, separator_hint
from .measurements import MeasurementError


def _header(path):
    """(line number of the header, its columns, the text after it)."""
    text = Path(path).read_text(encoding="utf-8", errors="strict")
    lines = text.splitlines(keepends=True)
    for i, line in enumerate(lines):
        if line.strip() and not line.lstrip().startswith("#"):
            return i + 1, [c.strip() for c in line.strip().split(",")], "".join(lines[i + 1:])
    raise MeasurementError(f"{path}: empty file (no header)")


def read_joint_states(path, joint_names, joint_types=None, ignored=None):
    """(stamps (k,) s, joints (k, dof) SI in the order of ``joint_names``) from a joint-state CSV (see the
    module docstring); ``joint_types``: 'revolute' or 'prismatic' per joint, to check each column's unit.
    The columns of joints the robot does not have (a gripper's) are read past; their names are appended to
    ``ignored`` (a list) when given, for the report to say."""
    p = Path(path)
    if not p.is_file():
        raise MeasurementError(f"{path}: {not_a_file(p)}")
    try:
        lineno, header, body = _header(p)
    except UnicodeDecodeError as exc:
        raise MeasurementError(f"{path}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    cols = {}
    for k, h in enumerate(header):
        m = _COL.match(h)
        if not m or not m.group(2):
            raise MeasurementError(f"{path}, line {lineno}: column {k + 1} {h[:60]!r} is not 'name[unit]'"
                                   f"{separator_hint(header)}")
        if m.group(1) in cols:
            raise MeasurementError(f"{path}, line {lineno}: column {m.group(1)!r} appears twice")
        cols[m.group(1)] = (k, m.group(2).strip())
    if "stamp" not in cols or cols["stamp"][1] not in TIME_UNITS:
        raise MeasurementError(f"{path}, line {lineno}: needs a column stamp with a time unit (stamp[s]; s, ms, us, "
                               f"ns)")
    other = [c for c in cols if c != "stamp" and not c.startswith("joint:")]
    if other:
        raise MeasurementError(f"{path}, line {lineno}: column {other[0]!r} is not a joint-state column (stamp, "
                               f"joint:<name>)")
    missing = [n for n in joint_names if f"joint:{n}" not in cols]
    if missing:
        have = [c[6:] for c in cols if c.startswith("joint:")]
        raise MeasurementError(f"{path}, line {lineno}: no column for joint(s) {missing} of the robot (the file has "
                               f"{have})")
    if ignored is not None:
        ignored += [c[6:] for c in cols if c.startswith("joint:") and c[6:] not in joint_names]
    types = joint_types or ["revolute"] * len(joint_names)
    scale = [TIME_UNITS[cols["stamp"][1]]]
    for n, kind in zip(joint_names, types):
        unit = cols[f"joint:{n}"][1]
        table = LENGTH_UNITS if kind == "prismatic" else ANGLE_UNITS
        if unit not in table:
            raise MeasurementError(f"{path}, line {lineno}: column joint:{n} needs "
                                   f"{'a length' if kind == 'prismatic' else 'an angle'} unit "
                                   f"({', '.join(sorted(table))}), got {unit!r}")
        scale.append(table[unit])
    use = [cols["stamp"][0]] + [cols[f"joint:{n}"][0] for n in joint_names]
    try:
        A = _loadtxt(body, use)
    except ValueError:
        A = None
    if A is None or A.shape[1] != len(use) or not np.all(np.isfinite(A)) or not _fields_fit(body, len(header), len(A)):
        _first_bad(path, body, lineno, len(header), use)
    if len(A) < 3:
        raise MeasurementError(f"{path}: {len(A)} joint state(s); a path needs at least 3")
    A *= np.array(scale)
    return A[:, 0], A[:, 1:]


def _fields_fit(body, ncols, rows) -> bool:
    """Whether each of the ``rows`` data lines of ``body`` has ``ncols`` fields (counted by its commas; lines
    with comments are counted one by one)."""
    if "#" not in body:
        return body.count(",") == (ncols - 1) * rows
    lines = [line.split("#", 1)[0] for line in body.splitlines()]
    return all(line.count(",") == ncols - 1 for line in lines if line.strip())


def _first_bad(path, body, lineno, ncols, use):
    for i, line in enumerate(body.splitlines()):
        line = line.split("#", 1)[0]
        if not line.strip():
            continue
        fields = line.split(",")
        if len(fields) != ncols:
            raise MeasurementError(f"{path}, line {lineno + 1 + i}: expected {ncols} columns, got {len(fields)}")
        for k in use:
            try:
                v = float(fields[k])
            except ValueError:
                raise MeasurementError(f"{path}, line {lineno + 1 + i}: column {k + 1}: {fields[k]!r} is not a "
                                       f"number") from None
            if not np.isfinite(v):
                raise MeasurementError(f"{path}, line {lineno + 1 + i}: column {k + 1}: {fields[k]!r} is not finite")
    raise MeasurementError(f"{path}: cannot read the joint states")


def read_points(path):
    """(stamps (n,) s, points (n, 3) m, source) of a tracker's stream: a points-only CSV read vectorised, any
    other measurement file (CSV with more columns, campaign log, rosbag2) by ``read_measurements``."""
    from . import read_measurements
    from .rosbag import is_recording, read_rosbag_streams
    p = Path(path)
    if is_recording(p):  # a recording: the points as they streamed, unpaired
        stamps, points, _, _ = read_rosbag_streams(p)
        return stamps, points, str(path)
    if p.is_file() and p.suffix.lower() == ".csv":
        try:
            lineno, header, body = _header(p)
        except UnicodeDecodeError:
            lineno, header = 0, []
        cols = {}
        for k, h in enumerate(header):
            m = _COL.match(h)
            if m:
                cols[m.group(1)] = (k, (m.group(2) or "").strip())
        if len(header) == 4 and set(cols) == {"stamp", "x", "y", "z"} and cols["stamp"][1] in TIME_UNITS and \
                all(cols[c][1] in LENGTH_UNITS for c in "xyz"):
            use = [cols[c][0] for c in ("stamp", "x", "y", "z")]
            try:
                A = _loadtxt(body, use)
            except ValueError:
                A = None
            if A is None or not np.all(np.isfinite(A)) or not _fields_fit(body, 4, len(A)):
                _first_bad(path, body, lineno, 4, use)
            if len(A) == 0:
                raise MeasurementError(f"{path}: no measurements")
            A *= np.array([TIME_UNITS[cols["stamp"][1]]] + [LENGTH_UNITS[cols[c][1]] for c in "xyz"])
            if np.all(np.abs(A[:, 1:]) <= MAX_POSITION_M):  # else the row-by-row reader names the line
                return A[:, 0], A[:, 1:], str(path)
    m = read_measurements(path)
    return m.stamps, m.T[:, :3, 3], m.source


def write_joint_states(path, stamps, joints, joint_names, joint_types=None, comments=()) -> Path:
    """Write joint states (SI) as CSV: ``stamp[s]`` then ``joint:<name>[rad]`` (``[m]`` for prismatic)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    types = joint_types or ["revolute"] * len(joint_names)
    header = ",".join(["stamp[s]"] + [f"joint:{n}[{'m' if t == 'prismatic' else 'rad'}]"
                                      for n, t in zip(joint_names, types)])
    head = "".join(f"# {c}\n" for c in comments) + header
    np.savetxt(path, np.column_stack([stamps, joints]), fmt=["%.6f"] + ["%.9f"] * len(joint_names), delimiter=",",
               header=head, comments="")
    return path


def write_points(path, stamps, points, comments=()) -> Path:
    """Write a tracker's points (m) as a measurement CSV: ``stamp[s],x[mm],y[mm],z[mm]``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    head = "".join(f"# {c}\n" for c in comments) + "stamp[s],x[mm],y[mm],z[mm]"
    np.savetxt(path, np.column_stack([stamps, np.asarray(points) * 1e3]), fmt=["%.6f", "%.5f", "%.5f", "%.5f"],
               delimiter=",", header=head, comments="")
    return path


def _loadtxt(body: str, use) -> np.ndarray:
    """(n, len(use)) numbers of the CSV ``body`` (0 rows for a file of a header alone, without numpy's warning)."""
    import warnings
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", "loadtxt: input contained no data", UserWarning)
        return np.loadtxt(io.StringIO(body), delimiter=",", comments="#", usecols=use, ndmin=2)
