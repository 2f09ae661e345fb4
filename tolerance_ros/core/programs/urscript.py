"""Universal Robots URScript (``.script``, ``.urscript``): the targets of ``movej``, ``movel``, ``movep``,
``movec`` and ``servoj``.

A target is a pose ``p[x, y, z, rx, ry, rz]`` (m; the rotation vector, rad) of the tool centre point, or joints
``[q1, ..., q6]`` (rad), written in the call, in a variable assigned once from such a literal, in
``get_inverse_kin(...)``, or in a feature frame ``pose_trans(FRAME, ...)`` (``FRAME`` a variable holding a pose
literal, or given with ``--frame``). The tool centre point is the one the last ``set_tcp(p[...])`` before the
motion set, else the installation's (``--tool``). A pose is solved, as the controller does, near the joints the
robot has when it starts the motion: the configuration of the target before it in the script, and the turns of
the last joint target. Anything else (a pose computed at run time) is listed and left as written.
"""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from .model import BASE, Program, Target, Unresolved, Use, edits, pose_matrix
from .orientation import to_matrix
from .text import Lines, ProgramError, mask, matching, number_at, read_text, split_top

NAME = "urscript"
SUFFIXES = (".script", ".urscript")
COMMENT = "#"
INHERITS = "nearest"   # a pose without configuration: see filtering._inherit

_ASSIGN = re.compile(r"(?m)^[ \t]*(?:(?:global|local)[ \t]+)?([A-Za-z_]\w*)[ \t]*=(?!=)[ \t]*")
_CALL = re.compile(r"\b(movej|movel|movep|movec|servoj|set_tcp)\s*\(")
_LITERAL = re.compile(r"(p?)\s*\[")


def _literal(text, code, start, end, where):
    """(kind 'pose' or 'list', [Number], (start, end)) of a literal ``p[...]`` or ``[...]`` filling
    ``code[start:end]``, or None."""
    chunk = code[start:end]
    m = _LITERAL.match(chunk.lstrip())
    if not m:
        return None
    open_at = start + len(chunk) - len(chunk.lstrip()) + m.end() - 1
    close = matching(code, open_at, "[", "]", where)
    if code[close:end].strip():
        return None
    nums = []
    for a, b in split_top(code, open_at + 1, close - 1):
        if not re.fullmatch(r"\s*[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?\s*", code[a:b]):
            return None
        nums.append(number_at(text, a, b, where))
    return ("pose" if m.group(1) else "list"), nums, (start, close)


def _args(code, open_at, where):
    close = matching(code, open_at, "(", ")", where)
    parts = [p for p in split_top(code, open_at + 1, close - 1) if code[p[0]:p[1]].strip()]
    return [p for p in parts if not re.match(r"\s*[A-Za-z_]\w*\s*=(?!=)", code[p[0]:p[1]])], close


def read(paths) -> Program:
    texts, targets, unresolved, frames, tools = {}, [], [], {}, {}
    for path in map(Path, paths):
        text = read_text(path)
        texts[path] = text
        code = mask(text, COMMENT, "\"'")
        lines = Lines(text)
        assigned = {}
        for m in _ASSIGN.finditer(code):
            name = m.group(1)
            end = code.find("\n", m.end())
            end = len(code) if end < 0 else end
            lit = _literal(text, code, m.end(), end, f"{path}:{lines.line(m.start())}")
            assigned.setdefault(name, []).append((lit, lines.line(m.start())))
        variables = {}
        for name, found in assigned.items():
            if len(found) == 1 and found[0][0] is not None:
                kind, nums, _ = found[0][0]
                variables[name] = (kind, nums, found[0][1])
                if kind == "pose" and len(nums) == 6:
                    frames[name] = _pose([n.value for n in nums])
        tool = None
        declared = {}
        for m in _CALL.finditer(code):
            line = lines.line(m.start())
            where = f"{path}:{line}"
            fn = m.group(1)
            args, close = _args(code, m.end() - 1, where)
            if fn == "set_tcp":
                lit = _literal(text, code, *args[0], where) if args else None
                arg = code[args[0][0]:args[0][1]].strip() if args else ""
                if lit and lit[0] == "pose" and len(lit[1]) == 6:
                    tool = f"set_tcp at line {line}"
                    tools[tool] = _pose([n.value for n in lit[1]])
                elif arg in variables and variables[arg][0] == "pose":
                    tool = f"set_tcp({arg}) at line {line}"
                    tools[tool] = _pose([n.value for n in variables[arg][1]])
                else:
                    tool = None
                    unresolved.append(Unresolved(path, line, f"set_tcp({arg})", "a tool centre point computed at run "
                                                                               "time: the motions after it are not "
                                                                               "corrected"))
                continue
            count = 2 if fn == "movec" else 1
            if len(args) < count:
                raise ProgramError(f"{where}: {fn}: expected its target{'s' if count > 1 else ''}")
            for a, b in args[:count]:
                _target(fn, text, code, a, b, path, line, tool, variables, declared, targets, unresolved)
    return Program(NAME, texts, targets, tools, frames, {}, {}, unresolved)


def _pose(v) -> np.ndarray:
    return pose_matrix(np.array(v[:3]), to_matrix("rotvec", [v[3:6]])[0])


def _target(fn, text, code, a, b, path, line, tool, variables, declared, targets, unresolved):
    where = f"{path}:{line}"
    arg = code[a:b].strip()
    frame = BASE
    m = re.fullmatch(r"(?s)(get_inverse_kin|pose_trans)\s*\((.*)\)", arg)
    if m:
        open_at = a + code[a:b].index("(")
        inner, _ = _args(code, open_at, where)
        if m.group(1) == "get_inverse_kin":
            if not inner:
                raise ProgramError(f"{where}: get_inverse_kin: expected a pose")
            a, b = inner[0]
        else:
            ident = code[inner[0][0]:inner[0][1]].strip() if len(inner) == 2 else ""
            if not re.fullmatch(r"[A-Za-z_]\w*", ident):
                unresolved.append(Unresolved(path, line, f"{fn}({arg})", "a pose computed at run time"))
                return
            frame = ident
            a, b = inner[1]
        arg = code[a:b].strip()
    use = Use(path, line, tool, frame, fn)
    lit = _literal(text, code, a, b, where)
    if lit is not None:
        kind, nums, _ = lit
        t = _make(kind, nums, path, line, f"{fn} at line {line}", where)
        t.uses.append(use)
        targets.append(t)
        return
    if arg in variables:
        key = (path, arg)
        if key not in declared:
            kind, nums, vline = variables[arg]
            declared[key] = _make(kind, nums, path, vline, arg, f"{path}:{vline}")
            targets.append(declared[key])
        declared[key].uses.append(use)
        return
    unresolved.append(Unresolved(path, line, f"{fn}({arg})", "a target computed at run time"))


def _make(kind, nums, path, line, name, where) -> Target:
    if kind == "pose":
        if len(nums) != 6:
            raise ProgramError(f"{where}: {name}: a pose p[...] has 6 values, got {len(nums)}")
        keys = ("x", "y", "z", "rx", "ry", "rz")
        fields = dict(zip(keys, nums))
        return Target(path, line, name, "pose", fields, {k: f.value for k, f in fields.items()}, orientation="rotvec")
    fields = {f"q{k + 1}": n for k, n in enumerate(nums)}
    return Target(path, line, name, "joints", fields, {k: f.value for k, f in fields.items()})


def decode(target: Target, model, setup):
    dof = model.dof
    want, windows = np.zeros(3, int), np.full((dof, 2), np.nan)
    if target.kind == "joints":
        if len(target.values) != dof:
            raise ProgramError(f"{target.where}: {target.name}: {len(target.values)} joints for robot {model.name!r} "
                               f"of {dof}")
        return None, np.array([target.values[f"q{k + 1}"] for k in range(dof)]), want, windows
    return _pose([target.values[k] for k in ("x", "y", "z", "rx", "ry", "rz")]), None, want, windows


ORIENTATION = ("rotvec", ("rx", "ry", "rz"))


def encode(target: Target, q, T, orient, model, setup, fmt) -> list:
    if target.kind == "joints":
        new = {f"q{k + 1}": v for k, v in enumerate(q)}
        return edits(target, new, lambda v, num, name: fmt(v, num, "m" if model.joint_types[int(name[1:]) - 1]
                                                             == "prismatic" else "rad"))
    new = dict(zip(("x", "y", "z"), T[:3, 3]))
    new.update(zip(("rx", "ry", "rz"), orient))
    return edits(target, new, lambda v, num, name: fmt(v, num, "m" if name in "xyz" else "rad"))


def header(text: str, lines_: list, newline: str) -> str:
    return "".join(f"# {line}{newline}" for line in lines_) + text
