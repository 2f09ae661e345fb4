"""Compensated trajectories: the joints, velocities and accelerations that make the calibrated robot's tool
follow the path the nominal model plans.

Positions: ``compensate`` of each point's nominal joints (the calibrated robot's tool where the nominal
model puts it, at the calibration's tool point). Velocities: the tool's twist is kept, ``J_c(q_c) qdot_c =
J_n(q_n) qdot_n``, with the smallest change to the nominal rate, ``qdot_c = qdot_n + J_c^+ (J_n - J_c)
qdot_n`` (``J^+`` the pseudo-inverse; on a square arm this is ``J_c^-1 J_n qdot_n``, on a redundant one it
keeps the nominal path's self-motion, as the compensated positions do; rows as in ``compensate``:
position, and orientation times ``LENGTH`` when the pose is matched); accelerations by the same map (the
term of the map's own rate, second order in the calibration's small correction, is left out). SI: rad,
m, s.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..models.base import Mechanism
from .compensate import Compensation, compensate
from ..models.ik import LENGTH, joint_jacobian


@dataclass
class CompensatedTrajectory:
    """positions, velocities, accelerations : (m, dof) compensated (velocities / accelerations None when
    the input had none); ``compensation``: the point-wise solution with its flags; ``flagged`` (m,) mask of
    points out of reach, near a singularity or out of limits, with ``reasons`` {point: text}."""

    positions: np.ndarray
    velocities: np.ndarray | None
    accelerations: np.ndarray | None
    compensation: Compensation
    flagged: np.ndarray
    reasons: dict


def rate_map(calibrated: Mechanism, nominal: Mechanism, q_c, q_n, match="pose", jacobians=None) -> np.ndarray:
    """(m, dof, dof) ``I + J_c(q_c)^+ (J_n(q_n) - J_c(q_c))``: a joint rate of the nominal path to the
    calibrated one (``jacobians``: (J_c, J_n) when already known)."""
    if jacobians is not None and jacobians[1] is not None:
        Jc, Jn = jacobians
    else:
        Jc, Jn = joint_jacobian(calibrated, q_c)[1], joint_jacobian(nominal, q_n)[1]
    if match == "position":
        Jc, Jn = Jc[:, :3], Jn[:, :3]
    else:
        Jc, Jn = Jc.copy(), Jn.copy()
        Jc[:, 3:] *= LENGTH
        Jn[:, 3:] *= LENGTH
    rows, dof = Jc.shape[1:]
    if rows <= dof:   # full row rank away from singularities: J^+ = J^T (J J^T)^-1, damped a hair
        G = np.einsum("mij,mkj->mik", Jc, Jc) + 1e-12 * np.eye(rows)
        return np.eye(dof) + np.einsum("mji,mjk->mik", Jc, np.linalg.solve(G, Jn - Jc))
    return np.eye(dof) + np.linalg.pinv(Jc) @ (Jn - Jc)


def compensate_trajectory(calibrated: Mechanism, nominal: Mechanism, positions, velocities=None, accelerations=None,
                          match="pose") -> CompensatedTrajectory:
    """Compensate a trajectory's points (m, dof) with their rates (see the module docstring)."""
    q_n = nominal.check_joints(positions, "positions")
    comp = compensate(calibrated, nominal, joints=q_n, match=match)
    M = (rate_map(calibrated, nominal, comp.q, q_n, match, comp.jacobians)
         if velocities is not None or accelerations is not None else None)

    def mapped(rates, field):
        if rates is None:
            return None
        r = np.asarray(rates, float).reshape(q_n.shape)
        if not np.all(np.isfinite(r)):
            raise ValueError(f"{field}: not finite")
        return np.einsum("mij,mj->mi", M, r)

    flagged = ~comp.reached | comp.near_singularity | comp.out_of_limits
    reasons = {}
    for i in np.flatnonzero(flagged):
        why = [w for w, on in (("out of reach", not comp.reached[i]), ("near a singularity", comp.near_singularity[i]),
                               ("out of the joint limits", comp.out_of_limits[i])) if on]
        reasons[int(i)] = ", ".join(why) + f" (residual {comp.residual_position[i] * 1e6:.3g} um)"
    return CompensatedTrajectory(comp.q, mapped(velocities, "velocities"), mapped(accelerations, "accelerations"),
                                 comp, flagged, reasons)
