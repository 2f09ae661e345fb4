"""Inverse kinematics of serial chains, batched: damped least squares (Levenberg-Marquardt:
``dq = J^T (J J^T + lambda^2 I)^-1 e``, lambda adapted per target, the step kept only when the error falls)
from given joints (``solve``), or the nominal solution of pose targets from a seed or from the best of
several seeded starts (``nominal_solution``). The joint Jacobian is the parameter-error Jacobian's column of
each joint's zero offset (theta_i or d_i of a D-H chain, ``j.offset`` of a URDF chain), which moves the tool
as the joint. SI: m, rad; orientation rows weighed by ``LENGTH`` against positions.
"""
from __future__ import annotations

import numpy as np

from ..geometry import rotation_error
from .base import PRISMATIC, Mechanism, ModelError

LENGTH = 1.0  # m: weight of orientation errors (rad) against position errors (m) in the solve and the flags
MATCHES = ("pose", "position")


def joint_columns(model: Mechanism) -> np.ndarray:
    """(dof,) column of each joint's zero offset in the model's parameter-error Jacobian."""
    try:
        return model.joint_columns()
    except ModelError:
        raise ModelError(f"compensation: robot {model.name!r} is a {type(model).__name__}; joints are solved for "
                         f"serial D-H and URDF chains") from None


def joint_jacobian(model: Mechanism, q):
    """(T (n, 4, 4), J (n, 6, dof)): tool poses and their derivative in the joints (base frame; position
    rows m per rad or m per m, orientation rows rad per unit)."""
    T, EJ = model.fk_and_jacobian(q)
    return T, EJ.J[:, :, joint_columns(model)] * model.joint_direction


def _errors(T_target, T, match):
    dp = T_target[:, :3, 3] - T[:, :3, 3]
    if match == "position":
        return dp, np.zeros_like(dp)
    return dp, rotation_error(T_target[:, :3, :3], T[:, :3, :3])


def _stacked(dp, dphi, match):
    return dp if match == "position" else np.concatenate([dp, LENGTH * dphi], axis=1)


def solve(model: Mechanism, T_target, q0, match="pose", tol_position=1e-9, tol_orientation=1e-9, max_iter=100,
          damping=1e-3, max_step=0.2):
    """Damped least squares for every target at once: (q (n, dof), residual position (n,) m, residual
    orientation (n,) rad, iterations (n,)), from q0 (n, dof) towards T_target (n, 4, 4). A step is
    shortened to ``max_step`` (rad or m, largest joint) so that a solve near a singularity stays near
    its start."""
    return solve_jacobians(model, T_target, q0, match, tol_position, tol_orientation, max_iter, damping, max_step)[:4]


def solve_jacobians(model, T_target, q0, match, tol_position, tol_orientation, max_iter, damping=1e-3, max_step=0.2):
    """``solve`` and the joint Jacobians (n, 6, dof) at its answer."""
    if match not in MATCHES:
        raise ValueError(f"match: expected one of {MATCHES}, got {match!r}")
    T_target = np.asarray(T_target, float)
    q = model.check_joints(q0).copy()
    n = len(q)
    lam = np.full(n, float(damping))
    T, J = joint_jacobian(model, q)
    dp, dphi = _errors(T_target, T, match)
    err = np.linalg.norm(_stacked(dp, dphi, match), axis=1)
    done = (np.linalg.norm(dp, axis=1) <= tol_position) & (np.linalg.norm(dphi, axis=1) <= tol_orientation)
    iters = np.zeros(n, int)
    rows = 3 if match == "position" else 6
    for _ in range(max_iter):
        act = np.flatnonzero(~done & (lam < 1e6))
        if not act.size:
            break
        iters[act] += 1
        Ja = J[act, :rows].copy()
        if rows == 6:
            Ja[:, 3:] *= LENGTH
        e = _stacked(dp[act], dphi[act], match)
        A = Ja @ Ja.transpose(0, 2, 1) + (lam[act] ** 2)[:, None, None] * np.eye(rows)
        step = np.einsum("nij,ni->nj", Ja, np.linalg.solve(A, e[:, :, None])[:, :, 0])
        step *= np.minimum(1.0, max_step / np.maximum(np.abs(step).max(axis=1), 1e-300))[:, None]
        q_try = q[act] + step
        T_try, J_try = joint_jacobian(model, q_try)
        dp_try, dphi_try = _errors(T_target[act], T_try, match)
        err_try = np.linalg.norm(_stacked(dp_try, dphi_try, match), axis=1)
        better = err_try < err[act]
        ok = act[better]
        q[ok], T[ok], J[ok] = q_try[better], T_try[better], J_try[better]
        dp[ok], dphi[ok], err[ok] = dp_try[better], dphi_try[better], err_try[better]
        lam[ok] = np.maximum(lam[ok] / 3.0, 1e-12)
        lam[act[~better]] *= 4.0
        done[ok] = ((np.linalg.norm(dp[ok], axis=1) <= tol_position)
                    & (np.linalg.norm(dphi[ok], axis=1) <= tol_orientation))
    return q, np.linalg.norm(dp, axis=1), np.linalg.norm(dphi, axis=1), iters, J


def into_limits(model: Mechanism, q, near=None) -> np.ndarray:
    """Each revolute joint at the full-turn equivalent closest to ``near`` (default: itself) that lies
    within its limits, where there is one (a continuous joint has none: the equivalent closest to ``near``);
    prismatic joints unchanged."""
    q = np.asarray(q, float)
    ref = q if near is None else np.asarray(near, float)
    lo, hi = model.joint_limits[:, 0], model.joint_limits[:, 1]
    k = np.round((ref - q) / (2 * np.pi))[..., None] + np.array([-1.0, 0.0, 1.0])
    cand = q[..., None] + 2 * np.pi * k
    inside = (cand >= lo[:, None] - 1e-12) & (cand <= hi[:, None] + 1e-12)
    if model.continuous is not None:
        inside |= np.asarray(model.continuous, bool)[:, None]
    best = np.argmin(np.abs(cand - ref[..., None]) + np.where(inside, 0.0, 1e9), axis=-1)
    out = np.take_along_axis(cand, best[..., None], axis=-1)[..., 0]
    rev = np.array([t != PRISMATIC for t in model.joint_types])
    return np.where(rev, out, q)


def nominal_solution(model: Mechanism, T_target, seed=None, restarts=8, rng=0, match="pose", **kw):
    """(n, dof) joints of the nominal model at pose targets: from ``seed`` ((dof,) or (n, dof)), or the
    best of the middle of the joint limits and ``restarts`` seeded random starts (the converged solution
    closest to the middle)."""
    T_target = np.asarray(T_target, float)
    n = len(T_target)
    mid = model.joint_limits.mean(axis=1)
    if seed is not None:
        q0 = np.broadcast_to(model.check_joints(seed) if np.ndim(seed) == 2 else np.asarray(seed, float),
                             (n, model.dof))
        return into_limits(model, solve(model, T_target, q0, match, **kw)[0], q0)
    starts = np.vstack([mid[None], model.sample_joints(restarts, rng)])
    k = len(starts)
    q0 = np.repeat(starts[None], n, axis=0).reshape(n * k, model.dof)
    q, rp, ro, _ = solve(model, np.repeat(T_target, k, axis=0), q0, match, **kw)
    q = into_limits(model, q, q0).reshape(n, k, model.dof)
    tol_p, tol_o = kw.get("tol_position", 1e-9), kw.get("tol_orientation", 1e-9)
    bad = ((rp > tol_p) | (ro > tol_o)).reshape(n, k)
    bad |= model.out_of_limits(q.reshape(n * k, -1)).any(axis=1).reshape(n, k)
    score = np.linalg.norm(q - mid, axis=2) + 1e6 * bad + (rp + ro).reshape(n, k)
    return q[np.arange(n), np.argmin(score, axis=1)]
