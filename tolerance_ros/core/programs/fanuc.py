"""FANUC TP programs in their ASCII form (``.ls``): the positions of the ``/POS`` section.

A position ``P[n]`` (``P[n:"comment"]``) holds, for motion group 1 (``GP1``), its user frame and tool (``UF : u,
UT : t``) and either a Cartesian position (``CONFIG : 'F|N U|D T|B, t4, t5, t6'``, X, Y, Z mm; W, P, R deg,
``R = Rz(R) Ry(P) Rx(W)``) or joints (J1-J6 deg; a 7th joint as E1). UF 0 is the world frame and UT 0 the
faceplate. The configuration: F (flip) for J5 > 0, N otherwise; U with the wrist centre in front of the lower arm,
D behind it; T with the wrist centre in front of axis 1, B behind it; the turn numbers of J4, J5 and J6 (0 for
-180 to 180 deg, 1 for 180 to 540 deg, ...). FANUC's J3 is the forearm's angle from the horizontal (the J2/J3
interaction): with ``j3="absolute"`` (the default) the model's joint 3 is J3 minus J2 along joint 3's axis. Other
motion groups, positions in registers (``PR[n]``) and offsets added at run time are left as written; a motion with
an offset or to a register is listed.

The header is written as remarks at the end of ``/MN`` (TP has no comment outside it), 32 characters a line.
"""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from .configuration import keeps
from .model import BASE, Program, Target, Unresolved, Use, edits, pose_matrix
from .orientation import to_matrix
from .text import NUMBER, Lines, Number, ProgramError, read_text

NAME = "fanuc"
SUFFIXES = (".ls",)
REMARK = 32        # characters of a remark line

_ENTRY = re.compile(r"P\[\s*(\d+)\s*(?::\s*\"[^\"\r\n]*\"\s*)?\]\s*\{")
_GROUP = re.compile(r"GP(\d+)\s*:")
_VALUE = re.compile(r"\b([XYZWPR]|J\d+|E\d+)\s*=\s*(" + NUMBER + r")\s*(mm|deg)\b")
_FRAMES = re.compile(r"\bUF\s*:\s*(\w+)\s*,\s*UT\s*:\s*(\w+)")
_CONFIG = re.compile(r"CONFIG\s*:\s*'([^']*)'")
_CONFIG_TEXT = re.compile(r"\s*([FN])\s+([UD])\s+([TB])\s*,\s*(-?\d+)\s*,\s*(-?\d+)\s*,\s*(-?\d+)\s*")
_MOTION = re.compile(r"(?m)^[ \t]*(?:\d+[ \t]*:[ \t]*([JLCA])[ \t]+|:[ \t]*)(P|PR)\[\s*(\d+)[^\]\r\n]*\]([^\r\n]*)")
_NUMBERED = re.compile(r"(?m)^([ \t]*)(\d+):")


def _sections(text, path):
    """(offset of /MN, offset of /POS, offset of /END) of an .ls text; ProgramError for another file."""
    spots = {}
    for m in re.finditer(r"(?m)^/(PROG|ATTR|APPL|MN|POS|END)\b", text):
        spots.setdefault(m.group(1), m.start())
    if "PROG" not in spots or "MN" not in spots:
        raise ProgramError(f"{path}:1: not a TP program listing (.ls): no /PROG and /MN sections")
    return spots["MN"], spots.get("POS"), spots.get("END", len(text))


def read(paths) -> Program:
    texts, targets, unresolved = {}, [], []
    for path in map(Path, paths):
        text = read_text(path)
        texts[path] = text
        lines = Lines(text)
        mn, pos, end = _sections(text, path)
        stop = pos if pos is not None else end
        found = {}
        if pos is not None:
            at = pos
            while True:
                m = _ENTRY.search(text, at, end)
                if not m:
                    break
                close = text.find("};", m.end(), end)
                if close < 0:
                    raise ProgramError(f"{path}:{lines.line(m.start())}: P[{m.group(1)}] is never closed ('}};')")
                t = _position(text, m, close, path, lines)
                if t is not None:
                    targets.append(t)
                    found[int(m.group(1))] = t
                at = close + 2
        for m in _MOTION.finditer(text, mn, stop):
            line = lines.line(m.start())
            kind, index, rest = m.group(2), int(m.group(3)), m.group(4)
            what = f"{m.group(1) or ':'} {kind}[{index}]"
            if kind == "PR":
                unresolved.append(Unresolved(path, line, what, "a position register: its value is on the controller"))
                continue
            t = found.get(index)
            if t is None:
                unresolved.append(Unresolved(path, line, what, f"P[{index}] has no position in /POS"))
                continue
            t.uses.append(Use(path, line, t.tool, t.frame, what))
            extra = re.search(r"(?i)\b(Tool_Offset|Offset|VOFFSET|INC)\b", rest)
            if extra:
                unresolved.append(Unresolved(path, line, what, f"{extra.group(1)}: the offset is added at run time "
                                                               f"(P[{index}] itself is corrected)"))
    return Program(NAME, texts, targets, {}, {}, {}, {}, unresolved)


def _position(text, m, close, path, lines):
    """The Target of group 1 of a P[n] entry (None when it has no group 1)."""
    name = f"P[{m.group(1)}]"
    body_start = m.end()
    groups = list(_GROUP.finditer(text, body_start, close))
    g1 = next((k for k, g in enumerate(groups) if g.group(1) == "1"), None)
    if g1 is None:
        return None
    a = groups[g1].end()
    b = groups[g1 + 1].start() if g1 + 1 < len(groups) else close
    line = lines.line(m.start())
    where = f"{path}:{line}"
    fr = _FRAMES.search(text, a, b)
    if fr is None:
        raise ProgramError(f"{where}: {name}: no 'UF : n, UT : n'")
    frame, tool = (BASE if v == "0" else (v if v.isdigit() else None) for v in fr.groups())
    fields, units = {}, {}
    for v in _VALUE.finditer(text, a, b):
        key = v.group(1)
        fields[key] = Number(v.start(2), v.end(2), v.group(2))
        units[key] = v.group(3)
    cfg = _CONFIG.search(text, a, b)
    cartesian = all(k in fields for k in "XYZWPR")
    joints = "J1" in fields
    if cartesian == joints:
        raise ProgramError(f"{where}: {name}: expected X, Y, Z, W, P, R or J1... J6")
    config = {}
    if cartesian:
        if cfg is None:
            raise ProgramError(f"{where}: {name}: a Cartesian position without CONFIG")
        c = _CONFIG_TEXT.fullmatch(cfg.group(1))
        if c is None:
            raise ProgramError(f"{where}: {name}: CONFIG '{cfg.group(1)}' is not 'F|N U|D T|B, t4, t5, t6'")
        config = {"flip": c.group(1), "up": c.group(2), "front": c.group(3),
                  "turns": [int(c.group(k)) for k in (4, 5, 6)],
                  "spans": [(cfg.start(1) + c.start(k), cfg.start(1) + c.end(k)) for k in (4, 5, 6)]}
        if any(units[k] != "mm" for k in "XYZ") or any(units[k] != "deg" for k in "WPR"):
            raise ProgramError(f"{where}: {name}: X, Y, Z in mm and W, P, R in deg expected")
    t = Target(path, line, name, "pose" if cartesian else "joints", fields, {k: f.value for k, f in fields.items()},
               config, frame, tool, orientation="wpr")
    t.extra["units"] = units
    return t


def coupling(model) -> float:
    """+1 or -1: FANUC's J3 (from the horizontal) is the model's joint 3 plus this times joint 2 (the sign of the
    product of joints 2 and 3's axes at the zero pose)."""
    from ..models.ik import joint_jacobian
    _, J = joint_jacobian(model, np.zeros((1, model.dof)))
    return float(np.sign(J[0, 3:, 1] @ J[0, 3:, 2]) or 1.0)


def _joint_keys(dof):
    return [f"J{k + 1}" for k in range(min(dof, 6))] + [f"E{k + 1}" for k in range(max(dof - 6, 0))]


def decode(target: Target, model, setup):
    dof = model.dof
    windows = np.full((dof, 2), np.nan)
    want = np.zeros(3, int)
    if target.kind == "joints":
        keys = _joint_keys(dof)
        missing = [k for k in keys if k not in target.values]
        if missing:
            raise ProgramError(f"{target.where}: {target.name}: robot {model.name!r} has {dof} joints; no "
                               f"{', '.join(missing)}")
        units = target.extra["units"]
        for k, t in zip(keys, model.joint_types):
            if units[k] != ("mm" if t == "prismatic" else "deg"):
                raise ProgramError(f"{target.where}: {target.name}: {k} in {units[k]} for a {t} joint")
        q = np.array([target.values[k] * (1e-3 if t == "prismatic" else np.pi / 180)
                      for k, t in zip(keys, model.joint_types)])
        if setup.fanuc_j3_absolute and dof >= 3:
            q[2] -= setup.fanuc_coupling * q[1]
        return None, q, want, windows
    p = np.array([target.values[k] for k in "XYZ"]) * 1e-3
    R = to_matrix("wpr", [[target.values[k] for k in "WPR"]])[0]
    c = target.config
    want[:] = [1 if c["front"] == "T" else -1, 1 if c["up"] == "U" else -1, 1 if c["flip"] == "F" else -1]
    for j, t in zip((3, 4, 5), c["turns"]):
        windows[j] = [np.pi * (2 * t - 1), np.pi * (2 * t + 1)]
    return pose_matrix(p, R), None, want, windows


def turn(q) -> int:
    """FANUC's turn number of a joint angle (rad): 0 for [-180, 180) deg, 1 for [180, 540), -1 for [-540, -180)."""
    return int(np.floor((np.degrees(q) + 180.0) / 360.0 + 1e-12))


ORIENTATION = ("wpr", ("W", "P", "R"))


def encode(target: Target, q, T, orient, model, setup, fmt) -> list:
    units = target.extra["units"]
    if target.kind == "joints":
        keys = _joint_keys(model.dof)
        q = np.array(q, float)
        if setup.fanuc_j3_absolute and model.dof >= 3:
            q[2] += setup.fanuc_coupling * q[1]
        new = {k: (v * 1e3 if t == "prismatic" else np.degrees(v)) for k, v, t in zip(keys, q, model.joint_types)}
        return edits(target, new, lambda v, num, name: fmt(v, num, units[name]))
    new = dict(zip("XYZ", T[:3, 3] * 1e3))
    new.update(zip("WPR", orient))
    out = edits(target, new, lambda v, num, name: fmt(v, num, units[name]))
    for j, old, (a, b) in zip((3, 4, 5), target.config["turns"], target.config["spans"]):
        if not keeps(q[j], np.pi * (2 * old - 1), np.pi * (2 * old + 1)):
            out.append((a, b, str(turn(q[j]))))
    return out


def _remarks(lines_) -> list:
    """Remark texts of at most ``REMARK`` characters (words cut where they must be), no ';'."""
    out = []
    for line in lines_:
        line = line.replace(";", ",")
        while len(line) > REMARK:
            cut = line.rfind(" ", 0, REMARK + 1)
            cut = cut if cut > 0 else REMARK
            out.append(line[:cut].rstrip())
            line = line[cut:].lstrip()
        out.append(line)
    return out


def header(text: str, lines_: list, newline: str) -> str:
    """The text with ``lines_`` as remarks numbered after the last line of /MN."""
    mn, pos, end = _sections(text, "")
    stop = pos if pos is not None else end
    body = text[mn:stop]
    numbered = list(_NUMBERED.finditer(body))
    expect, style = 1, None
    for m in numbered:
        lead, num = m.group(1), int(m.group(2))
        width = len(lead.expandtabs(8)) + len(m.group(2))
        if style is None and num == 1:
            style = (lead, width)
        if style is not None and num == expect and (lead == style[0] or width == style[1]):
            expect += 1
    lead, width = style or ("   ", 4)
    out = []
    for k, remark in enumerate(_remarks(lines_)):
        num = str(expect + k)
        prefix = (lead + num) if "\t" in lead else num.rjust(width)
        out.append(f"{prefix}:  !{remark} ;{newline}")
    at = stop
    if at > 0 and text[at - 1] not in "\r\n":
        out.insert(0, newline)
    return text[:at] + "".join(out) + text[at:]
