"""What every program format shares once read: its targets with the places of their numbers, the tools and frames
it declares, and the motions it makes that no filter can correct (a target computed at run time).

A ``Target`` is one position the program stores: a Cartesian pose (in a frame, for a tool, with a configuration) or
joints. Its ``fields`` are the numbers written in the file (their spans), in the file's units; its ``uses`` the
motions that move to it, each with the tool and the frame in force there. The format's module reads its values
(``pose``: position m and rotation in the target's frame; ``joints``: the model's joints, SI) and, once corrected,
writes the new values into the same fields.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .text import Number

BASE = ""          # the name of the base frame (wobj0, UF 0, BASE 0, the UR base) and of the flange (tool0, UT 0)


@dataclass
class Use:
    """A motion that moves to a target: its file and line, the tool and the frame in force (None: not known)."""

    path: Path
    line: int
    tool: str | None
    frame: str | None
    what: str = ""


@dataclass
class Target:
    """A stored position of the program (see the module docstring). ``kind`` 'pose' or 'joints'; ``name`` as the
    program calls it ('p10', 'P[3]', 'XP1', or the motion's line for an inline one); ``frame`` and ``tool`` are
    the target's own where the format stores them with it (FANUC), else those of its uses; ``config`` the
    format's configuration data as read; ``values`` the numbers read, by field name, in the file's units."""

    path: Path
    line: int
    name: str
    kind: str
    fields: dict
    values: dict
    config: dict = field(default_factory=dict)
    frame: str | None = None
    tool: str | None = None
    uses: list = field(default_factory=list)
    orientation: str = ""
    extra: dict = field(default_factory=dict)

    @property
    def where(self) -> str:
        return f"{self.path}:{self.line}"


@dataclass
class Unresolved:
    """A motion the filter leaves as written: where, what, why."""

    path: Path
    line: int
    what: str
    why: str


@dataclass
class Program:
    """A program read: its files' texts (by path), targets, the tools (4x4 in the flange frame, m) and frames (4x4
    in the base frame, m) it declares, the reasons a declared tool or frame cannot serve (a tool the robot does not
    hold, a work object that moves), and the motions no filter corrects."""

    dialect: str
    texts: dict
    targets: list
    tools: dict = field(default_factory=dict)
    frames: dict = field(default_factory=dict)
    refused_tools: dict = field(default_factory=dict)
    refused_frames: dict = field(default_factory=dict)
    unresolved: list = field(default_factory=list)
    notes: list = field(default_factory=list)


def pose_matrix(position, R) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = position
    return T


def edits(target: Target, new: dict, fmt) -> list:
    """(start, end, text) edits writing ``new`` {field: value} into the target's fields with ``fmt(value, Number,
    field)`` (a value whose text does not change gives no edit)."""
    out = []
    for name, value in new.items():
        num: Number = target.fields[name]
        text = fmt(value, num, name)
        if text != num.text:
            out.append((num.start, num.end, text))
    return out
