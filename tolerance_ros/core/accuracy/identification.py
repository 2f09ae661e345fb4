"""Identification of the as-built parameter errors (and a base correction) from measured poses.

One result type, ``Identification``, for the batch fit (``identify``: regularised Gauss-Newton on the
nonlinear model, positions and optionally orientations) and for the streaming one
(``identify_from_normal_equations``: one regularised least-squares step from normal equations that
were accumulated in constant memory, positions only). Both use the prior ``N(0, delta^2)`` of the
tolerances when a budget is given (a weak ridge otherwise), judge identifiability from the singular
values of the column-scaled Jacobian, and list the identifiable parameters outside their tolerance.
For a calibration, ``identify(..., hold="dependent")`` holds a minimal set of dependent parameters at
nominal (chosen by QR with column pivoting, ``dependent_parameters``) so that the others are
estimated without a prior, and ``noise_from_residuals`` scales their covariance by the residual noise.
SI throughout; the base correction is [x y z (m), rx ry rz (rad)] applied on the left of the model.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import qr

from ..geometry import exp_so3
from .verdicts import pose_errors

BASE_NAMES = ("base.x", "base.y", "base.z", "base.rx", "base.ry", "base.rz")
SCALE_WITHOUT_BUDGET = 1e-3  # column scale (m or rad) of parameters without a tolerance, and of the base


@dataclass
class Identification:
    """Identified parameter errors (SI) with their standard deviations and identifiability.

    ``method`` is 'gauss-newton' (batch, nonlinear) or 'linearised' (streaming, one step). ``held``
    names the parameters held at nominal (error 0, std 0); ``aliases`` maps an estimated unknown to the
    held parameters it absorbs, ``{name: {held: c}}`` with ``estimate = own error + sum c * held error``
    to first order (SI ratios, at nominal); ``sigma`` is the position noise (m) that scales the
    covariance (estimated from the residuals when asked); ``fit_condition`` is the condition number of
    the column-scaled Jacobian of the estimated unknowns (parameters and base).
    """

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
    method: str = "gauss-newton"
    out_of_tolerance: list = field(default_factory=list)
    held: list = field(default_factory=list)
    aliases: dict = field(default_factory=dict)
    sigma: float | None = None
    fit_condition: float | None = None

    def to_dict(self) -> dict:
        return {"method": self.method,
                "parameters": [{"name": n, "error": float(v), "std": float(s)}
                               for n, v, s in zip(self.names, self.dx, self.std)],
                "base_correction": dict(zip(BASE_NAMES, map(float, self.base))), "rank": self.rank,
                "unknowns": self.n_unknowns, "condition": self.condition, "unidentifiable": self.unidentifiable,
                "residual_rms_before_m": self.residual_rms_before, "residual_rms_after_m": self.residual_rms_after,
                "iterations": self.iterations, "out_of_tolerance": self.out_of_tolerance, "held": self.held,
                "aliases": self.aliases, "sigma_m": self.sigma, "fit_condition": self.fit_condition}


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


def base_matrix(base) -> np.ndarray:
    """4x4 transform of a base correction [x y z (m), rotation vector (rad)]."""
    T = np.eye(4)
    T[:3, :3] = exp_so3(base[3:])[0]
    T[:3, 3] = base[:3]
    return T


def column_scale(delta, p: int) -> np.ndarray:
    """(p + 6,) expected size of each unknown: its tolerance, or ``SCALE_WITHOUT_BUDGET``."""
    d = np.full(p, SCALE_WITHOUT_BUDGET) if delta is None else np.where(np.asarray(delta) > 0, delta,
                                                                          SCALE_WITHOUT_BUDGET)
    return np.concatenate([d, np.full(6, SCALE_WITHOUT_BUDGET)])


def _prior(delta, sigma_position, p, estimate_base=True) -> np.ndarray:
    """Diagonal of the regulariser: (sigma / tolerance)^2 with a budget, a weak ridge without."""
    prior = (sigma_position / column_scale(delta, p)) ** 2 if delta is not None else np.full(p + 6, 1e-12)
    if not estimate_base:
        prior[p:] = 1e12
    return prior


def _stack(model, q, T_meas, dx, base, use_orientation, w_ori):
    """Residuals (measured - model) and their Jacobian in the unknowns [dx; base], stacked per pose."""
    T_nom, EJ = model.fk_and_jacobian(q, dx)
    B = base_matrix(base)
    Tb = B @ T_nom
    dp, dphi = pose_errors(Tb, T_meas)
    Jb = base_jacobian(Tb[:, :3, 3])
    R0 = B[:3, :3]
    rows_J = [np.concatenate([np.einsum("ij,njp->nip", R0, EJ.position), Jb[:, :3]], axis=2)]
    rows_r = [dp]
    if use_orientation:
        rows_J.append(w_ori * np.concatenate([np.einsum("ij,njp->nip", R0, EJ.orientation), Jb[:, 3:]], axis=2))
        rows_r.append(w_ori * dphi)
    J = np.concatenate(rows_J, axis=1).reshape(-1, model.n_params + 6)
    r = np.concatenate(rows_r, axis=1).reshape(-1)
    return J, r


def _identifiability(s, V, cols, n_unknowns, tol_rank):
    """(rank, condition, weight in the null space per unknown) from the singular values ``s`` and right
    singular vectors ``V`` (columns) of the scaled Jacobian restricted to the columns ``cols``."""
    smax = s.max() if s.size else 0.0
    keep = s > tol_rank * smax
    rank = int(keep.sum())
    weight = np.zeros(n_unknowns)
    null = V[:, ~keep]
    if null.size:
        weight[cols] = np.sqrt(np.sum(null ** 2, axis=1))
    cond = float(smax / s[keep].min()) if rank else float("inf")
    return rank, cond, weight


def dependent_parameters(Js, p, estimate_base=True, tol_rank=1e-6) -> np.ndarray:
    """(p,) mask of the parameters to hold at nominal so that the rest (and the base) are identifiable.

    ``Js`` is the column-scaled Jacobian in the unknowns [dx (p); base (6)]. The base columns are kept;
    their span is projected out of the parameter columns, and QR with column pivoting (the elimination
    of redundant parameters of Hollerbach & Wampler 1996) keeps the parameters whose pivot exceeds
    ``tol_rank`` times the largest singular value of ``Js``; the other parameters are dependent.
    """
    A = Js[:, :p]
    if estimate_base:
        Qb, Rb = np.linalg.qr(Js[:, p:])
        Qb = Qb[:, np.abs(np.diag(Rb)) > 1e-12 * max(np.abs(Rb).max(), 1e-300)]
        A = A - Qb @ (Qb.T @ A)
    smax = np.linalg.norm(Js, 2) if Js.size else 0.0
    _, R, piv = qr(A, mode="economic", pivoting=True)
    pivots = np.zeros(p)
    k = min(R.shape)
    pivots[piv[:k]] = np.abs(np.diag(R))[:k]
    return ~(pivots > tol_rank * smax)


def _aliases(Js, free, held, scale, names, tol=1e-6) -> dict:
    """What each estimated unknown absorbs of the held parameters (see ``Identification``), from the
    least-squares projection of the held columns on the estimated ones at nominal."""
    if not len(held) or not len(free):
        return {}
    A = np.linalg.lstsq(Js[:, free], Js[:, held], rcond=None)[0]
    out = {}
    for i, j in enumerate(free):
        hits = {names[h]: float(A[i, k] * scale[j] / scale[h]) for k, h in enumerate(held) if abs(A[i, k]) > tol}
        if hits:
            out[names[j]] = hits
    return out


def _result(model, x, cov, rank, cond, weight, cols, delta, rms0, rms1, iterations, method, estimate_base=True):
    p = model.n_params
    names = tuple(model.param_names) + BASE_NAMES
    zero_effect = set(np.setdiff1d(np.arange(p + 6), cols).tolist())
    unident = [names[j] for j in range(p + 6) if weight[j] >= 0.1 or j in zero_effect]
    if not estimate_base:
        unident = [u for u in unident if not u.startswith("base.")]
    std = np.sqrt(np.maximum(np.diag(cov), 0.0))
    ident = Identification(tuple(model.param_names), x[:p], std[:p], x[p:], rank, len(cols), cond, unident,
                           rms0, rms1, iterations, method)
    if delta is not None:
        d = np.asarray(delta, float)
        for j, n in enumerate(model.param_names):
            if n in unident or d[j] <= 0 or abs(ident.dx[j]) <= d[j]:
                continue
            ident.out_of_tolerance.append({"name": n, "error": float(ident.dx[j]), "tolerance": float(d[j]),
                                           "ratio": float(abs(ident.dx[j]) / d[j]), "std": float(ident.std[j])})
        ident.out_of_tolerance.sort(key=lambda o: -o["ratio"])
    return ident


def identify(model, q, T_meas, delta=None, sigma_position=1e-5, sigma_orientation=None, iterations=8,
             estimate_base=True, tol_rank=1e-6, hold=None, noise_from_residuals=False) -> Identification:
    """Estimate parameter errors dx (and a base correction) from measured base-frame poses (n, 4, 4).

    Regularised Gauss-Newton on the nonlinear model: minimise ``|r(dx)|^2 / sigma^2 + |dx / delta|^2``.
    Identifiability from the SVD of the column-scaled Jacobian at the nominal parameters (a structural
    property of the model and the poses; the perturbed model only blurs its null space): singular values
    below ``tol_rank`` of the largest leave a null space, and a parameter with a weight of 0.1 or more
    in it cannot be separated from others. ``sigma_orientation`` (rad) adds the orientation rows.

    ``hold``: None estimates every parameter; ``"dependent"`` holds the parameters of
    ``dependent_parameters`` (judged at nominal) at 0; a list of names holds those. With
    ``noise_from_residuals`` the covariance is scaled by the residual noise ``|r|^2 / (rows - unknowns)``
    instead of ``sigma_position^2`` (the prior, if any, is kept).
    """
    q = model.check_joints(q)
    T_meas = np.asarray(T_meas, float)
    p = model.n_params
    use_ori = sigma_orientation is not None
    w_ori = sigma_position / sigma_orientation if use_ori else 0.0
    scale = column_scale(delta, p)
    prior = _prior(delta, sigma_position, p, estimate_base)
    x = np.zeros(p + 6)
    J, r = _stack(model, q, T_meas, None, x[p:], use_ori, w_ori)
    Js = J * scale
    rms0 = float(np.sqrt(np.mean(r ** 2)))
    held = np.zeros(p + 6, bool)
    if not estimate_base:
        held[p:] = True
    if isinstance(hold, str) and hold == "dependent":
        held[:p] = dependent_parameters(Js, p, estimate_base, tol_rank)
    elif hold is not None:
        held[model.param_index(list(hold))] = True
    free = np.flatnonzero(~held)
    it = 0
    for it in range(1, iterations + 1):
        Jf = J[:, free]
        step = np.linalg.solve(Jf.T @ Jf + np.diag(prior[free]), Jf.T @ r - prior[free] * x[free])
        x[free] += step
        J, r = _stack(model, q, T_meas, x[:p], x[p:], use_ori, w_ori)
        if np.max(np.abs(step) / scale[free]) < 1e-10:
            break
    Jf = J[:, free]
    noise = sigma_position
    if noise_from_residuals:
        dof = len(r) - len(free)
        if dof < 1:
            raise ValueError(f"identification: {len(r)} residuals for {len(free)} unknowns; the noise cannot be "
                             f"estimated (measure more poses)")
        noise = float(np.sqrt(r @ r / dof))
    cov = np.zeros((p + 6, p + 6))
    cov[np.ix_(free, free)] = np.linalg.inv(Jf.T @ Jf + np.diag(prior[free])) * noise ** 2
    cols = np.flatnonzero(np.linalg.norm(Js, axis=0) > 0)
    A = Js[:, cols]
    _, s, Vt = np.linalg.svd(A, full_matrices=A.shape[0] < A.shape[1])  # Vt square; U small or thin
    s = np.concatenate([s, np.zeros(len(cols) - len(s))])
    rank, cond, weight = _identifiability(s, Vt.T, cols, p + 6, tol_rank)
    ident = _result(model, x, cov, rank, cond, weight, cols, delta, rms0, float(np.sqrt(np.mean(r ** 2))), it,
                    "gauss-newton", estimate_base)
    ident.held = [model.param_names[j] for j in np.flatnonzero(held[:p])]
    ident.aliases = _aliases(Js, free, np.flatnonzero(held[:p]), scale, tuple(model.param_names) + BASE_NAMES)
    ident.sigma = noise
    sf = np.linalg.svd(Js[:, free], compute_uv=False)
    ident.fit_condition = float(sf.max() / sf.min()) if sf.size and sf.min() > 0 else float("inf")
    return ident


def identify_from_normal_equations(model, JtJ, Jtr, rtr, rows, delta=None, sigma_position=1e-5,
                                   tol_rank=1e-6) -> Identification:
    """One regularised least-squares step from accumulated normal equations (``J^T J``, ``J^T r``,
    ``r^T r`` over ``rows`` residuals, unknowns [dx; base], position rows, at the nominal parameters);
    see ``identify``."""
    p = model.n_params
    prior = _prior(delta, sigma_position, p)
    A = JtJ + np.diag(prior)
    x = np.linalg.solve(A, Jtr)
    cov = np.linalg.inv(A) * sigma_position ** 2
    scale = column_scale(delta, p)
    N = JtJ * np.outer(scale, scale)
    cols = np.flatnonzero(np.diag(N) > 0)
    lam, V = np.linalg.eigh(N[np.ix_(cols, cols)])
    rank, cond, weight = _identifiability(np.sqrt(np.maximum(lam, 0.0)), V, cols, p + 6, tol_rank)
    rss_after = max(rtr - 2.0 * x @ Jtr + x @ JtJ @ x, 0.0)
    return _result(model, x, cov, rank, cond, weight, cols, delta, float(np.sqrt(rtr / rows)),
                   float(np.sqrt(rss_after / rows)), 1, "linearised")
