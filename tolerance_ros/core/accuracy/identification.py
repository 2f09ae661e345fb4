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

from ..geometry import exp_so3, rotation_error
from .targets import Targets, shift_jacobian

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
    targets: Targets | None = None
    targets_std: np.ndarray | None = None
    compliance: np.ndarray | None = None
    compliance_std: np.ndarray | None = None
    compliance_held: list = field(default_factory=list)
    row_residuals: np.ndarray | None = None
    weights: np.ndarray | None = None
    n_free: int = 0

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
    """(p + 6,) expected size of each unknown: its tolerance (finite, > 0), or ``SCALE_WITHOUT_BUDGET``."""
    d = np.full(p, SCALE_WITHOUT_BUDGET) if delta is None else np.where(
        (np.asarray(delta) > 0) & np.isfinite(delta), delta, SCALE_WITHOUT_BUDGET)
    return np.concatenate([d, np.full(6, SCALE_WITHOUT_BUDGET)])


def _prior(delta, sigma_position, p, estimate_base=True) -> np.ndarray:
    """Diagonal of the regulariser: (sigma / tolerance)^2 with a budget (0 where the tolerance is infinite,
    the scale of ``column_scale`` where it is 0), a weak ridge without."""
    if delta is None:
        prior = np.full(p + 6, 1e-12)
    else:
        d = np.asarray(delta, float)
        prior = np.where(np.isinf(np.r_[d, np.zeros(6)]), 0.0, (sigma_position / column_scale(d, p)) ** 2)
    if not estimate_base:
        prior[p:] = 1e12
    return prior


class _Layout:
    """Columns of the unknowns: parameter errors (p), base correction (6), target points (3 per target),
    target rotations (3 per target, measured frames with orientation rows), compliances (one per joint
    in ``cmask``)."""

    def __init__(self, p, K, est_targets, rot_targets, cmask):
        self.p, self.K = p, K
        self.cmask = np.zeros(0, bool) if cmask is None else np.asarray(cmask, bool)
        self.nc = int(self.cmask.sum())
        self.nt = 3 * K if est_targets else 0
        self.nr = 3 * K if (est_targets and rot_targets) else 0
        self.base = slice(p, p + 6)
        self.t = slice(p + 6, p + 6 + self.nt)
        self.r = slice(self.t.stop, self.t.stop + self.nr)
        self.c = slice(self.r.stop, self.r.stop + self.nc)
        self.n = self.c.stop

    @property
    def nuisance(self) -> np.ndarray:
        """Columns always estimated, whatever the parameters: the base and the targets."""
        return np.r_[np.arange(self.base.start, self.base.stop), np.arange(self.t.start, self.r.stop)]

    @property
    def estimable(self) -> np.ndarray:
        """Columns that may be held: the parameters and the compliances."""
        return np.r_[np.arange(self.p), np.arange(self.c.start, self.c.stop)]


def _targets_with(targets, layout, x):
    """Target frames (K, 4, 4) with the updates of ``x``: points shifted, rotations turned in the tool frame."""
    X = targets.X.copy()
    if layout.nt:
        X[:, :3, 3] += x[layout.t].reshape(-1, 3)
    if layout.nr:
        X[:, :3, :3] = exp_so3(x[layout.r].reshape(-1, 3)) @ X[:, :3, :3]
    return X


def _stack(model, q, T_meas, x, layout, targets, idx, use_ori, w_ori, gravity=None, sqrt_w=None):
    """(J, r, |dp|): the Jacobian in the unknowns (``_Layout``) and the residuals (measured - model), rows
    stacked per measurement, and each measurement's position residual (m, unweighted). The model of a
    measurement is ``B T(q + C g, dx) X_k`` at its target ``k``."""
    p = layout.p
    q_eff = q
    if layout.nc:
        c = np.zeros(model.dof)
        c[layout.cmask] = x[layout.c]
        q_eff = q + gravity * c
    T_tool, EJ = model.fk_and_jacobian(q_eff, x[:p])
    X = _targets_with(targets, layout, x)[idx]
    arms = np.einsum("nij,nj->ni", T_tool[:, :3, :3], X[:, :3, 3])
    Jt = shift_jacobian(EJ.J, arms) if np.any(arms) else EJ.J
    B = base_matrix(x[layout.base])
    R0 = B[:3, :3]
    Tp = B @ T_tool @ X
    n = len(q)
    rows = 6 if use_ori else 3
    J = np.zeros((n, rows, layout.n))
    J[:, :3, :p] = np.einsum("ij,njp->nip", R0, Jt[:, :3])
    Jb = base_jacobian(Tp[:, :3, 3])
    J[:, :3, layout.base] = Jb[:, :3]
    if use_ori:
        J[:, 3:, :p] = w_ori * np.einsum("ij,njp->nip", R0, Jt[:, 3:])
        J[:, 3:, layout.base] = w_ori * Jb[:, 3:]
    RW = R0 @ T_tool[:, :3, :3]
    for k in range(layout.K if layout.nt else 0):
        sel = idx == k
        J[sel, :3, layout.t.start + 3 * k:layout.t.start + 3 * k + 3] = RW[sel]
        if use_ori and layout.nr:
            J[sel, 3:, layout.r.start + 3 * k:layout.r.start + 3 * k + 3] = w_ori * RW[sel]
    if layout.nc:
        Jc = Jt[:, :, model.joint_columns()[layout.cmask]] * gravity[:, None, layout.cmask]
        J[:, :3, layout.c] = np.einsum("ij,njc->nic", R0, Jc[:, :3])
        if use_ori:
            J[:, 3:, layout.c] = w_ori * np.einsum("ij,njc->nic", R0, Jc[:, 3:])
    dp = T_meas[:, :3, 3] - Tp[:, :3, 3]
    r = dp if not use_ori else np.concatenate([dp, w_ori * rotation_error(T_meas[:, :3, :3], Tp[:, :3, :3])], axis=1)
    if sqrt_w is not None:
        J *= sqrt_w[:, None, None]
        r = r * sqrt_w[:, None]
    return J.reshape(n * rows, layout.n), r.reshape(-1), np.linalg.norm(dp, axis=1)


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


def _largest_singular_value(A) -> float:
    """Largest singular value of a tall matrix, from the eigenvalues of its Gram matrix."""
    if not A.size:
        return 0.0
    return float(np.sqrt(max(np.linalg.eigvalsh(A.T @ A)[-1], 0.0)))


def _singular_values_and_vectors(A):
    """(singular values, descending; right singular vectors as columns) of A (m, k), from the Gram matrix
    when A is tall (its small singular values are accurate to about sqrt(eps) of the largest, enough to
    judge ranks at ``tol_rank``), else from a full SVD."""
    if A.shape[0] >= A.shape[1]:
        lam, V = np.linalg.eigh(A.T @ A)
        order = np.argsort(lam)[::-1]
        return np.sqrt(np.maximum(lam[order], 0.0)), V[:, order]
    _, s, Vt = np.linalg.svd(A, full_matrices=True)
    return np.concatenate([s, np.zeros(A.shape[1] - len(s))]), Vt.T


def dependent_parameters(Js, p, estimate_base=True, tol_rank=1e-6) -> np.ndarray:
    """(p,) mask of the parameters to hold at nominal so that the rest (and the base) are identifiable;
    ``Js`` is the column-scaled Jacobian in the unknowns [dx (p); base (6)] (see ``dependent_columns``)."""
    return dependent_columns(Js, np.arange(p), np.arange(p, p + 6) if estimate_base else np.zeros(0, int), tol_rank)


def dependent_columns(Js, estimable, nuisance, tol_rank=1e-6) -> np.ndarray:
    """Mask over the ``estimable`` columns of the scaled Jacobian ``Js``: those to hold so that the rest and
    the ``nuisance`` columns (always estimated: base, targets) are identifiable.

    The nuisance columns' span is projected out of the estimable columns, and QR with column pivoting
    (the elimination of redundant parameters of Hollerbach & Wampler 1996) keeps the columns whose pivot
    exceeds ``tol_rank`` times the largest singular value of ``Js``; the others are dependent.
    """
    A = Js[:, estimable]
    if len(nuisance):
        Qb, Rb = np.linalg.qr(Js[:, nuisance])
        Qb = Qb[:, np.abs(np.diag(Rb)) > 1e-12 * max(np.abs(Rb).max(), 1e-300)]
        A = A - Qb @ (Qb.T @ A)
    smax = _largest_singular_value(Js)
    from scipy.linalg import qr  # here: importing scipy takes about 1 s of a node's start
    _, R, piv = qr(A, mode="economic", pivoting=True)
    pivots = np.zeros(len(estimable))
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
             estimate_base=True, tol_rank=1e-6, hold=None, noise_from_residuals=False, targets=None,
             target_index=None, estimate_targets=False, gravity=None, compliance=None,
             weights=None, estimate=None, analysis=True, compliance_prior=None) -> Identification:
    """Estimate parameter errors dx (and a base correction) from measured base-frame poses (n, 4, 4).

    Regularised Levenberg-Marquardt on the nonlinear model: minimise ``|r(dx)|^2 / sigma^2 + |dx / delta|^2``
    (a Gauss-Newton step, damped only where it would raise the cost). Identifiability from the SVD of the
    column-scaled Jacobian at the nominal parameters (a structural property of the model and the poses;
    the perturbed model only blurs its null space): singular values below ``tol_rank`` of the largest
    leave a null space, and a parameter with a weight of 0.1 or more in it cannot be separated from
    others. ``sigma_orientation`` (rad) adds the orientation rows (measured frames only).

    targets, target_index : the measured targets' frames in the tool frame (``targets.Targets``) and each
    row's target (default: the tool frame itself); with ``estimate_targets`` their points (and, with
    orientation rows, their rotations) are corrected too. gravity, compliance : (n, dof) gravity load of
    each row's joints (N m, N) and the (dof,) mask of the joints whose compliance (rad/(N m), m/N) is
    estimated: the joints deflect by ``c * g``; ``compliance_prior`` (dof,) their prior standard deviations
    (rad/(N m), m/N; None: none). weights : (n,) row weights (0 leaves a row out).
    analysis : False skips the identifiability analysis (rank, condition, unidentifiable, aliases), for
    fits that only predict (cross-validation).

    ``estimate``: the names of the parameters to estimate (None: all; the others are held at 0). ``hold``:
    None holds no more; ``"dependent"`` also holds the parameters (and compliances) of ``dependent_columns``
    (judged at nominal among those without a prior, the base and targets always estimated) at 0; a list of
    names holds those. With ``noise_from_residuals`` the covariance is scaled by the residual noise
    ``|r|^2 / (rows - unknowns)`` instead of ``sigma_position^2`` (the prior, if any, is kept).
    """
    q = model.check_joints(q)
    T_meas = np.asarray(T_meas, float)
    n, p = len(q), model.n_params
    use_ori = sigma_orientation is not None
    w_ori = sigma_position / sigma_orientation if use_ori else 0.0
    targets = targets if targets is not None else Targets.at_tool()
    idx = targets.rows(target_index if target_index is not None else [], n)
    layout = _Layout(p, len(targets), estimate_targets, targets.frames and use_ori, compliance)
    if layout.nc:
        gravity = np.asarray(gravity, float).reshape(n, model.dof)
    w = np.ones(n) if weights is None else np.asarray(weights, float).reshape(n)
    sqrt_w = None if weights is None else np.sqrt(w)
    scale = np.concatenate([column_scale(delta, p), np.full(layout.nt + layout.nr, SCALE_WITHOUT_BUDGET),
                            _compliance_scale(gravity, layout)])
    prior = np.concatenate([_prior(delta, sigma_position, p, estimate_base), np.full(layout.n - p - 6, 1e-12)])
    if layout.nc and compliance_prior is not None:
        prior[layout.c] = (sigma_position / np.asarray(compliance_prior, float)[layout.cmask]) ** 2
    x = np.zeros(layout.n)
    J, r, _ = _stack(model, q, T_meas, x, layout, targets, idx, use_ori, w_ori, gravity, sqrt_w)
    rows_used = max(int(np.count_nonzero(w)), 1) * (6 if use_ori else 3)
    Js = J * scale
    rms0 = float(np.sqrt(r @ r / rows_used))
    held = np.zeros(layout.n, bool)
    if not estimate_base:
        held[layout.base] = True
    if estimate is not None:
        held[:p] = True
        held[model.param_index(list(estimate))] = False
    if isinstance(hold, str) and hold == "dependent":
        nuisance = layout.nuisance if estimate_base else layout.nuisance[6:]
        cand = layout.estimable[~held[layout.estimable]]
        cand = cand[prior[cand] <= 1e-12]  # a column with a prior is determined by it
        held[cand[dependent_columns(Js, cand, nuisance, tol_rank)]] = True
    elif hold is not None:
        held[model.param_index(list(hold))] = True
    free = np.flatnonzero(~held)
    cost = r @ r + prior @ (x * x)
    lam, it = 0.0, 0
    for it in range(1, iterations + 1):
        Jf = J[:, free] * scale[free]
        A = Jf.T @ Jf + np.diag(prior[free] * scale[free] ** 2)
        g = Jf.T @ r - prior[free] * x[free] * scale[free]
        for _ in range(12):
            step = np.linalg.solve(A + lam * np.diag(np.diag(A)), g) * scale[free]
            x_new = x.copy()
            x_new[free] += step
            J_new, r_new, _ = _stack(model, q, T_meas, x_new, layout, targets, idx, use_ori, w_ori, gravity, sqrt_w)
            cost_new = r_new @ r_new + prior @ (x_new * x_new)
            if np.isfinite(cost_new) and cost_new <= cost * (1 + 1e-12):
                lam = lam / 10 if lam > 1e-6 else 0.0
                break
            lam = max(lam * 10, 1e-4)
        else:
            break
        x, J, r, cost = x_new, J_new, r_new, cost_new
        if np.max(np.abs(step) / scale[free]) < 1e-10:
            break
    Jf = J[:, free]
    noise = sigma_position
    if noise_from_residuals:
        dof = rows_used - len(free)
        if dof < 1:
            raise ValueError(f"identification: {rows_used} residuals for {len(free)} unknowns; the noise cannot be "
                             f"estimated (measure more poses)")
        noise = float(np.sqrt(r @ r / dof))
    cov = np.zeros((layout.n, layout.n))
    cov[np.ix_(free, free)] = np.linalg.pinv(Jf.T @ Jf + np.diag(prior[free])) * noise ** 2
    cols = np.flatnonzero(np.linalg.norm(Js, axis=0) > 0)
    main = np.arange(p + 6)
    if analysis:
        s, V = _singular_values_and_vectors(Js[:, cols])
        rank, cond, weight = _identifiability(s, V, cols, layout.n, tol_rank)
    else:
        rank, cond, weight = 0, float("nan"), np.zeros(layout.n)
    ident = _result(model, x[main], cov[np.ix_(main, main)], rank, cond, weight[main], cols[cols < p + 6], delta,
                    rms0, float(np.sqrt(r @ r / rows_used)), it, "gauss-newton", estimate_base)
    ident.held = [model.param_names[j] for j in np.flatnonzero(held[:p])]
    ident.sigma = noise
    if analysis:
        ident.aliases = _aliases(Js, free[free < p + 6], np.flatnonzero(held[:p]), scale,
                                 tuple(model.param_names) + BASE_NAMES)
        sf = _singular_values_and_vectors(Js[:, free])[0]
        ident.fit_condition = float(sf.max() / sf.min()) if sf.size and sf.min() > 0 else float("inf")
    else:
        ident.unidentifiable = []
    ident.targets = Targets(targets.names, _targets_with(targets, layout, x), targets.frames)
    if layout.nt:
        ident.targets_std = np.sqrt(np.maximum(np.diag(cov)[layout.t], 0.0)).reshape(-1, 3)
    if layout.nc:
        ident.compliance = np.zeros(model.dof)
        ident.compliance[layout.cmask] = x[layout.c]
        ident.compliance_std = np.zeros(model.dof)
        ident.compliance_std[layout.cmask] = np.sqrt(np.maximum(np.diag(cov)[layout.c], 0.0))
        ident.compliance_held = [model.joint_names[j] for j, h in zip(np.flatnonzero(layout.cmask), held[layout.c]) if h]
    ident.row_residuals = _stack(model, q, T_meas, x, layout, targets, idx, use_ori, w_ori, gravity)[2]
    ident.weights = w
    ident.n_free = int(len(free))
    return ident


def _compliance_scale(gravity, layout) -> np.ndarray:
    """Column scale of each estimated compliance: the one that deflects its joint by 1 mrad (or 1 mm) at
    the largest load of the data."""
    if not layout.nc:
        return np.zeros(0)
    top = np.abs(np.asarray(gravity, float)[:, layout.cmask]).max(axis=0)
    return SCALE_WITHOUT_BUDGET / np.where(top > 0, top, 1.0)


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
