"""The measurements every reader returns (SI) and the one error type of all readers."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


class MeasurementError(ValueError):
    """A measurement file or message that cannot be read; the message gives its position."""


@dataclass
class Measurements:
    """Measured tool poses (SI) with their stamps, optional joints and test-pose labels."""

    stamps: np.ndarray
    T: np.ndarray
    joints: np.ndarray | None = None
    joint_names: tuple = ()
    pose: np.ndarray | None = None
    cycle: np.ndarray | None = None
    has_orientation: bool = True
    source: str = ""
    skipped: list = field(default_factory=list)

    def __len__(self):
        return len(self.stamps)


def concat(parts) -> Measurements:
    """One Measurements from several chunks of the same source."""
    parts = list(parts)
    first = parts[0]
    return Measurements(np.concatenate([p.stamps for p in parts]), np.concatenate([p.T for p in parts]),
                        None if first.joints is None else np.concatenate([p.joints for p in parts]),
                        first.joint_names,
                        np.concatenate([p.pose for p in parts]) if first.pose is not None else None,
                        np.concatenate([p.cycle for p in parts]) if first.cycle is not None else None,
                        first.has_orientation, first.source, [s for p in parts for s in p.skipped])

