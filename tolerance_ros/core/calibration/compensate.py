"""Compensated joints: the joint values that put the calibrated robot's tool at each target, batched.

Targets are tool poses in the nominal base frame (4x4, m) or nominal joint configurations (the pose the
nominal model reaches there). Each target is solved by damped least squares (Levenberg-Marquardt:
``dq = J^T (J J^T + lambda^2 I)^-1 e``, lambda adapted per target, the step kept only when the error
falls; ``models.ik``) on the calibrated model, starting from the nominal solution: the given joints, or for a
pose target the nominal model's own solution from a seed (or from the best of several seeded starts).
On a redundant arm the damped step is the smallest joint change, so the compensated joints stay near
the nominal ones.

Flags per target: ``reached`` (residual within the tolerances), ``near_singularity`` (smallest over
largest singular value of the Jacobian, orientation rows times ``LENGTH`` so both are metres, below
``singular_ratio``), ``out_of_limits`` (a joint outside its limits after full turns are taken out).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..models.base import PRISMATIC, Mechanism, ModelError
from ..models.ik import LENGTH, into_limits, joint_jacobian, nominal_solution, solve_jacobians


@dataclass
class Compensation:
    """Solutions of a batch of targets (SI): joints (n, dof), the nominal solution they started from,
    residual position (m) and orientation (rad) errors, flags and iterations per target."""

    joint_names: tuple
    q: np.ndarray
    q_nominal: np.ndarray
    residual_position: np.ndarray
    residual_orientation: np.ndarray
    reached: np.ndarray
    near_singularity: np.ndarray
    out_of_limits: np.ndarray
    iterations: np.ndarray
    match: str = "pose"
    revolute: np.ndarray | None = None
    jacobians: tuple | None = None   # (calibrated at q, nominal at q_nominal) joint Jacobians (n, 6, dof)

    @property
    def correction(self) -> np.ndarray:
        """(n, dof) compensated minus nominal joints; revolute differences wrapped to (-pi, pi]."""
        d = self.q - self.q_nominal
        if self.revolute is None:
            return d
        return np.where(self.revolute, np.pi - np.mod(np.pi - d, 2 * np.pi), d)

    def to_dict(self) -> dict:
        """Plain dict, SI; flags as lists of target indices."""
        return {"joint_names": list(self.joint_names), "n": int(len(self.q)), "match": self.match,
                "joints": self.q, "nominal_joints": self.q_nominal, "correction": self.correction,
                "residual_position_m": self.residual_position, "residual_orientation_rad": self.residual_orientation,
                "out_of_reach": np.flatnonzero(~self.reached).tolist(),
                "near_singularity": np.flatnonzero(self.near_singularity).tolist(),
                "out_of_limits": np.flatnonzero(self.out_of_limits).tolist(), "iterations": self.iterations.tolist()}


def compensate(calibrated: Mechanism, nominal: Mechanism, joints=None, poses=None, seed=None, match="pose",
               singular_ratio=1e-3, tol_position=1e-9, tol_orientation=1e-9, max_iter=100, restarts=8,
               rng=0) -> Compensation:
    """Joints that put the calibrated robot's tool at each target, from the nominal solution.

    joints : (n, dof) nominal joint configurations (their nominal tool poses are the targets), or
    poses : (n, 4, 4) target tool poses in the nominal base frame, m (``seed`` as ``nominal_solution``).
    """
    if (joints is None) == (poses is None):
        raise ValueError("compensate: give either joints or poses")
    if calibrated.joint_names != nominal.joint_names:
        raise ModelError("compensate: the calibrated and nominal models have different joints")
    kw = {"tol_position": tol_position, "tol_orientation": tol_orientation, "max_iter": max_iter}
    J_nom = None
    if joints is not None:
        q_nom = nominal.check_joints(joints)
        T_target, J_nom = joint_jacobian(nominal, q_nom)
    else:
        T_target = np.asarray(poses, float)
        if T_target.ndim != 3 or T_target.shape[1:] != (4, 4):
            raise ValueError(f"poses: expected (n, 4, 4) tool poses, got shape {T_target.shape}")
        q_nom = nominal_solution(nominal, T_target, seed, restarts, rng, match, **kw)
    q, rp, ro, it, J = solve_jacobians(calibrated, T_target, q_nom, match, **kw)
    q = into_limits(calibrated, q, q_nom)          # full turns of revolute joints: the same poses and J
    Js = J[:, :3] if match == "position" else np.concatenate([J[:, :3], LENGTH * J[:, 3:]], axis=1)
    s2 = np.linalg.eigvalsh(np.einsum("nij,nkj->nik", Js, Js) if Js.shape[1] <= Js.shape[2]
                            else np.einsum("nji,njk->nik", Js, Js))          # squared singular values, ascending
    ratio = np.sqrt(np.maximum(s2[:, 0], 0.0) / np.maximum(s2[:, -1], 1e-300))
    reached = (rp <= tol_position) & (ro <= tol_orientation)
    comp = Compensation(tuple(calibrated.joint_names), q, q_nom, rp, ro, reached, ratio < singular_ratio,
                        calibrated.out_of_limits(q).any(axis=1), it, match,
                        np.array([t != PRISMATIC for t in calibrated.joint_types]))
    comp.jacobians = (J, J_nom)
    return comp
