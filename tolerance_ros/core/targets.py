"""Targets on the tool: what a tracker actually measures, each at its own offset from the model's tool frame.

A laser tracker measures reflectors (points) and motion capture measures markers (points) or rigid
bodies (frames); each sits at an offset from the model's tool (tip) frame that is rarely known to better
than millimetres. ``Targets`` holds, for each named target, its frame ``X`` in the tool frame (4x4, m):
the target's point is ``T_tool @ X[:3, 3]`` and, for a measured frame, its orientation ``T_tool @ X``.
Every error, bound and identification of a measurement is taken at its target, never at the flange.

``shift_jacobian`` moves a parameter-error Jacobian from the tool frame to a target point: a rigid
offset ``r = R_tool x`` turns the position error into ``dp + dphi x r``, so ``J_p' = J_p - [r]x J_o``
(orientation rows unchanged). SI throughout.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .models.base import ErrorJacobian, Mechanism, WrappedMechanism

MAX_OFFSET = 5.0  # m: a target farther from the tool frame is refused as a unit mistake


@dataclass
class Targets:
    """Named targets and their frames in the tool frame.

    names : (K,) target names ('' for the one unnamed target).  X : (K, 4, 4) target frames in the
    tool frame (m); a point target's rotation is the identity.  frames : True when the targets are
    measured frames (the measurements carry orientation), False for points.
    """

    names: tuple
    X: np.ndarray
    frames: bool = False

    def __post_init__(self):
        self.names = tuple(str(n) for n in self.names)
        self.X = np.asarray(self.X, float).reshape(len(self.names), 4, 4)
        if len(set(self.names)) != len(self.names):
            raise ValueError(f"targets: names must differ, got {list(self.names)}")

    @classmethod
    def at_tool(cls, names=("",), frames=False) -> "Targets":
        """Targets at the tool frame itself (zero offsets)."""
        return cls(tuple(names), np.tile(np.eye(4), (len(tuple(names)), 1, 1)), frames)

    @classmethod
    def from_offsets(cls, names, offsets, frames=False) -> "Targets":
        """Point targets at ``offsets`` (K, 3) m in the tool frame."""
        off = np.asarray(offsets, float).reshape(-1, 3)
        X = np.tile(np.eye(4), (len(off), 1, 1))
        X[:, :3, 3] = off
        return cls(tuple(names), X, frames)

    def __len__(self):
        return len(self.names)

    @property
    def offsets(self) -> np.ndarray:
        """(K, 3) target points in the tool frame, m."""
        return self.X[:, :3, 3]

    def index(self, labels) -> np.ndarray:
        """(n,) index of each row's target name (None: every row measures the one target)."""
        if labels is None:
            if len(self) != 1:
                raise ValueError(f"targets: the measurements name no target, but there are {len(self)} "
                                 f"({', '.join(self.names)})")
            return np.zeros(0, int)
        lookup = {n: k for k, n in enumerate(self.names)}
        labels = [str(t) for t in labels]
        missing = sorted(set(labels) - set(lookup))
        if missing:
            raise ValueError(f"targets: {missing} not among the known targets {list(self.names)}")
        return np.array([lookup[t] for t in labels], int)

    def rows(self, index, n) -> np.ndarray:
        """(n,) target index of each of ``n`` rows (``index`` from ``index``; empty: all the one target)."""
        index = np.asarray(index, int)
        return np.zeros(n, int) if index.size == 0 else index

    def poses(self, T_tool, index) -> np.ndarray:
        """(n, 4, 4) target frames in the base frame from tool frames (n, 4, 4) and each row's target."""
        T_tool = np.asarray(T_tool, float)
        return T_tool @ self.X[self.rows(index, len(T_tool))]

    def arms(self, T_tool, index) -> np.ndarray:
        """(n, 3) base-frame vector from the tool origin to each row's target point, m."""
        T_tool = np.asarray(T_tool, float)
        off = self.offsets[self.rows(index, len(T_tool))]
        return np.einsum("nij,nj->ni", T_tool[:, :3, :3], off)

    def to_dict(self) -> dict:
        """Plain dict, SI: {frames, targets: [{name, xyz (m), rotation (3x3)}]}."""
        return {"frames": bool(self.frames),
                "targets": [{"name": n, "xyz_m": X[:3, 3].tolist(), "rotation": X[:3, :3].tolist()}
                            for n, X in zip(self.names, self.X)]}


def shift_jacobian(J, arms) -> np.ndarray:
    """(n, 6, p) parameter-error Jacobian at target points ``arms`` (n, 3) m from the tool origin (base
    frame): position rows ``J_p - [r]x J_o``, orientation rows unchanged. Returns a new array."""
    J = np.asarray(J, float)
    r = np.asarray(arms, float)
    out = J.copy()
    Jo = J[:, 3:, :]
    # r x w for every column w of J_o
    out[:, :3, :] -= np.stack([r[:, 1, None] * Jo[:, 2] - r[:, 2, None] * Jo[:, 1],
                               r[:, 2, None] * Jo[:, 0] - r[:, 0, None] * Jo[:, 2],
                               r[:, 0, None] * Jo[:, 1] - r[:, 1, None] * Jo[:, 0]], axis=1)
    return out


def check_offsets(targets: Targets, what="registration"):
    """ValueError when a target lies implausibly far from the tool frame (units mistaken)."""
    far = np.linalg.norm(targets.offsets, axis=1)
    k = int(np.argmax(far)) if len(far) else 0
    if len(far) and far[k] > MAX_OFFSET:
        raise ValueError(f"{what}: target {targets.names[k] or '(unnamed)'} would sit {far[k]:.3g} m from the tool "
                         f"frame (more than {MAX_OFFSET:g} m): are the measurement units right?")


def at_point(model: Mechanism, offset=None) -> Mechanism:
    """``model`` with its tool point moved to ``offset`` (3,) m of the tool frame (an ``AtTarget``): its poses'
    origins are that point and its Jacobian's position rows that point's; ``model`` itself for None."""
    if offset is None:
        return model
    X = np.eye(4)
    X[:3, 3] = np.asarray(offset, float)
    return AtTarget(model, X)


class AtTarget(WrappedMechanism):
    """A mechanism whose tool frame is moved to a target frame ``X`` (4x4, m, in the tool frame): poses
    ``T @ X`` and the Jacobian at the target point (``shift_jacobian``); the rest is the inner model's.
    ``inner`` is the model, ``target`` the target's name."""

    def __init__(self, inner: Mechanism, X, target=""):
        super().__init__(inner)
        self.X = np.asarray(X, float).reshape(4, 4)
        self.target = str(target)

    def fk_and_jacobian(self, q, dx=None, jacobian: bool = True):
        T, EJ = self.inner.fk_and_jacobian(q, dx, jacobian)
        T_t = T @ self.X
        if not jacobian:
            return T_t, None
        arms = np.einsum("nij,j->ni", T[:, :3, :3], self.X[:3, 3])
        return T_t, ErrorJacobian(shift_jacobian(EJ.J, arms), EJ.names, EJ.units)

    def with_joint_limits(self, limits) -> "AtTarget":
        return AtTarget(self.inner.with_joint_limits(limits), self.X, self.target)
