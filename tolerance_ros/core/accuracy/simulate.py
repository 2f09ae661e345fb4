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


def measure_targets(model: Mechanism, q, dx=None, targets=None, noise_position=0.0, noise_orientation=0.0,
                    T_tracker_base=None, seed=0, stamps=None, labels=None, points=True, deflection=None):
    """Measurements of every target of ``targets`` (``targets.Targets``; default: the tool frame) at joints
    q (n, dof) by a tracker: one row per visit and target (a visit's rows share its stamp), as
    ``io.Measurements`` in the tracker frame. ``points``: the tracker reads points (no orientation);
    otherwise frames. ``deflection`` (n, dof) is added to the joints the as-built robot reaches (its
    elastic deflection), not to the joints it reports."""
    from .io import Measurements
    from .targets import Targets
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    q = np.asarray(q, float)
    targets = targets if targets is not None else Targets.at_tool(frames=not points)
    K, n = len(targets), len(q)
    T_tool = model.fk(q if deflection is None else q + deflection, dx)
    idx = np.tile(np.arange(K), n)
    rows = np.repeat(np.arange(n), K)
    T = targets.poses(T_tool[rows], idx)
    if noise_orientation > 0 and not points:
        T[:, :3, :3] = _small_rotations(rng, len(T), noise_orientation) @ T[:, :3, :3]
    if noise_position > 0:
        T[:, :3, 3] += rng.standard_normal((len(T), 3)) * noise_position
    if points:
        T[:, :3, :3] = np.eye(3)
    if T_tracker_base is not None:
        A = np.asarray(T_tracker_base, dtype=float)
        T[:, :3, 3] = T[:, :3, 3] @ A[:3, :3].T + A[:3, 3]
        if not points:
            T[:, :3, :3] = A[:3, :3] @ T[:, :3, :3]
    stamps = np.arange(n, dtype=float) if stamps is None else np.asarray(stamps, float)
    names = np.array(targets.names, dtype=object)
    return Measurements(stamps[rows], T, q[rows], model.joint_names,
                        None if labels is None else np.asarray(labels, dtype=object)[rows], np.full(len(T), -1),
                        not points, "simulated", [], names[idx] if K > 1 or targets.names[0] else None)
