"""Contact campaigns (calibration without a tracker), read and written.

CSV format: optional ``#`` comment lines, then a header, then a row per target in contact::

    stamp[s],pose,session,target,contact,joint:joint_1[rad],...,joint:joint_6[rad]

``contact`` is ``plane:<id>`` (the target lies on plane ``<id>``) or ``point:<id>`` (the target is at the fixed
point ``<id>``); each ``session`` has planes and points of its own (a table moved between days); ``target`` names
the point of the tool in contact (its nominal place in the tool frame comes from the command line); ``pose`` is
the test pose (optional: without it rows at equal joints form a pose). Joint columns are the joint readings (rad,
deg or mrad for revolute joints; m or mm for prismatic ones); a column for a joint the robot does not have is
ignored by the chain and listed (with an angle or length unit, its readings are kept: the rest of a standing robot's
posture, which loads its joints), a joint of the robot without a column is an error. Numbers as the measurement CSV reads them
(finite; no nan or inf). Every problem is a ``MeasurementError`` naming the file, the line and the column; with
``skip_bad`` a bad row is skipped and listed instead.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ...resources import not_a_file
from ...units import ANGLE_UNITS, LENGTH_UNITS
from .csv_format import _NOT_NUMERIC, _csv_row, _parse_header, separator_hint
from .measurements import MeasurementError
from .text import _check_text, _lines, _not_utf8, _show

_TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
_CONTACT = re.compile(r"^(plane|point):([A-Za-z0-9_.\-]{1,100})$")
_NAME = re.compile(r"^[^\x00-\x1f,]{0,100}$")
REQUIRED = ("stamp", "session", "target", "contact")
MAX_ROWS = 1_000_000


@dataclass
class Contacts:
    """Rows of a contact campaign (SI): stamps (n,) s; pose, session, target (n,) names; contact (n,)
    'plane:<id>' or 'point:<id>'; joints (n, dof) in the order of ``joint_names``; ``ignored`` the joint columns
    of joints the robot does not have; ``lines`` (n,) the line of each row; ``skipped`` [{line, reason}];
    ``others`` (n, m) the readings (SI) of the ignored columns ``other_names`` that carry an angle or length unit."""

    source: str
    stamps: np.ndarray
    pose: np.ndarray
    session: np.ndarray
    target: np.ndarray
    contact: np.ndarray
    joints: np.ndarray
    joint_names: tuple
    lines: np.ndarray
    ignored: list = field(default_factory=list)
    skipped: list = field(default_factory=list)
    others: np.ndarray | None = None
    other_names: tuple = ()

    def __len__(self):
        return len(self.stamps)

    def select(self, keep) -> "Contacts":
        keep = np.asarray(keep)
        return Contacts(self.source, self.stamps[keep], self.pose[keep], self.session[keep], self.target[keep],
                        self.contact[keep], self.joints[keep], self.joint_names, self.lines[keep], list(self.ignored),
                        list(self.skipped), None if self.others is None else self.others[keep], self.other_names)

    def where(self, i) -> str:
        return f"line {int(self.lines[i])}"


def is_contact_campaign(path) -> bool:
    """True for a contact campaign: a CSV with a ``contact`` column, or a campaign log with ``contact`` events."""
    p = Path(path)
    if p.suffix.lower() in (".jsonl", ".log") and p.is_file():
        with open(p, encoding="utf-8", errors="surrogateescape") as fh:
            for _, line in _lines(fh):
                if line is not None and '"event": "contact"' in line.replace('"event":"contact"', '"event": "contact"'):
                    return True
        return False
    return is_contact_csv(p)


def read_contact_campaign(path, joint_names, joint_types=None, skip_bad=False) -> tuple:
    """(Contacts, {target: (3,) m or None}) of a contact CSV (no offsets in it: {}) or a campaign log (the
    offsets its contact requests carried)."""
    if Path(path).suffix.lower() in (".jsonl", ".log"):
        return read_contact_log(path, joint_names, skip_bad)
    return read_contacts(path, joint_names, joint_types, skip_bad), {}


def read_contact_log(path, joint_names, skip_bad=False) -> tuple:
    """(Contacts, {target: offset (3,) m or None}) of the ``contact`` events of the accuracy monitor's campaign log
    (``services.monitor.MonitorLogic.on_contact``); other events are not read. A malformed contact event is an
    error naming its line, or with ``skip_bad`` is listed in ``skipped``. The readings of the joints outside the
    chain (``other_joint_names``, ``other_joints``, rad or m) are kept for the joints every event has."""
    import json
    p = Path(path)
    if not p.is_file():
        raise MeasurementError(f"{path}: {not_a_file(p)}")
    src = str(path)
    joint_names = tuple(joint_names)
    rows, skipped, offsets = [], [], {}
    with open(p, encoding="utf-8", errors="surrogateescape") as fh:
        for lineno, line in _lines(fh):
            if line is None or '"contact"' not in line:
                continue
            try:
                rec = json.loads(line)
                if not isinstance(rec, dict) or rec.get("event") != "contact":
                    continue
                names, joints = rec.get("joint_names"), rec.get("joints")
                if not isinstance(names, list) or not isinstance(joints, list) or len(names) != len(joints):
                    raise MeasurementError("joint_names, joints: expected two lists of one length")
                by = dict(zip(names, joints))
                missing = [j for j in joint_names if j not in by]
                if missing:
                    raise MeasurementError(f"joints: no value for joint(s) {missing} of the robot")
                q = [_number(repr(by[j]) if isinstance(by[j], (int, float)) else str(by[j]), f"joint:{j}")
                     for j in joint_names]
                contact = rec.get("contact")
                if not isinstance(contact, str) or not _CONTACT.match(contact):
                    raise MeasurementError(f"contact: expected plane:ID or point:ID, got {_show(str(contact))}")
                target = _name(str(rec.get("target", "")), "target")
                if not target:
                    raise MeasurementError("target: empty")
                off = rec.get("offset_m")
                if off is not None:
                    off = [_number(repr(v) if isinstance(v, (int, float)) else str(v), "offset_m") for v in off]
                    if len(off) != 3:
                        raise MeasurementError("offset_m: expected [x, y, z]")
                if offsets.get(target) is None:
                    offsets[target] = off
                stamp = _number(repr(rec.get("stamp")), "stamp")
                onames, ovals = rec.get("other_joint_names") or [], rec.get("other_joints") or []
                if not isinstance(onames, list) or not isinstance(ovals, list) or len(onames) != len(ovals):
                    raise MeasurementError("other_joint_names, other_joints: expected two lists of one length")
                other = {str(n): _number(repr(v) if isinstance(v, (int, float)) else str(v), f"joint:{n}")
                         for n, v in zip(onames, ovals) if str(n) not in joint_names}
                rows.append((stamp, _name(str(rec.get("pose") or ""), "pose"), _name(str(rec.get("session") or ""),
                                                                                     "session"),
                             target, contact, q, lineno, other))
            except (MeasurementError, ValueError) as exc:
                if not skip_bad:
                    raise MeasurementError(f"{src}, line {lineno}: {exc}") from None
                skipped.append({"line": lineno, "reason": str(exc)})
    if not rows:
        raise MeasurementError(f"{src}: no contact events")
    common = [n for n in rows[0][7] if all(n in r[7] for r in rows)]
    ignored = sorted({n for r in rows for n in r[7]} - set(common))
    out = Contacts(src, np.array([r[0] for r in rows]), np.array([r[1] for r in rows], dtype=object),
                   np.array([r[2] for r in rows], dtype=object), np.array([r[3] for r in rows], dtype=object),
                   np.array([r[4] for r in rows], dtype=object), np.array([r[5] for r in rows], float), joint_names,
                   np.array([r[6] for r in rows]), ignored, skipped,
                   np.array([[r[7][n] for n in common] for r in rows], float).reshape(len(rows), len(common)),
                   tuple(common))
    return out, offsets


def is_contact_csv(path) -> bool:
    """True when ``path`` is a CSV file whose header has a ``contact`` column."""
    p = Path(path)
    if p.suffix.lower() != ".csv" or not p.is_file():
        return False
    with open(p, encoding="utf-8", errors="surrogateescape", newline="") as fh:
        for _, line in _lines(fh):
            if line is None:
                return False
            if line.strip() and not line.lstrip().startswith("#"):
                return any(h.split("[")[0].strip() == "contact" for h in line.rstrip("\r\n").split(","))
    return False


def read_contacts(path, joint_names, joint_types=None, skip_bad=False) -> Contacts:
    """The contact campaign at ``path`` for a robot with ``joint_names`` (``joint_types`` 'revolute' or
    'prismatic' each, to check the units); see the module docstring."""
    p = Path(path)
    if not p.is_file():
        raise MeasurementError(f"{path}: {not_a_file(p)}")
    src = str(path)
    joint_names = tuple(joint_names)
    types = tuple(joint_types) if joint_types is not None else ("revolute",) * len(joint_names)
    rows, skipped = [], []
    spec = None
    with open(p, encoding="utf-8", errors="surrogateescape", newline="") as fh:
        for lineno, line in _lines(fh):
            try:
                bad = _check_text(line)
                if bad is not None:
                    raise MeasurementError(_not_utf8(line, bad))
                if not line.strip() or line.lstrip().startswith("#"):
                    continue
                if spec is None:
                    spec = _header(_csv_row(line, None), src, joint_names, types)
                    continue
                rows.append(_row(_csv_row(line, None), spec, lineno))
                if len(rows) > MAX_ROWS:
                    raise MeasurementError(f"more than {MAX_ROWS:,} rows; split the campaign")
            except MeasurementError as exc:
                if spec is None or not skip_bad or "more than" in str(exc):
                    msg = str(exc)
                    raise MeasurementError(msg if msg.startswith(src) else f"{src}, line {lineno}: {msg}") from None
                skipped.append({"line": lineno, "reason": str(exc)})
    if spec is None:
        raise MeasurementError(f"{src}: no header (expected {','.join(f'{c}[s]' if c == 'stamp' else c for c in REQUIRED)}"
                               f",joint:NAME[rad],...)")
    if not rows:
        raise MeasurementError(f"{src}: no contacts" + (f" ({len(skipped)} bad row(s) skipped, the first on line "
                                                        f"{skipped[0]['line']}: {skipped[0]['reason']})" if skipped
                                                        else ""))
    stamps = np.array([r[0] for r in rows])
    out = Contacts(src, stamps, np.array([r[1] for r in rows], dtype=object), np.array([r[2] for r in rows], dtype=object),
                   np.array([r[3] for r in rows], dtype=object), np.array([r[4] for r in rows], dtype=object),
                   np.array([r[5] for r in rows], float).reshape(len(rows), len(joint_names)), joint_names,
                   np.array([r[6] for r in rows]), spec["ignored"], skipped,
                   np.array([r[7] for r in rows], float).reshape(len(rows), len(spec["others"])), tuple(spec["others"]))
    return out


def _header(header, src, joint_names, types):
    cols = _parse_header(header, src)
    missing = [c for c in REQUIRED if c not in cols]
    if missing:
        raise MeasurementError(f"{src}: a contact campaign needs the column(s) {missing}; its header has "
                               f"{list(cols)}{separator_hint(header)}")
    known = set(REQUIRED) | {"pose"}
    unknown = [c for c in cols if c not in known and not c.startswith("joint:")]
    if unknown:
        raise MeasurementError(f"{src}: unknown column(s) {unknown} (a contact campaign has "
                               f"stamp, pose, session, target, contact and joint:NAME columns)")
    unit = cols["stamp"][1]
    if unit not in _TIME_UNITS:
        raise MeasurementError(f"{src}: column 'stamp' needs a time unit in brackets ({', '.join(_TIME_UNITS)}), got "
                               f"{unit!r}")
    for c in ("pose", "session", "target", "contact"):
        if c in cols and cols[c][1]:
            raise MeasurementError(f"{src}: column {c!r} holds names; it takes no unit, got [{cols[c][1]}]")
    jcols = {c[len("joint:"):]: v for c, v in cols.items() if c.startswith("joint:")}
    absent = [j for j in joint_names if j not in jcols]
    if absent:
        raise MeasurementError(f"{src}: no column for joint(s) {absent} of the robot (joint:NAME[rad] columns; the "
                               f"file has {list(jcols) or 'none'})")
    scale, index = [], []
    for j, t in zip(joint_names, types):
        i, u = jcols[j]
        table = LENGTH_UNITS if t == "prismatic" else ANGLE_UNITS
        if u not in table:
            raise MeasurementError(f"{src}: column 'joint:{j}' ({t}) needs {'a length' if t == 'prismatic' else 'an angle'} "
                                   f"unit in brackets ({', '.join(sorted(table))}), got {u!r}")
        scale.append(table[u])
        index.append(i)
    others = [(j, jcols[j][0], ANGLE_UNITS.get(jcols[j][1], LENGTH_UNITS.get(jcols[j][1])))
              for j in sorted(set(jcols) - set(joint_names))]
    others = [o for o in others if o[2] is not None]
    return {"ncols": len(header), "stamp": (cols["stamp"][0], _TIME_UNITS[unit]),
            "pose": cols["pose"][0] if "pose" in cols else None, "session": cols["session"][0],
            "target": cols["target"][0], "contact": cols["contact"][0], "joints": index, "scale": np.array(scale),
            "names": [f"joint:{j}" for j in joint_names], "ignored": sorted(set(jcols) - set(joint_names)),
            "others": [o[0] for o in others], "other_columns": [(o[1], f"joint:{o[0]}", o[2]) for o in others],
            "source": src}


def _number(text, name):
    t = text.strip()
    if not t or _NOT_NUMERIC.search(t):
        raise MeasurementError(f"{name}: not a number: {_show(text)}")
    try:
        v = float(t)
    except ValueError:
        raise MeasurementError(f"{name}: not a number: {_show(text)}") from None
    if not np.isfinite(v):
        raise MeasurementError(f"{name}: not a finite number: {_show(text)}")
    return v


def _name(text, name):
    t = text.strip()
    if not _NAME.match(t):
        raise MeasurementError(f"{name}: a name of at most 100 printable characters, got {_show(t)}")
    return t


def _row(fields, spec, lineno):
    if len(fields) != spec["ncols"]:
        raise MeasurementError(f"{len(fields)} fields where the header has {spec['ncols']}")
    i, s = spec["stamp"]
    stamp = _number(fields[i], "stamp") * s
    contact = fields[spec["contact"]].strip()
    if not _CONTACT.match(contact):
        raise MeasurementError(f"contact: expected plane:ID or point:ID (ID of letters, digits, _ . -), got "
                               f"{_show(contact)}")
    target = _name(fields[spec["target"]], "target")
    if not target:
        raise MeasurementError("target: empty (name the point of the tool in contact)")
    pose = _name(fields[spec["pose"]], "pose") if spec["pose"] is not None else ""
    session = _name(fields[spec["session"]], "session")
    q = [_number(fields[k], n) * sc for k, n, sc in zip(spec["joints"], spec["names"], spec["scale"])]
    others = [_number(fields[k], n) * sc for k, n, sc in spec["other_columns"]]
    return stamp, pose, session, target, contact, q, lineno, others


def write_contacts(path, stamps, pose, session, target, contact, joints, joint_names, joint_types=None, comments=()):
    """Write a contact campaign: joints (n, dof) in rad (m for the prismatic ones of ``joint_types``)."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    types = joint_types or ("revolute",) * len(joint_names)
    lines = [f"# {c}" for c in comments]
    lines.append(",".join(["stamp[s]", "pose", "session", "target", "contact"] + [
        f"joint:{j}[{'m' if t == 'prismatic' else 'rad'}]" for j, t in zip(joint_names, types)]))
    for k in range(len(stamps)):
        lines.append(",".join([repr(float(stamps[k])), str(pose[k]), str(session[k]), str(target[k]), str(contact[k])]
                              + [repr(float(v)) for v in joints[k]]))
    p.write_text("\n".join(lines) + "\n")
    return p
