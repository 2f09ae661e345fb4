"""Simulated measurements: an as-built robot inside a tolerance budget, seen by a tracker.

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
