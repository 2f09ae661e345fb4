"""A simulated measurement source: an as-built robot inside a tolerance budget, seen by a tracker.

The as-built robot has parameter errors drawn within the budget (seeded); the tracker measures the
tool pose in its own frame (``T_tracker_base`` maps base-frame poses into the tracker frame) with
Gaussian noise on position (m) and orientation (rad, a small rotation about a random axis).
"""
from __future__ import annotations

import numpy as np

from ..analysis import sample_errors
from ..geometry import exp_so3
from ..models.base import Mechanism


def as_built_errors(delta, seed=0, distribution="uniform") -> np.ndarray:
    """(p,) parameter errors of one as-built robot within ``+-delta`` (SI)."""
    return sample_errors(np.asarray(delta, dtype=float), 1, distribution, seed)[0]


def _small_rotations(rng, n, sigma):
    return exp_so3(rng.standard_normal((n, 3)) * sigma)


def measure(model: Mechanism, q, dx=None, noise_position=0.0, noise_orientation=0.0, T_tracker_base=None,
            seed=0) -> np.ndarray:
    """(n, 4, 4) tracker readings of the as-built tool at joints q (n, dof)."""
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    T = model.fk(q, dx)
    n = len(T)
    if noise_orientation > 0:
        T[:, :3, :3] = _small_rotations(rng, n, noise_orientation) @ T[:, :3, :3]
    if noise_position > 0:
        T[:, :3, 3] += rng.standard_normal((n, 3)) * noise_position
    if T_tracker_base is not None:
        T = np.asarray(T_tracker_base, dtype=float) @ T
    return T


class SimulatedTracker:
    """A stand-in laser tracker: an as-built robot drawn within ``delta`` (seeded), measurement noise
    and a base-frame offset. ``measure_at(q)`` gives the reading (4x4, tracker frame) at joints q."""

    def __init__(self, model: Mechanism, delta, seed=0, noise_position=1e-5, noise_orientation=1e-5,
                 T_tracker_base=None, distribution="uniform"):
        self.model = model
        self.dx = as_built_errors(delta, seed, distribution)
        self.noise_position, self.noise_orientation = noise_position, noise_orientation
        self.T_tracker_base = None if T_tracker_base is None else np.asarray(T_tracker_base, float)
        self.rng = np.random.default_rng(seed + 1)

    def measure_at(self, q) -> np.ndarray:
        return measure(self.model, np.atleast_2d(q), self.dx, self.noise_position, self.noise_orientation,
                       self.T_tracker_base, self.rng)[0]

    def on_joint_state(self, names, positions) -> np.ndarray:
        """Reading for a joint state (names in any order); raises ValueError if joints are missing."""
        names = list(names)
        missing = [n for n in self.model.joint_names if n not in names]
        if missing:
            raise ValueError(f"joint state lacks {missing}")
        q = np.asarray(positions, float)[[names.index(n) for n in self.model.joint_names]]
        return self.measure_at(q)
