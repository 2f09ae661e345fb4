"""ABB RAPID modules (``.mod``, ``.modx``, ``.prg``, ``.sys``): ``robtarget`` and ``jointtarget`` data, declared
(``CONST``, ``PERS``, ``VAR``, also in arrays) or written inline in the motion instructions; the ``tooldata`` and
``wobjdata`` they use.

- robtarget ``[[x, y, z], [q1, q2, q3, q4], [cf1, cf4, cf6, cfx], [eax_a, ..., eax_f]]``: mm, a quaternion (q1 the
  scalar), the configuration (the quadrants of axes 1, 4 and 6, and ``cfx``: 4 when the wrist centre is behind axis
  1, 2 when it is behind the lower arm, 1 when axis 5 is negative), the external axes (left as written);
- jointtarget ``[[rax_1, ..., rax_6], [eax_a, ..., eax_f]]``: degrees (mm for a linear axis); a 7-joint arm's 7th
  joint is ``eax_a``;
- tooldata ``[robhold, [[x, y, z], [q1, ..., q4]], [load]]``: the tool frame in the flange frame (a tool the robot
  does not hold is refused); wobjdata ``[robhold, ufprog, ufmec, uframe, oframe]``: a target's frame is
  ``uframe * oframe`` in the world frame (a work object the robot holds or that moves is refused).

A motion instruction (``MoveJ``, ``MoveL``, ``MoveC``, ``MoveAbsJ`` and their ``DO``, ``Sync``, ``AO``, ``GO``
forms; ``TriggJ/L/C``; ``SearchL/C``; ``ArcL/C``; ``CapL/C``; ``PaintL/C``) moves to its first argument (its first
two for a circular one, after the signal and the search point for a search); its tool is its last positional
argument, its work object ``\\WObj`` (``wobj0``: the world frame). RAPID names are case-insensitive.
"""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from .configuration import keeps
from .model import BASE, Program, Target, Unresolved, Use, pose_matrix
from .orientation import to_matrix
from .text import NUMBER, Lines, Number, ProgramError, mask, read_text, split_top

NAME = "rapid"
SUFFIXES = (".mod", ".modx", ".prg", ".sys")
COMMENT = "!"
MARK = "tolerance-ros filter"

_DECL = re.compile(r"(?i)\b(?:(?:LOCAL|TASK)\s+)?(CONST|PERS|VAR)\s+(robtarget|jointtarget|tooldata|wobjdata)\s+"
                   r"([A-Za-z]\w*)\s*(\{[^}]*\})?\s*(:=)?")
MOTIONS = ("MoveJ", "MoveL", "MoveC", "MoveAbsJ", "MoveJDO", "MoveLDO", "MoveCDO", "MoveJSync", "MoveLSync",
           "MoveCSync", "MoveJAO", "MoveLAO", "MoveCAO", "MoveJGO", "MoveLGO", "MoveCGO", "TriggJ", "TriggL", "TriggC",
           "TriggJIOs", "TriggLIOs", "SearchL", "SearchC", "ArcL", "ArcC", "ArcLStart", "ArcLEnd", "ArcCStart",
           "ArcCEnd", "ArcL1", "ArcL2", "ArcC1", "ArcC2", "CapL", "CapC", "PaintL", "PaintC")
_MOTION = re.compile(r"(?i)(?<![\w.])(" + "|".join(sorted(MOTIONS, key=len, reverse=True)) + r")(?![\w])")
_SPACE = re.compile(r"\s*")
_IDENT = re.compile(r"([A-Za-z]\w*)(?:\s*\{\s*(\d+)\s*\})?$")
_BOOL = {"TRUE": True, "FALSE": False}


# ---------------------------------------------------------------- aggregates

_TOKEN = re.compile(r"\s*(?:([\[\],])|(" + NUMBER + r")(?![\w.])|([A-Za-z_]\w*)|(\"[^\"\r\n]*\"))")


def _aggregate(text, code, start, where):
    """(nested lists of leaves, end) of the aggregate ``[...]`` at ``start`` of ``code`` (comments blanked, strings
    kept): a leaf is a ``Number`` or the raw text of a name, a boolean or a string."""
    stack, i = [[]], start
    if code[start] != "[":
        raise ProgramError(f"{where}: expected an aggregate '[...]'")
    i += 1
    while True:
        m = _TOKEN.match(code, i)
        if m is None:
            rest = code[i:i + 30].strip().split("\n")[0]
            if not rest or rest.startswith(";"):
                raise ProgramError(f"{where}: an aggregate '[' is never closed")
            raise ProgramError(f"{where}: {rest!r} is not a literal value (a target written as an expression is "
                               f"computed at run time)")
        punct, number, name, string = m.groups()
        i = m.end()
        if punct is None:
            after = _SPACE.match(code, i).end()
            if after >= len(code) or code[after] not in ",]":
                rest = code[m.start():m.start() + 30].strip().split("\n")[0]
                raise ProgramError(f"{where}: {rest!r} is not a literal value (a target written as an expression is "
                                   f"computed at run time)")
        if punct == "[":
            stack.append([])
        elif punct == "]":
            done = stack.pop()
            if not stack:
                return done, i
            stack[-1].append(done)
        elif punct == ",":
            pass
        elif number is not None:
            value = float(number)
            if not np.isfinite(value):
                raise ProgramError(f"{where}: {number!r} is not a finite number")
            stack[-1].append(Number(m.start(2), m.end(2), number))
        else:
            stack[-1].append(name or string)


def _shape(agg, shape, what, where):
    """Check that ``agg`` has the nested ``shape`` (a list of sizes or sub-shapes; 'n' a number, 'x' anything)."""
    if isinstance(shape, str):
        if shape == "n" and not isinstance(agg, Number):
            raise ProgramError(f"{where}: {what}: expected a number, got {agg!r}")
        return
    if not isinstance(agg, list) or len(agg) != len(shape):
        raise ProgramError(f"{where}: {what}: expected an aggregate of {len(shape)} components")
    for a, s in zip(agg, shape):
        _shape(a, s, what, where)


ROBTARGET = [["n"] * 3, ["n"] * 4, ["n"] * 4, ["n"] * 6]
JOINTTARGET = [["n"] * 6, ["n"] * 6]
POSE = [["n"] * 3, ["n"] * 4]


def _frame(pose_agg) -> np.ndarray:
    """4x4 (m) of a RAPID pose aggregate [[x, y, z], [q1, ..., q4]] (mm)."""
    p = np.array([v.value for v in pose_agg[0]]) * 1e-3
    return pose_matrix(p, to_matrix("quat", [[v.value for v in pose_agg[1]]])[0])


def _robtarget(agg, path, line, name) -> Target:
    where = f"{path}:{line}"
    _shape(agg, ROBTARGET, f"robtarget {name}", where)
    fields = {f: agg[0][k] for k, f in enumerate(("x", "y", "z"))}
    fields.update({f: agg[1][k] for k, f in enumerate(("q1", "q2", "q3", "q4"))})
    fields.update({f: agg[2][k] for k, f in enumerate(("cf1", "cf4", "cf6", "cfx"))})
    config = {}
    for f in ("cf1", "cf4", "cf6", "cfx"):
        v = fields[f].value
        if v != int(v):
            raise ProgramError(f"{where}: robtarget {name}: {f} must be a whole number, got {fields[f].text}")
        config[f] = int(v)
    if not 0 <= config["cfx"] <= 7:
        raise ProgramError(f"{where}: robtarget {name}: cfx {config['cfx']} is not one of 0-7")
    values = {f: fields[f].value for f in fields}
    return Target(path, line, name, "pose", fields, values, config, orientation="quat")


def _jointtarget(agg, path, line, name) -> Target:
    where = f"{path}:{line}"
    _shape(agg, JOINTTARGET, f"jointtarget {name}", where)
    fields = {f"j{k + 1}": agg[0][k] for k in range(6)}
    fields.update({f"e{k + 1}": agg[1][k] for k in range(6)})
    return Target(path, line, name, "joints", fields, {f: v.value for f, v in fields.items()})


# ---------------------------------------------------------------- reading

def read(paths) -> Program:
    """The targets, tools, work objects and motions of RAPID module files."""
    texts, decls, stmts = {}, {}, []
    targets, tools, frames, refused_tools, refused_frames, unresolved = [], {}, {}, {}, {}, []
    for path in paths:
        path = Path(path)
        text = read_text(path)
        texts[path] = text
        code = mask(text, COMMENT, '"')
        values = mask(text, COMMENT, '"', keep_strings=True)
        lines = Lines(text)
        for m in _DECL.finditer(code):
            storage, kind, name, dims, assign = m.groups()
            line = lines.line(m.start())
            where = f"{path}:{line}"
            kind = kind.lower()
            if not assign:
                if kind in ("robtarget", "jointtarget"):
                    decls.setdefault(name.lower(), []).append(("runtime", kind, path, line))
                continue
            start = _SPACE.match(code, m.end()).end()
            if start >= len(code) or code[start] != "[":
                decls.setdefault(name.lower(), []).append(("runtime", kind, path, line))
                continue
            agg, end = _aggregate(text, values, start, where)
            if not code.startswith(";", _SPACE.match(code, end).end()):
                raise ProgramError(f"{where}: declaration of {name}: expected ';' after its value")
            items = [(name, agg)]
            if dims:
                items = [(f"{name}{{{k + 1}}}", a) for k, a in enumerate(agg)]
                if not all(isinstance(a, list) for a in agg):
                    raise ProgramError(f"{where}: {name}: expected an array of aggregates")
            for item_name, item in items:
                key = item_name.lower()
                if kind == "robtarget":
                    t = _robtarget(item, path, line, item_name)
                    t.extra["storage"] = storage.upper()
                    targets.append(t)
                    decls.setdefault(key, []).append(("target", t, path, line))
                elif kind == "jointtarget":
                    t = _jointtarget(item, path, line, item_name)
                    t.extra["storage"] = storage.upper()
                    targets.append(t)
                    decls.setdefault(key, []).append(("target", t, path, line))
                elif kind == "tooldata":
                    _shape(item, ["x", POSE, "x"], f"tooldata {item_name}", where)
                    if _BOOL.get(str(item[0]).upper()) is False:
                        refused_tools[key] = (f"tooldata {item_name} ({where}) is a stationary tool (robhold FALSE): "
                                              f"the robot holds the work object")
                    tools[key] = _frame(item[1])
                else:
                    _shape(item, ["x", "x", "x", POSE, POSE], f"wobjdata {item_name}", where)
                    if _BOOL.get(str(item[0]).upper()) is True:
                        refused_frames[key] = (f"wobjdata {item_name} ({where}) is held by the robot (robhold TRUE): "
                                               f"its tool is stationary")
                    elif _BOOL.get(str(item[1]).upper()) is False:
                        refused_frames[key] = (f"wobjdata {item_name} ({where}) moves with a mechanical unit "
                                               f"(ufprog FALSE)")
                    frames[key] = _frame(item[3]) @ _frame(item[4])
        stmts.append((path, values, code, lines))
    for path, text, code, lines in stmts:
        for m in _MOTION.finditer(code):
            k = m.start()
            while k > 0 and code[k - 1] in " \t":
                k -= 1
            if k > 0 and code[k - 1] not in ";\r\n" and not re.search(r"(?i)\b(THEN|ELSE|DO)$", code[max(0, k - 8):k]):
                continue
            end = code.find(";", m.end())
            if end < 0:
                raise ProgramError(f"{path}:{lines.line(m.start())}: {m.group(1)}: no ';' ends it")
            _motion(m.group(1), text, code, m.end(), end, path, lines.line(m.start()), decls, targets, unresolved)
    return Program(NAME, texts, targets, tools, frames, refused_tools, refused_frames, unresolved)


def _options(part: str) -> dict:
    return {k.lower(): v.strip() for k, v in re.findall(r"\\(\w+)(?:\s*:=\s*([^\\]*))?", part)}


def _motion(instr, text, code, start, end, path, line, decls, targets, unresolved):
    where = f"{path}:{line}"
    parts = [(a, b) for a, b in split_top(code, start, end)]
    positional, options = [], {}
    for a, b in parts:
        chunk = code[a:b]
        cut = chunk.find("\\")
        head = chunk if cut < 0 else chunk[:cut]
        options.update(_options(chunk if cut < 0 else chunk[cut:]))
        if head.strip():
            off = a + len(head) - len(head.lstrip())
            positional.append((off, a + len(head.rstrip())))
    low = instr.lower()
    circular = re.match(r"(?i)(move|trigg|arc|cap|paint|search)c", low) is not None
    joint = "absj" in low
    if low.startswith("search"):
        idx = [2, 3] if circular else [2]
    else:
        idx = [0, 1] if circular else [0]
    if len(positional) < max(idx) + 2:
        raise ProgramError(f"{where}: {instr}: expected its target(s), speed and tool")
    tool = code[positional[-1][0]:positional[-1][1]].strip()
    wobj = options.get("wobj", "wobj0")
    use = Use(path, line, BASE if tool.lower() == "tool0" else tool, BASE if wobj.lower() == "wobj0" else wobj, instr)
    for k in idx:
        a, b = positional[k]
        arg = code[a:b].strip()
        if arg.startswith("["):
            agg, _ = _aggregate(text, text, a + code[a:b].index("["), where)
            t = (_jointtarget if joint else _robtarget)(agg, path, line, f"{instr} at line {line}")
            t.uses.append(use)
            targets.append(t)
            continue
        m = _IDENT.match(arg)
        found = decls.get((m.group(1) + (f"{{{m.group(2)}}}" if m.group(2) else "")).lower()) if m else None
        if found and len(found) > 1:
            same = [d for d in found if d[2] == path]
            found = same[:1] if len(same) == 1 else found
        if not found or len(found) != 1 or found[0][0] != "target":
            why = ("computed at run time" if not found or (found and found[0][0] == "runtime")
                   else f"{arg} is declared {len(found)} times")
            if m and not found:
                why = f"{arg} is not declared in these files"
            unresolved.append(Unresolved(path, line, f"{instr} {arg}", why))
            continue
        t = found[0][1]
        if (t.kind == "joints") != joint:
            raise ProgramError(f"{where}: {instr}: {arg} is a {'jointtarget' if t.kind == 'joints' else 'robtarget'}")
        t.uses.append(use)


# ---------------------------------------------------------------- values

def decode(target: Target, model, setup):
    """(pose 4x4 in its frame or None, joints (dof,) or None, want (3,), windows (dof, 2))."""
    dof = model.dof
    windows = np.full((dof, 2), np.nan)
    want = np.zeros(3, int)
    if target.kind == "joints":
        raw = [target.values[f"j{k + 1}"] for k in range(6)] + [target.values[f"e{k + 1}"] for k in range(6)]
        if dof > 12:
            raise ProgramError(f"{target.where}: a jointtarget holds 12 axes; robot {model.name!r} has {dof}")
        q = np.array([v * (1e-3 if t == "prismatic" else np.pi / 180) for v, t in zip(raw[:dof], model.joint_types)])
        return None, q, want, windows
    p = np.array([target.values[f] for f in ("x", "y", "z")]) * 1e-3
    R = to_matrix("quat", [[target.values[f] for f in ("q1", "q2", "q3", "q4")]])[0]
    c = target.config
    want[:] = [-1 if c["cfx"] & 4 else 1, -1 if c["cfx"] & 2 else 1, -1 if c["cfx"] & 1 else 1]
    for j, f in ((0, "cf1"), (3, "cf4"), (5, "cf6")):
        windows[j] = np.radians([90.0 * c[f], 90.0 * (c[f] + 1)])
    return pose_matrix(p, R), None, want, windows


def quadrant(q) -> int:
    """ABB's quadrant of a joint angle (rad): 0 for [0, 90) deg, 1 for [90, 180), -1 for [-90, 0), ..."""
    return int(np.floor(np.degrees(q) / 90.0 + 1e-12))


ORIENTATION = ("quat", ("q1", "q2", "q3", "q4"))


def encode(target: Target, q, T, orient, model, setup, fmt) -> list:
    """Edits writing the corrected target: joints ``q`` (model, SI) or pose ``T`` (4x4, m, in its frame) with its
    orientation written ``orient`` (``ORIENTATION``'s values nearest the old ones) and its configuration from ``q``."""
    from .model import edits
    if target.kind == "joints":
        new = {f"j{k + 1}" if k < 6 else f"e{k - 5}": (v * 1e3 if t == "prismatic" else np.degrees(v))
               for k, (v, t) in enumerate(zip(q, model.joint_types))}
        units = {k: "deg" for k in new}
        units.update({f"j{k + 1}" if k < 6 else f"e{k - 5}": "mm" for k, t in enumerate(model.joint_types)
                      if t == "prismatic"})
        return edits(target, new, lambda v, num, name: fmt(v, num, units[name]))
    new = dict(zip(("x", "y", "z"), T[:3, 3] * 1e3))
    new.update(zip(("q1", "q2", "q3", "q4"), orient))
    units = {"x": "mm", "y": "mm", "z": "mm", "q1": "quat", "q2": "quat", "q3": "quat", "q4": "quat"}
    out = edits(target, new, lambda v, num, name: fmt(v, num, units[name]))
    for name, j in (("cf1", 0), ("cf4", 3), ("cf6", 5)):
        num = target.fields[name]
        old = int(num.value)
        if not keeps(q[j], *np.radians([90.0 * old, 90.0 * (old + 1)])):
            out.append((num.start, num.end, str(quadrant(q[j]))))
    return out


def header(text: str, lines_: list, newline: str) -> str:
    """The text with ``lines_`` as comments after its MODULE line (at its start when it has none)."""
    code = mask(text, COMMENT, '"')
    m = re.search(r"(?im)^[ \t]*MODULE\b[^\r\n]*(\r\n|\r|\n|$)", code)
    at = m.end() if m else 0
    indent = "    "
    block = "".join(f"{indent}! {line}{newline}" for line in lines_)
    if m and not m.group(1):
        block = newline + block
    return text[:at] + block + text[at:]
