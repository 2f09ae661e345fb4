"""A program filtered through a calibration: read in its format, every target corrected at once, written back with
only its numbers changed and a header naming the calibration and the command.

The frames a program's targets are written in come from the program (ABB tooldata and wobjdata, KUKA FRAME data,
URScript ``set_tcp`` and feature poses, FANUC's UF and UT numbers) or from the ``Setup`` (``tools`` and ``frames``
given on the command line, which take precedence; ``default_tool``, the tool of motions whose tool the program does
not say). ``base`` is where the controller's base frame (ABB's world frame, UF 0, BASE 0, the UR base) lies in the
model's base frame, ``flange`` where the controller's flange frame lies in the model's tool frame. A target whose
tool or frame is not known, or that two motions use with different ones, is left as written and listed.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..calibration.envelope import Envelope
from ..models.base import Mechanism
from . import fanuc, krl, rapid, urscript
from .configuration import ArmGeometry
from .correct import Requests, correct
from .model import BASE, Program
from .orientation import nearest
from .text import ProgramError, formatted, newline, replaced

DIALECTS = {m.NAME: m for m in (rapid, krl, fanuc, urscript)}
MARK = "tolerance-ros filter: corrected"   # the header's first words (31 characters: one FANUC remark)


def dialect_for(paths, name=None):
    """The format module of the files (``name`` when given, else by their suffix); ProgramError otherwise."""
    if name:
        return DIALECTS[name]
    suffixes = {str(p).lower().rsplit(".", 1)[-1] for p in paths}
    found = [m for m in DIALECTS.values() if all("." + s in m.SUFFIXES for s in suffixes)]
    if len(found) != 1:
        known = ", ".join(f"{m.NAME} ({' '.join(m.SUFFIXES)})" for m in DIALECTS.values())
        raise ProgramError(f"{paths[0]}:1: cannot tell the program's format from its name; give --format "
                           f"(one of: {known})")
    return found[0]


@dataclass
class Setup:
    """How a program's frames meet the model, and the correction's bounds (see the module docstring)."""

    model: Mechanism
    calibrated: Mechanism
    envelope: Envelope = field(default_factory=Envelope)
    base: np.ndarray = field(default_factory=lambda: np.eye(4))
    flange: np.ndarray = field(default_factory=lambda: np.eye(4))
    tools: dict = field(default_factory=dict)
    frames: dict = field(default_factory=dict)
    default_tool: np.ndarray | None = None
    fanuc_j3_absolute: bool = True
    fanuc_coupling: float = 1.0
    geometry: ArmGeometry | None = None

    def __post_init__(self):
        self.tools = {str(k).lower(): np.asarray(v, float) for k, v in self.tools.items()}
        self.frames = {str(k).lower(): np.asarray(v, float) for k, v in self.frames.items()}
        if self.geometry is None and self.model.dof == 6 and all(t != "prismatic" for t in self.model.joint_types):
            self.geometry = ArmGeometry(self.model)
        self.fanuc_coupling = fanuc.coupling(self.model) if self.model.dof >= 3 else 1.0


@dataclass
class Outcome:
    """Per target a row (dict); the corrected texts by path; ``left``: [(target, reason)] of the targets left as
    written; ``unresolved``: the motions no correction reaches."""

    program: Program
    rows: list
    texts: dict
    left: list
    unresolved: list


def already_filtered(text: str) -> bool:
    return MARK in text.lower()


def _lookup(name, given: dict, declared: dict, refused: dict, default, what: str):
    """(4x4 or None, reason or None) of a tool or frame by name."""
    if name is None:
        if default is not None:
            return default, None
        return None, f"its {what} is not known (the motion's {what} is set at run time)"
    if name == BASE:
        return np.eye(4), None
    key = str(name).lower()
    if key in given:
        return given[key], None
    if key in refused:
        return None, refused[key]
    if key in declared:
        return declared[key], None
    option = "--tool" if what == "tool" else "--frame"
    return None, f"its {what} {name} is not declared in these files: give it with {option} {name}=X,Y,Z,RX,RY,RZ"


def resolve(program: Program, setup: Setup):
    """(targets, Requests, reasons, frames): every target of ``program`` decoded, its tool and frame resolved
    (``frames[i]`` the target's frame in the model's base frame), a reason where it cannot be corrected."""
    dialect = DIALECTS[program.dialect]
    model = setup.model
    dof = model.dof
    tools = {str(k).lower(): v for k, v in program.tools.items()}
    frames = {str(k).lower(): v for k, v in program.frames.items()}
    refused_tools = {str(k).lower(): v for k, v in program.refused_tools.items()}
    refused_frames = {str(k).lower(): v for k, v in program.refused_frames.items()}
    targets = [t for t in program.targets if not (t.extra.get("frame") and not t.uses)]
    n = len(targets)
    req = Requests.empty(n, dof)
    why = [None] * n
    frame_of = [np.eye(4)] * n
    cache = {}
    for i, t in enumerate(targets):
        T, q, want, windows = dialect.decode(t, model, setup)
        req.want[i], req.windows[i] = want, windows
        if t.kind == "joints":
            req.q[i] = q
            continue
        req.pose[i] = True
        if setup.geometry is None:
            why[i] = (f"a Cartesian target is corrected on a 6-joint revolute arm (robot {model.name!r} has {dof} "
                      f"joints): give joints")
            continue
        uses = t.uses or ([] if t.tool is None and t.frame is None else [None])
        if not uses:
            why[i] = "no motion in these files moves to it: its tool and frame are not known"
            continue
        found = []
        for u in uses:
            names = (t.tool, t.frame) if u is None else (u.tool, u.frame)
            if names not in cache:
                X, r1 = _lookup(names[0], setup.tools, tools, refused_tools, setup.default_tool, "tool")
                F, r2 = _lookup(names[1], setup.frames, frames, refused_frames, None, "frame")
                cache[names] = (X, F, r1 or r2)
            X, F, reason = cache[names]
            if reason:
                found = reason
                break
            if not found or names != found[0][2:]:
                found.append((X, F, *names))
        if isinstance(found, str):
            why[i] = found
            continue
        first = found[0]
        if len(found) > 1 and any(not (np.allclose(X, first[0], atol=1e-12) and np.allclose(F, first[1], atol=1e-12))
               for X, F, *_ in found):
            pairs = sorted({f"tool {a or 'flange'} in frame {b or 'base'}" for *_, a, b in found})
            why[i] = (f"its motions use it with different tools or frames ({'; '.join(pairs)}): one correction "
                      f"cannot serve them")
            continue
        X, F = first[0], first[1]
        frame_of[i] = setup.base @ F
        req.T[i] = frame_of[i] @ T
        req.tool[i] = setup.flange @ X
    if getattr(dialect, "INHERITS", None):
        _inherit(targets, req, why, setup, dialect.INHERITS)
    return targets, req, why, frame_of


def filter_program(program: Program, setup: Setup, header_lines: list) -> Outcome:
    """Correct every target of ``program`` and write the texts (see the module docstring)."""
    dialect = DIALECTS[program.dialect]
    model = setup.model
    targets, req, why, frame_of = resolve(program, setup)
    ready = np.array([w is None for w in why], bool)
    idx = np.flatnonzero(ready)
    sub = Requests(req.pose[idx], req.T[idx], req.tool[idx], req.q[idx], req.want[idx], req.windows[idx], req.near[idx])
    res = correct(model, setup.calibrated, sub, setup.envelope, setup.geometry)
    edits = {p: [] for p in program.texts}
    rows, left = [], []
    fmt = lambda value, num, unit: formatted(value, num.text, unit)  # noqa: E731
    position = {int(i): k for k, i in enumerate(idx)}
    correction = res.correction
    done = [i for i in range(len(targets)) if i in position and res.ok[position[i]]]
    poses = [i for i in done if targets[i].kind == "pose"]
    T_frame, orient = {}, {}
    if poses:
        kind, keys = dialect.ORIENTATION
        F = np.linalg.inv(np.array([frame_of[i] for i in poses]))
        T = F @ res.T[[position[i] for i in poses]]
        values = nearest(kind, [[targets[i].values[k] for k in keys] for i in poses], T[:, :3, :3])
        T_frame = dict(zip(poses, T))
        orient = dict(zip(poses, values))
    for i, t in enumerate(targets):
        row = {"name": t.name, "file": str(t.path), "line": t.line, "kind": t.kind}
        k = position.get(i)
        if k is None or not res.ok[k]:
            reason = why[i] if k is None else res.reason[k]
            row.update(status="left", reason=reason)
            left.append((t, reason))
            rows.append(row)
            continue
        q = res.q[k]
        e = dialect.encode(t, q, T_frame.get(i), orient.get(i), model, setup, fmt)
        edits[t.path].extend(e)
        row.update(status="corrected" if e else "unchanged", reason=None,
                   joints_nominal=res.q_nominal[k], joints=q, correction=correction[k], shift_m=float(res.shift[k]),
                   changed_fields=len(e))
        if res.signs is not None:
            row["configuration"] = res.signs[k].tolist()
            row["margin"] = res.margin[k].tolist()
        rows.append(row)
    texts = {}
    for path, text in program.texts.items():
        body = replaced(text, edits[path])
        texts[path] = dialect.header(body, header_lines, newline(text))
    return Outcome(program, rows, texts, left, list(program.unresolved))


def _inherit(targets, req, why, setup, how):
    """Cartesian targets without a configuration, in the order of their first motion: with ``how`` 'configuration'
    (KUKA: the status of the motion before) the configuration of the target before them, solved nearest the last joint
    target; with 'nearest' (UR: the solution nearest the joints the motion starts from) solved from the last joint
    target, in whatever configuration that leads to."""
    geometry = setup.geometry
    if geometry is None:
        return
    order = sorted(range(len(targets)), key=lambda i: _first_use(targets[i]))
    joints = [i for i in order if targets[i].kind == "joints" and why[i] is None]
    flags = {}
    if joints:
        signs, _ = geometry.flags(req.q[joints])
        flags = {i: s for i, s in zip(joints, signs)}
    last_flags, last_q = None, None
    for i in order:
        if targets[i].kind == "joints":
            if i in flags:
                last_flags, last_q = flags[i], req.q[i]
            continue
        if np.any(req.want[i] != 0):
            last_flags = req.want[i].copy()
            continue
        if why[i] is not None:
            continue
        if last_flags is None or (how == "nearest" and last_q is None):
            why[i] = ("it gives no configuration and no motion before it in the program does: its solution depends on "
                      "where the robot is (move to joints before it)")
            continue
        if how == "configuration":
            req.want[i] = last_flags
        if last_q is not None:
            req.near[i] = last_q


def _first_use(t):
    if t.uses:
        u = t.uses[0]
        return (str(u.path), u.line)
    return (str(t.path), t.line)


def check_programs(texts: dict):
    """ProgramError for a text a filter already wrote."""
    for path, text in texts.items():
        if already_filtered(text):
            raise ProgramError(f"{path}:1: already corrected by tolerance-ros filter (its header says so): filter the "
                               f"original program (the .orig kept by --in-place), never a corrected one")


def landing(before: Program, after: Program, setup: Setup, truth: Mechanism) -> dict:
    """Where the targets of ``before`` land on the as-built robot ``truth`` (the chain with the model's tool frame)
    when the controller runs ``before`` and when it runs ``after`` (the same program corrected): each Cartesian
    target solved on the nominal robot in the configuration written, each joint target driven as written.
    {"name", "kind", "target", "before_m", "after_m", "before_rad", "after_rad"} per target both resolve (position
    and rotation errors against the pose intended: ``before``'s target, or the nominal robot's pose at its joints)."""
    from ..geometry import rotation_error
    tb, rb, wb, _ = resolve(before, setup)
    ta, ra, wa, _ = resolve(after, setup)
    if [t.kind for t in tb] != [t.kind for t in ta]:     # in the same order (an inline target's line moves)
        raise ValueError("landing: the programs do not hold the same targets")
    keep = np.array([w1 is None and w2 is None for w1, w2 in zip(wb, wa)], bool)
    idx = np.flatnonzero(keep)
    out = {"name": [tb[i].name for i in idx], "kind": [tb[i].kind for i in idx], "target": [tb[i] for i in idx]}
    model = setup.model
    intended = np.where(rb.pose[idx, None, None], rb.T[idx], np.nan)
    jt = idx[~rb.pose[idx]]
    if len(jt):
        intended[~rb.pose[idx]] = model.fk(rb.q[jt]) @ rb.tool[jt]
    for label, r in (("before", rb), ("after", ra)):
        q = np.where(r.pose[idx, None], np.nan, r.q[idx])
        pose = np.flatnonzero(r.pose[idx])
        if len(pose):
            k = idx[pose]
            T_flange = np.einsum("nij,njk->nik", r.T[k], np.linalg.inv(r.tool[k]))
            qs, found, _ = setup.geometry.solve(T_flange, r.want[k], r.windows[k], r.near[k])
            q[pose] = np.where(found[:, None], qs, np.nan)
        got = np.full((len(idx), 4, 4), np.nan)
        fine = np.isfinite(q).all(axis=1)
        got[fine] = truth.fk(q[fine]) @ r.tool[idx[fine]]
        out[f"{label}_m"] = np.linalg.norm(got[:, :3, 3] - intended[:, :3, 3], axis=1)
        rot = np.full(len(idx), np.nan)
        if fine.any():
            rot[fine] = np.linalg.norm(rotation_error(got[fine, :3, :3], intended[fine, :3, :3]), axis=1)
        out[f"{label}_rad"] = rot
    return out
