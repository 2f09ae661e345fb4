"""The measurements every reader returns (SI) and the one error type of all readers."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


class MeasurementError(ValueError):
    """A measurement file or message that cannot be read; the message gives its position."""


@dataclass
class Measurements:
    """Measured tool poses or points (SI) with their stamps, optional joints, test-pose labels and targets.

    ``T`` (n, 4, 4): the measured pose in the tracker frame (m); without orientation (``has_orientation``
    False) only its position is measured and its rotation is the identity, never read. ``target`` (n,)
    names the reflector or marker each row measured (None: one target, unnamed); rows of one pose visit
    share its stamp, joints and labels. ``line`` (n,): where each row came from in its file (the line of a
    CSV row or of a campaign log's measurement; None where the reader has no lines). ``load`` (n, 3) or (n, 6): the force
    (N, base frame) applied at the tool when the row was measured, and the torque (N m) where recorded (None: no
    load recorded; ISO 9283 static compliance).
    """

    stamps: np.ndarray
    T: np.ndarray
    joints: np.ndarray | None = None
    joint_names: tuple = ()
    pose: np.ndarray | None = None
    cycle: np.ndarray | None = None
    has_orientation: bool = True
    source: str = ""
    skipped: list = field(default_factory=list)
    target: np.ndarray | None = None
    line: np.ndarray | None = None
    load: np.ndarray | None = None

    def __len__(self):
        return len(self.stamps)

    @property
    def loaded(self) -> np.ndarray:
        """(n,) bool: the rows measured under a load at the tool (all False without load columns)."""
        if self.load is None:
            return np.zeros(len(self), bool)
        return np.any(self.load != 0, axis=1)

    @property
    def target_names(self) -> tuple:
        """The targets in order of first appearance (``("",)`` for one unnamed target)."""
        if self.target is None:
            return ("",)
        return tuple(dict.fromkeys(str(t) for t in self.target))

    def where(self, i) -> str:
        """Where row ``i`` comes from, in words: 'line 12' of its file, or 'row 12' (0-based) without lines."""
        return f"line {int(self.line[i])}" if self.line is not None else f"row {int(i)}"

    def target_index(self, names=None) -> np.ndarray:
        """(n,) index of each row's target in ``names`` (default ``target_names``)."""
        names = self.target_names if names is None else tuple(names)
        if self.target is None:
            return np.zeros(len(self), int)
        lookup = {n: k for k, n in enumerate(names)}
        missing = sorted({str(t) for t in self.target} - set(lookup))
        if missing:
            raise MeasurementError(f"{self.source}: target(s) {missing} are not among {list(names)}")
        return np.array([lookup[str(t)] for t in self.target], int)

    def select(self, rows) -> "Measurements":
        """The measurements of ``rows`` (a boolean mask or indices), same source."""
        rows = np.asarray(rows)
        pick = (lambda a: None if a is None else a[rows])
        return Measurements(self.stamps[rows], self.T[rows], pick(self.joints), self.joint_names, pick(self.pose),
                            pick(self.cycle), self.has_orientation, self.source, list(self.skipped),
                            pick(self.target), pick(self.line), pick(self.load))


def concat(parts) -> Measurements:
    """One Measurements from several chunks of the same source."""
    parts = list(parts)
    first = parts[0]
    return Measurements(np.concatenate([p.stamps for p in parts]), np.concatenate([p.T for p in parts]),
                        None if first.joints is None else np.concatenate([p.joints for p in parts]),
                        first.joint_names,
                        np.concatenate([p.pose for p in parts]) if first.pose is not None else None,
                        np.concatenate([p.cycle for p in parts]) if first.cycle is not None else None,
                        first.has_orientation, first.source, [s for p in parts for s in p.skipped],
                        np.concatenate([p.target for p in parts]) if first.target is not None else None,
                        np.concatenate([p.line for p in parts]) if first.line is not None else None,
                        np.concatenate([p.load for p in parts]) if first.load is not None else None)

