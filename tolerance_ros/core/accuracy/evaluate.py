"""Measured against nominal: pose errors, the budget check, identification of parameter errors, and
the ISO 9283 statistics per test pose. All inputs and outputs SI; errors in the robot base frame."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import criterion_bound
from ..geometry import rotation_error
from .iso9283 import pose_characteristics


def pose_errors(T_nominal, T_actual):
    """(dp (n, 3) m, dphi (n, 3) rad): position and small-rotation errors of actual vs nominal poses."""
    Tn, Ta = np.asarray(T_nominal, float), np.asarray(T_actual, float)
    dp = Ta[:, :3, 3] - Tn[:, :3, 3]
    dphi = rotation_error(Ta[:, :3, :3], Tn[:, :3, :3])
    return dp, dphi


def predicted_bounds(model, q, delta, criterion="paper", k_sigma=3.0, EJ=None):
    """(position (n,) m, orientation (n,) rad) bounds of the budget at configurations q."""
    EJ = EJ if EJ is not None else model.error_jacobian(q)
    return (criterion_bound(EJ.position, delta, criterion, k_sigma),
            criterion_bound(EJ.orientation, delta, criterion, k_sigma))


def budget_check(err_pos, bound_pos, limit=None, err_ori=None, bound_ori=None, limit_ori=None) -> dict:
    """Per-measurement verdicts: 'within' the predicted bound, 'over bound' (still within the design
    limit), 'over limit'; margins are bound - error (negative when over)."""
    e, b = np.asarray(err_pos, float), np.asarray(bound_pos, float)
    verdict = np.where(e <= b, "within", "over bound").astype(object)
    if limit is not None:
        verdict[e > limit] = "over limit"
    out = {"error": e, "bound": b, "margin": b - e, "verdict": verdict}
    if err_ori is not None and bound_ori is not None:
        eo, bo = np.asarray(err_ori, float), np.asarray(bound_ori, float)
        out.update(orientation_error=eo, orientation_bound=bo, orientation_margin=bo - eo)
        worse = (eo > bo) & (verdict == "within")
        verdict[worse] = "over bound"
        if limit_ori is not None:
            verdict[eo > limit_ori] = "over limit"
    return out


def summarize_verdicts(check: dict) -> dict:
    v = check["verdict"]
    n = len(v)
    counts = {k: int(np.sum(v == k)) for k in ("within", "over bound", "over limit")}
    return {"n": n, **counts, "within_rate": counts["within"] / n if n else None,
            "worst_margin": float(check["margin"].min()) if n else None}


BASE_NAMES = ("base.x", "base.y", "base.z", "base.rx", "base.ry", "base.rz")


@dataclass
class Identification:
    """Identified parameter errors (SI) with their standard deviations and identifiability."""

    names: tuple
    dx: np.ndarray
    std: np.ndarray
    base: np.ndarray
    rank: int
    n_unknowns: int
    condition: float
    unidentifiable: list
    residual_rms_before: float
    residual_rms_after: float
    iterations: int
    out_of_tolerance: list = field(default_factory=list)

    def to_dict(self) -> dict:
        return {"parameters": [{"name": n, "error": float(v), "std": float(s)}
                               for n, v, s in zip(self.names, self.dx, self.std)],
                "base_correction": dict(zip(BASE_NAMES, map(float, self.base))), "rank": self.rank,
                "unknowns": self.n_unknowns, "condition": self.condition, "unidentifiable": self.unidentifiable,
                "residual_rms_before_m": self.residual_rms_before, "residual_rms_after_m": self.residual_rms_after,
                "iterations": self.iterations, "out_of_tolerance": self.out_of_tolerance}


def base_jacobian(p) -> np.ndarray:
    """(n, 6, 6) pose error of tool points p (n, 3) per base correction [translation m; rotation rad]."""
    n = len(p)
    Jb = np.zeros((n, 6, 6))
    Jb[:, :3, :3] = np.eye(3)
    Jb[:, 0, 4], Jb[:, 0, 5] = p[:, 2], -p[:, 1]
    Jb[:, 1, 3], Jb[:, 1, 5] = -p[:, 2], p[:, 0]
    Jb[:, 2, 3], Jb[:, 2, 4] = p[:, 1], -p[:, 0]
    Jb[:, 3:, 3:] = np.eye(3)
    return Jb


def _stack(model, q, T_meas, dx, base, use_orientation, w_ori):
    T_nom = model.fk(q, dx)
    Tb = _apply_base(T_nom, base)
    dp, dphi = pose_errors(Tb, T_meas)
    EJ = model.error_jacobian(q, dx)
    Jb = base_jacobian(Tb[:, :3, 3])
    R0 = _base_matrix(base)[:3, :3]
    Jp = np.einsum("ij,njp->nip", R0, EJ.position)
    Jo = np.einsum("ij,njp->nip", R0, EJ.orientation)
    rows_J = [np.concatenate([Jp, Jb[:, :3]], axis=2)]
    rows_r = [dp]
    if use_orientation:
        rows_J.append(w_ori * np.concatenate([Jo, Jb[:, 3:]], axis=2))
        rows_r.append(w_ori * dphi)
    J = np.concatenate(rows_J, axis=1).reshape(-1, model.n_params + 6)
    r = np.concatenate(rows_r, axis=1).reshape(-1)
    return J, r


def _base_matrix(base):
    from scipy.spatial.transform import Rotation
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(base[3:]).as_matrix()
    T[:3, 3] = base[:3]
    return T


def _apply_base(T, base):
    return _base_matrix(base) @ T


def identify(model, q, T_meas, delta=None, sigma_position=1e-5, sigma_orientation=None, iterations=8,
             estimate_base=True, tol_rank=1e-6) -> Identification:
    """Estimate parameter errors dx (and a base correction) from measured base-frame poses.

    Regularised Gauss-Newton on the nonlinear model: minimise ``|r(dx)|^2 / sigma^2 + |dx / delta|^2``
    (the prior N(0, delta^2) when tolerances are given, a weak ridge otherwise). Identifiability from
    the SVD of the column-scaled Jacobian: singular values below ``tol_rank`` of the largest leave a
    null space; a parameter with a weight of 0.1 or more in it cannot be separated from others.
    """
    q = model.check_joints(q)
    T_meas = np.asarray(T_meas, float)
    p = model.n_params
    use_ori = sigma_orientation is not None
    w_ori = sigma_position / sigma_orientation if use_ori else 0.0
    scale = np.concatenate([np.where(np.asarray(delta) > 0, delta, 1e-3) if delta is not None
                            else np.array([1e-3 if k == "length" else 1e-3 for k in model.param_kinds]),
                            np.array([1e-3] * 3 + [1e-3] * 3)])
    prior = (sigma_position / scale) ** 2 if delta is not None else np.full(p + 6, 1e-12)
    if not estimate_base:
        prior[p:] = 1e12
    x = np.zeros(p + 6)
    J, r = _stack(model, q, T_meas, None, x[p:], use_ori, w_ori)
    rms0 = float(np.sqrt(np.mean(r ** 2)))
    it = 0
    for it in range(1, iterations + 1):
        A = J.T @ J + np.diag(prior)
        g = J.T @ r - prior * x
        step = np.linalg.solve(A, g)
        x = x + step
        J, r = _stack(model, q, T_meas, x[:p], x[p:], use_ori, w_ori)
        if np.max(np.abs(step) / scale) < 1e-10:
            break
    A = J.T @ J + np.diag(prior)
    cov = np.linalg.inv(A) * sigma_position ** 2
    Js = J * scale
    cols = np.flatnonzero(np.linalg.norm(Js, axis=0) > 0)
    s, Vt = np.linalg.svd(Js[:, cols], full_matrices=True)[1:]
    smax = s.max() if s.size else 0.0
    rank = int(np.sum(s > tol_rank * smax))
    null = Vt[rank:]
    names = tuple(model.param_names) + BASE_NAMES
    weight = np.zeros(p + 6)
    if null.size:
        weight[cols] = np.sqrt(np.sum(null ** 2, axis=0))
    zero_effect = np.setdiff1d(np.arange(p + 6), cols)
    unident = [names[j] for j in range(p + 6) if weight[j] >= 0.1 or j in zero_effect]
    if not estimate_base:
        unident = [u for u in unident if not u.startswith("base.")]
    cond = float(smax / s[rank - 1]) if rank else float("inf")
    ident = Identification(tuple(model.param_names), x[:p], np.sqrt(np.diag(cov))[:p], x[p:], rank, len(cols), cond,
                           unident, rms0, float(np.sqrt(np.mean(r ** 2))), it)
    if delta is not None:
        d = np.asarray(delta, float)
        for j, n in enumerate(model.param_names):
            if n in unident or d[j] <= 0:
                continue
            if abs(ident.dx[j]) > d[j]:
                ident.out_of_tolerance.append({"name": n, "error": float(ident.dx[j]), "tolerance": float(d[j]),
                                               "ratio": float(abs(ident.dx[j]) / d[j]),
                                               "std": float(ident.std[j])})
        ident.out_of_tolerance.sort(key=lambda o: -o["ratio"])
    return ident


def per_pose_statistics(names, T_commanded: dict, T_measured, labels) -> dict:
    """ISO 9283 characteristics for each test pose name (measured poses grouped by ``labels``)."""
    out = {}
    labels = np.asarray(labels, dtype=object)
    for name in names:
        sel = labels == name
        if sel.sum() >= 2:
            out[name] = pose_characteristics(T_commanded[name], np.asarray(T_measured)[sel]).to_dict()
        else:
            out[name] = {"n": int(sel.sum()), "note": "fewer than 2 measurements"}
    return out


def measurement_joints(model, meas, campaign=None) -> np.ndarray:
    """(n, dof) joints of each measurement in the model's order: from the joint columns, or from the
    campaign's test pose named in the ``pose`` column."""
    if meas.joints is not None and len(meas.joint_names):
        missing = [n for n in model.joint_names if n not in meas.joint_names]
        if missing:
            raise ValueError(f"{meas.source}: no joint columns for {missing} (have {list(meas.joint_names)})")
        idx = [list(meas.joint_names).index(n) for n in model.joint_names]
        return meas.joints[:, idx]
    if campaign is None or meas.pose is None:
        raise ValueError(f"{meas.source}: measurements carry no joints; give a campaign and label each row with "
                         f"its test pose")
    table = dict(zip(campaign.names, campaign.joints_for(model)))
    unknown = sorted({str(p) for p in meas.pose if p not in table})
    if unknown:
        raise ValueError(f"{meas.source}: test pose(s) {unknown} are not in campaign {campaign.name!r} "
                         f"({campaign.names})")
    return np.array([table[p] for p in meas.pose])
