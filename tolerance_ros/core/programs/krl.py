"""KUKA KRL programs: the ``.dat`` declarations of ``E6POS``, ``POS`` and ``FRAME`` (X, Y, Z mm; A, B, C deg,
``R = Rz(A) Ry(B) Rx(C)``; S and T) and of ``E6AXIS`` and ``AXIS`` (A1-A6 deg, E1-E6), with the ``.src`` motions
that use them (``PTP``, ``LIN``, ``CIRC``, ``SPTP``, ``SLIN``, ``SCIRC``, ``SPL``), inline aggregates included.

The tool and the base of a motion are those in force before it in the ``.src``: ``FDAT_ACT`` (its ``TOOL_NO`` and
``BASE_NO``), ``BAS(#TOOL, n)``, ``BAS(#BASE, n)``, ``$TOOL = TOOL_DATA[n]``, ``$BASE = BASE_DATA[n]``, or a
``FRAME`` the program declares; tool 0 is the flange and base 0 the world frame; an external TCP (``IPO_FRAME
#TCP``, ``$IPO_MODE = #TCP``) is refused. Status S: bit 0 set in the overhead area (wrist centre behind axis 1),
bit 1 set with the wrist centre in front of the lower arm, bit 2 set for A5 < 0; turn T: bit i set when axis i+1 is
negative. A position without S and T takes the configuration of the motion before it. KRL names are
case-insensitive; a program is its ``.src`` and ``.dat`` of the same name, read and written together.
"""
from __future__ import annotations

import re
from glob import escape as glob_escape
from pathlib import Path

import numpy as np

from .configuration import keeps
from .model import BASE, Program, Target, Unresolved, Use, edits, pose_matrix
from .orientation import to_matrix
from .text import Lines, ProgramError, mask, matching, number_at, read_text, split_top

NAME = "krl"
SUFFIXES = (".src", ".dat")
COMMENT = ";"
INHERITS = "configuration"   # a pose without configuration: see filtering._inherit

POSE_KEYS = ("X", "Y", "Z", "A", "B", "C")
AXIS_KEYS = ("A1", "A2", "A3", "A4", "A5", "A6")
EXT_KEYS = ("E1", "E2", "E3", "E4", "E5", "E6")
POSE_TYPES = ("E6POS", "POS", "FRAME")
AXIS_TYPES = ("E6AXIS", "AXIS")

_DECL = re.compile(r"(?im)^[ \t]*(?:DECL[ \t]+)?(?:GLOBAL[ \t]+)?(E6POS|POS|FRAME|E6AXIS|AXIS|FDAT)[ \t]+(\w+)"
                   r"[ \t]*(\[[^\]\r\n]*\])?[ \t]*(=)?")
_ELEMENT = re.compile(r"(?im)^[ \t]*(\w+)[ \t]*\[[ \t]*(\d+)[ \t]*\][ \t]*=[ \t]*\{")
_MOTION = re.compile(r"(?i)^[ \t]*(PTP|LIN|CIRC|SPTP|SLIN|SCIRC|SPL|PTP_REL|LIN_REL|CIRC_REL|SPTP_REL|SLIN_REL|"
                     r"SCIRC_REL)\b(.*)$")


def _aggregate(text, code, start, where) -> tuple:
    """({KEY: Number or raw text}, end) of ``{KEY value, ...}`` at ``start``."""
    end = matching(code, start, "{", "}", where)
    out = {}
    for a, b in split_top(code, start + 1, end - 1):
        chunk = code[a:b]
        m = re.match(r"\s*([A-Za-z_]\w*)(\[\])?\s+(.*?)\s*$", chunk, re.S)
        if not chunk.strip():
            continue
        if m is None:
            raise ProgramError(f"{where}: {chunk.strip()!r} is not a component 'NAME value'")
        key, value = m.group(1).upper(), m.group(3)
        vstart = a + m.start(3)
        if re.fullmatch(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?", value):
            out[key] = number_at(text, vstart, vstart + len(value), where)
        elif re.fullmatch(r"'B[01]+'", value, re.I):
            out[key] = ("bits", vstart, vstart + len(value), value)
        else:
            out[key] = text[vstart:vstart + len(value)]
    return out, end


def _target(kind, agg, path, line, name):
    """A Target of a position aggregate, or (None, why) when it is not a whole position."""
    keys = POSE_KEYS if kind in POSE_TYPES else AXIS_KEYS
    missing = [k for k in keys if not hasattr(agg.get(k), "value")]
    if missing:
        return None, f"{name} gives no {', '.join(missing)} (a partial position is completed at run time)"
    fields = {k: agg[k] for k in keys}
    fields.update({k: agg[k] for k in EXT_KEYS if hasattr(agg.get(k), "value")})
    config = {}
    for k in ("S", "T"):
        v = agg.get(k)
        if v is None:
            continue
        if isinstance(v, tuple):
            config[k] = (int(v[3][2:-1], 2), ("bits", v[1], v[2], v[3]))
        elif hasattr(v, "value") and float(v.value).is_integer() and v.value >= 0:
            config[k] = (int(v.value), ("int", v.start, v.end, v.text))
        else:
            raise ProgramError(f"{path}:{line}: {name}: {k} must be a whole number or 'B...' bits, got {v!r}")
    t = Target(path, line, name, "pose" if kind in POSE_TYPES else "joints", fields,
               {k: f.value for k, f in fields.items()}, config, orientation="zyx")
    return t, None


def _pair(paths) -> list:
    """The .src and .dat files of the programs named (each with its partner of the same name where it exists)."""
    out = []
    for p in map(Path, paths):
        partners = sorted(q for q in p.parent.glob(glob_escape(p.stem) + ".*")
                          if q.suffix.lower() in SUFFIXES and q.suffix.lower() != p.suffix.lower())
        for q in [p] + partners:
            if q not in out:
                out.append(q)
    return out


def read(paths) -> Program:
    """The targets and motions of KRL programs (``.src`` with its ``.dat``)."""
    paths = _pair(paths)
    texts, decl, fdat, frames, unresolved, targets = {}, {}, {}, {}, [], []
    sources = []
    for path in paths:
        text = read_text(path)
        texts[path] = text
        code = mask(text, COMMENT, '"')
        lines = Lines(text)
        arrays = {}
        for m in _DECL.finditer(code):
            kind, name, dims, eq = m.group(1).upper(), m.group(2), m.group(3), m.group(4)
            line = lines.line(m.start())
            if dims:
                arrays[name.upper()] = kind
                continue
            if not eq:
                if kind in POSE_TYPES + AXIS_TYPES:
                    decl[name.upper()] = ("runtime", kind)
                continue
            start = code.find("{", m.end())
            between = code[m.end():start] if start >= 0 else ""
            if start < 0 or between.strip():
                decl[name.upper()] = ("runtime", kind)
                continue
            agg, _ = _aggregate(text, code, start, f"{path}:{line}")
            _declare(kind, name, agg, path, line, decl, fdat, frames, targets)
        for m in _ELEMENT.finditer(code):
            base, index = m.group(1).upper(), m.group(2)
            if base not in arrays:
                continue
            line = lines.line(m.start())
            agg, _ = _aggregate(text, code, m.end() - 1, f"{path}:{line}")
            _declare(arrays[base], f"{m.group(1)}[{index}]", agg, path, line, decl, fdat, frames, targets)
        if path.suffix.lower() == ".src":
            sources.append((path, text, code, lines))
    for path, text, code, lines in sources:
        _motions(path, text, code, lines, decl, fdat, frames, targets, unresolved)
    return Program(NAME, texts, targets, {k: v for k, v in frames.items()}, dict(frames), {}, {}, unresolved)


def _declare(kind, name, agg, path, line, decl, fdat, frames, targets):
    key = name.upper()
    if kind == "FDAT":
        fdat[key] = agg
        return
    t, why = _target(kind, agg, path, line, name)
    if t is None:
        decl[key] = ("partial", why)
        return
    if kind == "FRAME":
        frames[key] = _pose(t)
        t.extra["frame"] = True          # a frame the program may use as a tool or a base, or move to
    targets.append(t)
    decl[key] = ("target", t)


def _pose(t: Target) -> np.ndarray:
    p = np.array([t.values[k] for k in ("X", "Y", "Z")]) * 1e-3
    return pose_matrix(p, to_matrix("zyx", [[t.values[k] for k in ("A", "B", "C")]])[0])


def _number_key(value: str):
    m = re.fullmatch(r"\s*(\d+)\s*", value or "")
    return None if m is None else (BASE if int(m.group(1)) == 0 else m.group(1))


def _motions(path, text, code, lines, decl, fdat, frames, targets, unresolved):
    tool = base = None
    external = False
    for i, start in enumerate(lines.starts):
        end = lines.starts[i + 1] if i + 1 < len(lines.starts) else len(code)
        line_code = code[start:end].rstrip("\r\n")
        line = i + 1
        for pat, what in ((r"\$TOOL\s*=\s*TOOL_DATA\s*\[\s*(\d+)\s*\]", "tool"),
                          (r"\$BASE\s*=\s*BASE_DATA\s*\[\s*(\d+)\s*\]", "base"),
                          (r"\bBAS\s*\(\s*#TOOL\s*,\s*(\d+)", "tool"), (r"\bBAS\s*\(\s*#BASE\s*,\s*(\d+)", "base")):
            m = re.search(pat, line_code, re.I)
            if m:
                if what == "tool":
                    tool = _number_key(m.group(1))
                else:
                    base = _number_key(m.group(1))
        for pat, what in ((r"\$TOOL\s*=\s*(\$NULLFRAME|[A-Za-z_]\w*)\s*$", "tool"),
                          (r"\$BASE\s*=\s*(\$NULLFRAME|[A-Za-z_]\w*)\s*$", "base")):
            m = re.search(pat, line_code, re.I)
            if m and not re.search(r"_DATA\s*\[", line_code, re.I):
                value = BASE if m.group(1).upper() == "$NULLFRAME" else m.group(1).upper()
                if what == "tool":
                    tool = value
                else:
                    base = value
        m = re.search(r"\$IPO_MODE\s*=\s*#(\w+)", line_code, re.I)
        if m:
            external = m.group(1).upper() == "TCP"
        m = re.search(r"\bFDAT_ACT\s*=\s*(\w+)", line_code, re.I)
        if m:
            f = fdat.get(m.group(1).upper())
            if f is None:
                tool = base = None
            else:
                tool = _number_key(getattr(f.get("TOOL_NO"), "text", None))
                base = _number_key(getattr(f.get("BASE_NO"), "text", None))
                ipo = str(f.get("IPO_FRAME", "")).strip().upper()
                external = ipo == "#TCP"
        m = _MOTION.match(line_code)
        if not m:
            continue
        instr = m.group(1).upper()
        args_at = start + m.start(2)
        args = line_code[m.start(2):]
        if instr.endswith("_REL"):
            unresolved.append(Unresolved(path, line, f"{instr}{args.rstrip()}", "a relative motion: its target is "
                                                                               "computed at run time"))
            continue
        cut = re.search(r"(?i)\s(C_PTP|C_DIS|C_VEL|C_ORI|C_SPL|WITH)\b", args)
        args_end = args_at + (cut.start() if cut else len(args.rstrip()))
        parts = split_top(code, args_at, args_end)
        circular = instr in ("CIRC", "SCIRC")
        if circular:
            parts = [p for p in parts if not re.match(r"(?i)\s*CA\b", code[p[0]:p[1]])]
        want = parts[:2] if circular else parts[:1]
        if len(want) < (2 if circular else 1) or not all(code[a:b].strip() for a, b in want):
            raise ProgramError(f"{path}:{line}: {instr}: expected its target{'s' if circular else ''}")
        use = Use(path, line, tool, base, instr)
        if external:
            use = Use(path, line, None, None, instr)
        for a, b in want:
            arg = code[a:b].strip()
            if arg.startswith("{"):
                off = a + code[a:b].index("{")
                agg, _ = _aggregate(text, code, off, f"{path}:{line}")
                kind = "E6AXIS" if any(k in agg for k in AXIS_KEYS) else "E6POS"
                t, why = _target(kind, agg, path, line, f"{instr} at line {line}")
                if t is None:
                    unresolved.append(Unresolved(path, line, f"{instr} {arg}", why))
                    continue
                t.uses.append(use)
                targets.append(t)
                continue
            found = decl.get(re.sub(r"\s+", "", arg).upper())
            if found is None or found[0] != "target":
                why = (found[1] if found and found[0] == "partial" else "computed at run time" if found
                       else f"{arg} is not declared in these files")
                unresolved.append(Unresolved(path, line, f"{instr} {arg}", why))
                continue
            found[1].uses.append(use)
            if external:
                unresolved.append(Unresolved(path, line, f"{instr} {arg}", "an external TCP (IPO_FRAME #TCP): the "
                                                                           "robot holds the work piece"))


def decode(target: Target, model, setup):
    """(pose 4x4 in its frame or None, joints (dof,) or None, want (3,), windows (dof, 2))."""
    dof = model.dof
    windows = np.full((dof, 2), np.nan)
    want = np.zeros(3, int)
    if target.kind == "joints":
        keys = list(AXIS_KEYS) + list(EXT_KEYS)
        if dof > 12:
            raise ProgramError(f"{target.where}: an E6AXIS holds 12 axes; robot {model.name!r} has {dof}")
        missing = [k for k in keys[:dof] if k not in target.values]
        if missing:
            raise ProgramError(f"{target.where}: {target.name}: robot {model.name!r} has {dof} joints; no "
                               f"{', '.join(missing)}")
        q = np.array([target.values[k] * (1e-3 if t == "prismatic" else np.pi / 180)
                      for k, t in zip(keys[:dof], model.joint_types)])
        return None, q, want, windows
    T = _pose(target)
    if "S" in target.config:
        s = target.config["S"][0]
        want[:] = [-1 if s & 1 else 1, 1 if s & 2 else -1, -1 if s & 4 else 1]
    if "T" in target.config:
        t = target.config["T"][0]
        for j in range(min(6, dof)):
            windows[j] = [-2 * np.pi, 0.0] if (t >> j) & 1 else [0.0, 2 * np.pi]
    return T, None, want, windows


ORIENTATION = ("zyx", ("A", "B", "C"))


def encode(target: Target, q, T, orient, model, setup, fmt) -> list:
    if target.kind == "joints":
        keys = list(AXIS_KEYS) + list(EXT_KEYS)
        new = {k: (v * 1e3 if t == "prismatic" else np.degrees(v)) for k, v, t in zip(keys, q, model.joint_types)}
        units = {k: ("mm" if t == "prismatic" else "deg") for k, t in zip(keys, model.joint_types)}
        return edits(target, new, lambda v, num, name: fmt(v, num, units[name]))
    new = dict(zip(("X", "Y", "Z"), T[:3, 3] * 1e3))
    new.update(zip(("A", "B", "C"), orient))
    out = edits(target, new, lambda v, num, name: fmt(v, num, "mm" if name in "XYZ" else "deg"))
    if "T" in target.config:
        old, (style, start, end, text) = target.config["T"]
        bits = old & ~0b111111
        for j in range(6):
            was = (old >> j) & 1
            keep = keeps(q[j], -2 * np.pi, 0.0) if was else keeps(q[j], 0.0, 2 * np.pi)
            bits |= (1 << j) if (was if keep else q[j] < 0) else 0
        if bits != old:
            if style == "bits":
                width = len(text) - 3
                out.append((start, end, f"'B{bits:0{width}b}'"))
            else:
                out.append((start, end, str(bits)))
    return out


def header(text: str, lines_: list, newline: str) -> str:
    """The text with ``lines_`` as comments after its DEF or DEFDAT line (at its start when it has none)."""
    code = mask(text, COMMENT, '"')
    m = re.search(r"(?im)^[ \t]*(?:GLOBAL[ \t]+)?(?:DEFDAT|DEF|DEFFCT)\b[^\r\n]*(\r\n|\r|\n|$)", code)
    at = m.end() if m else 0
    block = "".join(f"; {line}{newline}" for line in lines_)
    if m and not m.group(1):
        block = newline + block
    return text[:at] + block + text[at:]
