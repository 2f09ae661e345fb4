"""Identification of the as-built parameter errors (and a base correction) from measured poses.

One result type, ``Identification``, for the batch fit (``identify``: regularised Gauss-Newton on the
nonlinear model, positions and optionally orientations) and for the streaming one
(``identify_from_normal_equations``: one regularised least-squares step from normal equations that
were accumulated in constant memory, positions only). Both use the prior ``N(0, delta^2)`` of the
tolerances when a budget is given (a weak ridge otherwise), judge identifiability from the singular
values of the column-scaled Jacobian, and list the identifiable parameters proven out of their tolerance (by a
``conformity.DecisionRule``, guarded by the estimate's uncertainty).
For a calibration, ``identify(..., hold="dependent")`` holds a minimal set of dependent parameters at
nominal (chosen by QR with column pivoting, ``dependent_parameters``) so that the others are
estimated without a prior, and ``noise_from_residuals`` scales their covariance by the residual noise.
SI throughout; the base correction is [x y z (m), rx ry rz (rad)] applied on the left of the model.
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields, replace

import numpy as np

from .conformity import DEFAULT_RULE, DecisionRule
from .geometry import exp_so3, matrix_log_vec, rotation_error
from .models.base import ModelError
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
    the column-scaled Jacobian of the estimated unknowns (parameters and base); ``out_of_tolerance`` the
    identifiable parameters decided out by the rule ``decision_rule`` (with a budget).
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
    decision_rule: str | None = None
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
    row_leverage: np.ndarray | None = None
    weights: np.ndarray | None = None
    n_free: int = 0
    x: np.ndarray | None = None
    free_columns: np.ndarray | None = None
    convergence: "Convergence | None" = None
    held_judged_at: str = "nominal"
    effective_unknowns: float = 0.0
    undetermined: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        return {"method": self.method,
                "parameters": [{"name": n, "error": float(v), "std": float(s)}
                               for n, v, s in zip(self.names, self.dx, self.std)],
                "base_correction": dict(zip(BASE_NAMES, map(float, self.base))), "rank": self.rank,
                "unknowns": self.n_unknowns, "condition": self.condition, "unidentifiable": self.unidentifiable,
                "residual_rms_before_m": self.residual_rms_before, "residual_rms_after_m": self.residual_rms_after,
                "iterations": self.iterations, "out_of_tolerance": self.out_of_tolerance,
                "decision_rule": self.decision_rule, "held": self.held,
                "aliases": self.aliases, "sigma_m": self.sigma, "fit_condition": self.fit_condition,
                "convergence": None if self.convergence is None else self.convergence.to_dict(),
                "undetermined": dict(self.undetermined)}


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


def _prior(delta, sigma_position, p, estimate_base=True, base_prior=None) -> np.ndarray:
    """Diagonal of the regulariser, (p + 6,): (sigma / tolerance)^2 of each parameter with a budget (0 where
    the tolerance is infinite, the scale of ``column_scale`` where it is 0), 0 without; on the base
    correction 0 unless ``base_prior`` = (length m, angle rad) is given."""
    prior = np.zeros(p + 6)
    if delta is not None:
        d = np.asarray(delta, float)
        prior[:p] = np.where(np.isinf(d), 0.0, (sigma_position / column_scale(d, p)[:p]) ** 2)
    if base_prior is not None:
        prior[p:p + 3] = (sigma_position / float(base_prior[0])) ** 2
        prior[p + 3:] = (sigma_position / float(base_prior[1])) ** 2
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


def _rotated(R, A) -> np.ndarray:
    """(n, 3, k) ``R @ A[i]`` for each (3, k) block of ``A`` (n, 3, k): one matrix product over every block (one
    BLAS call, where an einsum or a broadcast matmul loops over the n small products)."""
    n, _, k = A.shape
    flat = np.ascontiguousarray(A.transpose(1, 0, 2)).reshape(3, n * k)
    return (R @ flat).reshape(3, n, k).transpose(1, 0, 2)


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
    J[:, :3, :p] = _rotated(R0, Jt[:, :3])
    Jb = base_jacobian(Tp[:, :3, 3])
    J[:, :3, layout.base] = Jb[:, :3]
    if use_ori:
        J[:, 3:, :p] = w_ori * _rotated(R0, Jt[:, 3:])
        J[:, 3:, layout.base] = w_ori * Jb[:, 3:]
    RW = R0 @ T_tool[:, :3, :3]
    for k in range(layout.K if layout.nt else 0):
        sel = idx == k
        J[sel, :3, layout.t.start + 3 * k:layout.t.start + 3 * k + 3] = RW[sel]
        if use_ori and layout.nr:
            J[sel, 3:, layout.r.start + 3 * k:layout.r.start + 3 * k + 3] = w_ori * RW[sel]
    if layout.nc:
        Jc = Jt[:, :, model.joint_columns()[layout.cmask]] * gravity[:, None, layout.cmask]
        J[:, :3, layout.c] = _rotated(R0, Jc[:, :3])
        if use_ori:
            J[:, 3:, layout.c] = w_ori * _rotated(R0, Jc[:, 3:])
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


TIE = 1e-6  # relative weight by which a preferred column wins a tie of the pivoting (never chance)


def dependent_columns(Js, estimable, nuisance, tol_rank=1e-6, preference=None) -> np.ndarray:
    """Mask over the ``estimable`` columns of the scaled Jacobian ``Js``: those to hold so that the rest and
    the ``nuisance`` columns (always estimated: base, targets) are identifiable.

    The nuisance columns' span is projected out of the estimable columns, and QR with column pivoting
    (the elimination of redundant parameters of Hollerbach & Wampler 1996) keeps the columns whose pivot
    exceeds ``tol_rank`` times the largest singular value of ``Js``; the others are dependent. Columns of
    equal size (a joint's zero offset and the turn of its origin about the joint's axis are the same column)
    are kept in the order of ``preference`` (len(estimable),) (small whole numbers, higher first), then the
    earlier one: each column is weighted by ``1 + TIE * (preference + order)`` so that rounding never breaks
    the tie.
    """
    A = Js[:, estimable]
    pref = np.zeros(len(estimable)) if preference is None else np.asarray(preference, float)
    A = A * (1.0 + TIE * (pref + 0.5 * (1.0 - np.arange(len(estimable)) / max(len(estimable), 1))))
    N = Js[:, nuisance]
    if A.shape[0] > 2 * (A.shape[1] + N.shape[1]):
        # A tall Jacobian (many measurements) is first reduced by an orthogonal transformation (unpivoted QR,
        # blocked LAPACK): the projection and the pivoting below depend only on the columns' inner products,
        # which it keeps, so they run on a square matrix of the same geometry.
        R = np.linalg.qr(np.hstack([A, N]), mode="r")
        A, N = R[:, :A.shape[1]], R[:, A.shape[1]:]
    if len(nuisance):
        Qb, Rb = np.linalg.qr(N)
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


def _result(model, x, cov, rank, cond, weight, cols, delta, rms0, rms1, iterations, method, estimate_base=True,
            rule: DecisionRule = DEFAULT_RULE):
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
        decided = rule.decide(ident.dx, ident.std, d)
        for j, n in enumerate(model.param_names):
            if n in unident or d[j] <= 0 or decided[j] != "out":
                continue
            ident.out_of_tolerance.append({"name": n, "error": float(ident.dx[j]), "tolerance": float(d[j]),
                                           "ratio": float(abs(ident.dx[j]) / d[j]), "std": float(ident.std[j]),
                                           "decision": "out"})
        ident.out_of_tolerance.sort(key=lambda o: -o["ratio"])
        ident.decision_rule = str(rule)
    return ident


MAX_ITERATIONS = 200   # cap of the damped Gauss-Newton loop; a fit that reaches it says so (Identification.convergence)
FTOL = 1e-12           # converged: a full Gauss-Newton step would lower the cost by less than this share
XTOL = 1e-12           # converged: the step is below this share of the unknowns (in column-scale units)
ROUNDING = 1e-9        # ... or no step lowers the cost, with a full step's decrement below this share: rounding
PRIOR_SHARE = 0.7      # a parameter whose posterior std is above this share of its prior std is set by the prior
NEAR_COPY = 0.99       # two estimated unknowns correlated beyond this cannot be told apart by the data


@dataclass
class Convergence:
    """How the damped Gauss-Newton (Levenberg-Marquardt) loop ended.

    stop : 'gradient' (a full Gauss-Newton step would lower the cost by less than ``FTOL`` of it), 'step' (the
    step is below ``XTOL`` of the unknowns, and the full step does not lower the cost by more than ``FTOL`` of
    it), 'no descent' (neither a damped step nor the full one lowers the cost) or 'iteration cap'.  converged :
    the gradient test, or a stop on the step or for no descent where the decrement is below ``ROUNDING`` of the
    cost (the minimum to rounding); a larger decrement that no step can take is a bound or a model that cannot
    be assembled there, not a minimum.  gradient_cosine : the
    largest cosine between the residual and a column of the Jacobian (0 at a minimum, scale-free; with a
    prior, of the augmented problem).  decrement : the cost a full Gauss-Newton step would still remove,
    as a share of the cost.  cost : the final cost, |r|^2 + the prior's term (m^2).
    """

    iterations: int
    stop: str
    converged: bool
    gradient_cosine: float
    decrement: float
    cost: float

    def to_dict(self) -> dict:
        return {"iterations": self.iterations, "stop": self.stop, "converged": self.converged,
                "gradient_cosine": self.gradient_cosine, "decrement": self.decrement, "cost_m2": self.cost}

    def words(self) -> str:
        """The stop in words, for reports."""
        if self.stop == "iteration cap":
            return (f"NOT CONVERGED: stopped by the cap of {self.iterations} iterations (a full step would still "
                    f"lower the cost by {self.decrement:.2g} of it)")
        if not self.converged:
            return (f"NOT CONVERGED: stopped ({self.stop}) after {self.iterations} iterations, a full step would still "
                    f"lower the cost by {self.decrement:.2g} of it but no step can be taken there (a bound of the "
                    f"search, or a model that cannot be assembled)")
        return f"converged in {self.iterations} iterations ({self.stop} test; largest gradient cosine " \
               f"{self.gradient_cosine:.1e})"


def _update(x, step, rot):
    """x + step, the rotation vectors at ``rot`` (k, 3) composed (``exp(step) exp(x)``) as their columns are
    the derivative of a turn applied on the left."""
    out = x + step
    if len(rot):
        R = exp_so3(step[rot]) @ exp_so3(x[rot])
        out[rot] = matrix_log_vec(R)
    return out


def _minimise(evaluate, x, free, scale, prior, rot, cap):
    """(x, J, r, Convergence): Levenberg-Marquardt on ``|r(x)|^2 + prior @ x^2`` over the ``free`` unknowns,
    from x. ``evaluate(x) -> (J, r)``; columns scaled by ``scale``. Each iteration takes the eigenvectors of
    the scaled normal matrix once: the Gauss-Newton step and every damped one (Levenberg, ``H + mu I`` in
    the scaled space, Nielsen's update of ``mu``) are then sums over them, directions the data leave
    undetermined (eigenvalues below 1e-12 of the largest) left out. Stops by the tests of ``Convergence``, and
    never while the full Gauss-Newton step lowers the cost: where the damped steps would stop (a step below
    ``XTOL``, or no damped step lowering the cost) the full step is tried, and taken when it lowers the cost by
    more than ``FTOL`` of it (a damping grown large on a rejected step otherwise leaves steps too short to go on)."""
    J, r = evaluate(x)
    cost = float(r @ r + prior @ (x * x))
    mu, nu, it, stop = 0.0, 2.0, 0, "iteration cap"
    sf, pf = scale[free], prior[free] * scale[free] ** 2
    decrement = cosine = np.inf
    small = False

    def trial(mu, V, lam, gv, live):
        s = V[:, live] @ (gv[live] / (lam[live] + mu))
        step = np.zeros_like(x)
        step[free] = s * sf
        x_new = _update(x, step, rot)
        try:
            J_new, r_new = evaluate(x_new)
            cost_new = float(r_new @ r_new + prior @ (x_new * x_new))
        except (ValueError, ArithmeticError):  # a step the model cannot assemble (a parallel mechanism)
            J_new, r_new, cost_new = None, None, np.inf
        return s, x_new, J_new, r_new, cost_new

    while True:
        Jf = J[:, free] * sf
        H = Jf.T @ Jf + np.diag(pf)
        g = Jf.T @ r - prior[free] * x[free] * sf
        lam, V = np.linalg.eigh(H)
        top = max(float(lam[-1]) if lam.size else 0.0, 1e-300)
        live = lam > 1e-12 * top
        gv = V.T @ g
        decrement = float(np.sum(gv[live] ** 2 / lam[live])) / cost if cost > 0 else 0.0
        norms = np.sqrt(np.sum(Jf * Jf, axis=0) + pf)
        cosine = float(np.max(np.abs(g) / np.where(norms > 0, norms, 1.0))) / max(np.sqrt(cost), 1e-300) \
            if len(free) else 0.0
        if decrement <= FTOL:
            stop = "gradient"
            break
        if it >= cap:
            break
        accepted = tried_full = False
        if not small:
            while mu <= 1e6 * top:
                s, x_new, J_new, r_new, cost_new = trial(mu, V, lam, gv, live)
                tried_full = tried_full or mu == 0.0
                pred = float(2.0 * s @ g - s @ H @ s)
                rho = (cost - cost_new) / pred if pred > 0 else -1.0
                if np.isfinite(cost_new) and cost_new < cost and rho > 0:
                    mu = mu * max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3) if mu > 1e-12 * top else 0.0
                    nu = 2.0
                    accepted = True
                    break
                mu = max(mu * nu, 1e-6 * top)
                nu *= 2.0
        if not accepted and not tried_full:
            s, x_new, J_new, r_new, cost_new = trial(0.0, V, lam, gv, live)
            if np.isfinite(cost_new) and cost - cost_new > FTOL * cost:
                accepted, mu, nu = True, 0.0, 2.0
        if not accepted:
            stop = "step" if small else "no descent"
            break
        it += 1
        small = np.max(np.abs(s)) <= XTOL * (np.max(np.abs(x[free] / sf)) + XTOL)
        x, J, r, cost = x_new, J_new, r_new, cost_new
    converged = stop == "gradient" or (stop in ("step", "no descent") and decrement <= ROUNDING)
    return x, J, r, Convergence(it, stop, bool(converged), cosine, max(decrement, 0.0), cost)


REGISTRATIONS = ("base", "base+tool")
PRIOR = (0.005, 0.005)      # m, rad: default prior std of the origin errors of a regularised fit (see the docs)


@dataclass(frozen=True)
class FitOptions:
    """How a calibration fits, validates and chooses (SI).

    registration : 'base' (the tracker) or 'base+tool' (and each target's offset on the tool).
    sigma_position : tracker position noise, m (weights the rows; the floor of every noise estimate).
    sigma_orientation : tracker orientation noise, rad, or None (orientations not fitted).
    robust : reject outliers (``fit``).  prior : (length m, angle rad) prior std of the origin errors of the
    regularised candidates, or None.  registration_prior : (m, rad) prior std of the base correction, or
    None (none).  folds, seed : the k-fold split by test pose.  iterations : cap of each fit's loop.
    payload : (kg, (3,) m in the tool frame) point mass that loads the joints of the elastostatic term, or
    None (the URDF's inertials, else a lumped 1 kg at the tool frame, see ``elastic.Load``).
    """

    registration: str = "base"
    sigma_position: float = 1e-5
    sigma_orientation: float | None = None
    robust: bool = True
    prior: tuple | None = PRIOR
    registration_prior: tuple | None = None
    folds: int = 10
    seed: int = 0
    iterations: int = MAX_ITERATIONS
    payload: tuple | None = None

    def __post_init__(self):
        if self.registration not in REGISTRATIONS:
            raise ValueError(f"registration: expected one of {REGISTRATIONS}, got {self.registration!r}")
        if not (np.isfinite(self.sigma_position) and self.sigma_position > 0):
            raise ValueError(f"sigma_position: expected a positive noise (m), got {self.sigma_position!r}")
        if self.folds < 2:
            raise ValueError("folds: must be >= 2")

    def updated(self, **changes) -> "FitOptions":
        """A copy with ``changes``; TypeError naming an unknown option."""
        known = {f.name for f in fields(self)}
        unknown = sorted(set(changes) - known)
        if unknown:
            raise TypeError(f"unknown calibration option(s) {unknown}; known: {sorted(known)}")
        return replace(self, **changes) if changes else self


@dataclass
class Unknowns:
    """What an identification estimates besides the parameter errors, and from which rows. ``estimate``: the
    names of the parameters estimated (None: all; the others held at 0); ``estimate_base``: the base
    correction too. ``targets``, ``target_index``: the measured targets' frames in the tool frame
    (``targets.Targets``) and each row's target (default: the tool frame itself); with ``estimate_targets``
    their points (and, with orientation rows, their rotations) are corrected too. ``gravity`` (n, dof): each
    row's joints' gravity load (N m, N) and ``compliance`` the (dof,) mask of the joints whose compliance
    (rad/(N m), m/N) is estimated (the joints deflect by ``c * g``), ``compliance_prior`` (dof,) their prior
    standard deviations (None: none)."""

    estimate: list | None = None
    estimate_base: bool = True
    targets: Targets | None = None
    target_index: object = None
    estimate_targets: bool = False
    gravity: object = None
    compliance: object = None
    compliance_prior: object = None


def identify(model, q, T_meas, delta=None, options: FitOptions | None = None, unknowns: Unknowns | None = None, *,
             hold=None, noise_from_residuals=False, weights=None, start=None, analysis=True,
             tol_rank=1e-6, rule: DecisionRule = DEFAULT_RULE, clusters=None) -> Identification:
    """Estimate parameter errors dx (and a base correction) from measured base-frame poses (n, 4, 4).

    Levenberg-Marquardt on the nonlinear model until converged (``Convergence``: the step and gradient
    tests, or the cap ``options.iterations``): minimise ``|r(dx)|^2 / sigma^2 + |dx / delta|^2`` (``options``:
    ``FitOptions``, its ``sigma_position``, ``sigma_orientation``, ``iterations`` and ``registration_prior``).
    No prior on the base correction and the targets unless ``options.registration_prior`` = (length m, angle
    rad) is given. ``unknowns`` (``Unknowns``): what is estimated besides the parameter errors. Identifiability from
    the SVD of the column-scaled Jacobian at the nominal parameters (a structural property of the model and
    the poses; the perturbed model only blurs its null space): singular values below ``tol_rank`` of the
    largest leave a null space, and a parameter with a weight of 0.1 or more in it cannot be separated from
    others. ``options.sigma_orientation`` (rad) adds the orientation rows (measured frames only).

    weights : (n,) row weights (0 leaves a row out).
    analysis : False skips the identifiability analysis (rank, condition, unidentifiable, aliases, what
    the data cannot tell), for fits that only predict (cross-validation). start : an ``Identification`` of
    the same unknowns to start from (a refit with other weights or noise).

    ``hold``:
    None holds no more; ``"dependent"`` also holds the parameters (and compliances) of ``dependent_columns``
    (a prior does not make a dependent parameter identifiable: it would only share the correction among
    copies; judged on columns scaled by 1 mm and 1 mrad whatever the prior, so that the choice among equal
    columns is ``dependent_columns``'s preference; the base and targets always estimated) at 0, judged at
    nominal, then at the solution among the
    columns still free (refitted when the solution shows more); a list of names holds those. With
    ``noise_from_residuals`` the covariance is scaled by the residual noise ``|r|^2 / (rows - effective
    unknowns)`` instead of ``sigma_position^2`` (the prior, if any, is kept); with ``clusters`` (n,), the group of
    each measurement (the visits of one test pose), by the larger of that and the noise of the groups' means
    (``cluster_noise``): an error the model lacks at a pose (backlash, a deflection) repeats at every visit of it
    and is not averaged away by the visits.
    """
    o, u = options or FitOptions(), unknowns or Unknowns()
    sigma_position, sigma_orientation, iterations = o.sigma_position, o.sigma_orientation, o.iterations
    estimate, estimate_base, targets = u.estimate, u.estimate_base, u.targets
    gravity, compliance = u.gravity, u.compliance
    q = model.check_joints(q)
    T_meas = np.asarray(T_meas, float)
    n, p = len(q), model.n_params
    use_ori = sigma_orientation is not None
    w_ori = sigma_position / sigma_orientation if use_ori else 0.0
    targets = targets if targets is not None else Targets.at_tool()
    idx = targets.rows(u.target_index if u.target_index is not None else [], n)
    layout = _Layout(p, len(targets), u.estimate_targets, targets.frames and use_ori, compliance)
    if layout.nc:
        gravity = np.asarray(gravity, float).reshape(n, model.dof)
    w = np.ones(n) if weights is None else np.asarray(weights, float).reshape(n)
    sqrt_w = None if weights is None else np.sqrt(w)
    scale = np.concatenate([column_scale(delta, p), np.full(layout.nt + layout.nr, SCALE_WITHOUT_BUDGET),
                            _compliance_scale(gravity, layout)])
    prior = np.concatenate([_prior(delta, sigma_position, p, estimate_base, o.registration_prior),
                            np.zeros(layout.n - p - 6)])
    if layout.nc and u.compliance_prior is not None:
        prior[layout.c] = (sigma_position / np.asarray(u.compliance_prior, float)[layout.cmask]) ** 2
    rot = np.r_[np.arange(p + 3, p + 6), np.arange(layout.r.start, layout.r.stop)].reshape(-1, 3) \
        if estimate_base else np.arange(layout.r.start, layout.r.stop).reshape(-1, 3)

    def evaluate(x):
        J, r, _ = _stack(model, q, T_meas, x, layout, targets, idx, use_ori, w_ori, gravity, sqrt_w)
        return J, r

    x0 = np.zeros(layout.n)
    J0, r0 = evaluate(x0)
    rows_used = max(int(np.count_nonzero(w)), 1) * (6 if use_ori else 3)
    Js0 = J0 * scale
    natural = np.concatenate([np.full(p + 6 + layout.nt + layout.nr, SCALE_WITHOUT_BUDGET), scale[layout.c]])
    rms0 = float(np.sqrt(r0 @ r0 / rows_used))
    held = np.zeros(layout.n, bool)
    if not estimate_base:
        held[layout.base] = True
    if estimate is not None:
        held[:p] = True
        held[model.param_index(list(estimate))] = False
    dependent = isinstance(hold, str) and hold == "dependent"
    nuisance = layout.nuisance if estimate_base else layout.nuisance[6:]
    cand = layout.estimable[~held[layout.estimable]]
    prefer = _preference(model, layout, cand)
    if dependent:
        held[cand[dependent_columns(J0 * natural, cand, nuisance, tol_rank, prefer)]] = True
    elif hold is not None:
        held[model.param_index(list(hold))] = True
    x = x0.copy()
    if start is not None and getattr(start, "x", None) is not None and len(start.x) == layout.n:
        x = np.where(held, 0.0, start.x)
    judged = "nominal"
    for _ in range(3):
        free = np.flatnonzero(~held)
        x, J, r, conv = _minimise(evaluate, x, free, scale, prior, rot, iterations)
        if not dependent or not len(cand):
            break
        at = held.copy()  # a dependence that only the solution shows, among the columns still free
        still = ~held[cand]
        at[cand[still][dependent_columns(J * natural, cand[still], nuisance, tol_rank, prefer[still])]] = True
        judged = "nominal and solution"
        if np.array_equal(at, held):
            break
        held = at
        x = np.where(held, 0.0, x)
    Jf = J[:, free]
    sf = scale[free]
    H = (Jf * sf).T @ (Jf * sf) + np.diag(prior[free] * sf ** 2)
    Hinv = np.linalg.pinv(H)
    edf = float(np.trace(Hinv @ ((Jf * sf).T @ (Jf * sf)))) if len(free) else 0.0
    noise = sigma_position
    if noise_from_residuals:
        dof = rows_used - edf
        if rows_used - len(free) < 1 or dof < 1:
            raise ValueError(f"identification: {rows_used} residuals for {len(free)} unknowns; the noise cannot be "
                             f"estimated (measure more poses)")
        noise = float(np.sqrt(r @ r / dof))
        if clusters is not None:
            noise = max(noise, cluster_noise(r, rows_used // max(int(np.count_nonzero(w)), 1), clusters, w, edf))
    cov = np.zeros((layout.n, layout.n))
    cov[np.ix_(free, free)] = Hinv * np.outer(sf, sf) * noise ** 2
    cols = np.flatnonzero(np.linalg.norm(Js0, axis=0) > 0)
    main = np.arange(p + 6)
    if analysis:
        s, V = _singular_values_and_vectors(Js0[:, cols])
        rank, cond, weight = _identifiability(s, V, cols, layout.n, tol_rank)
    else:
        rank, cond, weight = 0, float("nan"), np.zeros(layout.n)
    ident = _result(model, x[main], cov[np.ix_(main, main)], rank, cond, weight[main], cols[cols < p + 6], delta,
                    rms0, float(np.sqrt(r @ r / rows_used)), conv.iterations, "gauss-newton", estimate_base, rule)
    ident.x = x
    ident.free_columns = free
    ident.convergence = conv
    ident.held_judged_at = judged
    ident.held = [model.param_names[j] for j in np.flatnonzero(held[:p])]
    ident.sigma = noise
    ident.effective_unknowns = edf
    if analysis:
        ident.aliases = _aliases(Js0, free[free < p + 6], np.flatnonzero(held[:p]), scale,
                                 tuple(model.param_names) + BASE_NAMES)
        ev = np.linalg.eigvalsh(H) if len(free) else np.zeros(0)
        ident.fit_condition = float(np.sqrt(ev.max() / ev.min())) if ev.size and ev.min() > 0 else float("inf")
        names = _unknown_names(model, layout)
        ident.undetermined = _undetermined(names, free, cov, prior, scale, sigma_position, noise, layout)
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
        ident.compliance_held = [model.joint_names[j] for j, h in zip(np.flatnonzero(layout.cmask), held[layout.c])
                                 if h]
    J_all, _, ident.row_residuals = _stack(model, q, T_meas, x, layout, targets, idx, use_ori, w_ori, gravity)
    ident.row_leverage = _leverage(J_all.reshape(n, -1, layout.n)[:, :3, free] * sf, Hinv, w)
    ident.weights = w
    ident.n_free = int(len(free))
    return ident


def _leverage(Jp, Hinv, w) -> np.ndarray:
    """(n,) leverage of each measurement's position rows ``Jp`` (n, 3, k) (scaled, unweighted) in the fit whose
    inverse normal matrix is ``Hinv`` (k, k): the mean over its 3 rows of ``w j Hinv j^T``, the share of its
    residual the fit absorbs (a fitted row's residual has variance ``(1 - h) sigma^2``); for a row left out
    (``w`` 0) the unweighted figure, by which its residual, a prediction, is larger (``(1 + h) sigma^2``)."""
    n, rows, k = Jp.shape
    flat = Jp.reshape(n * rows, k)
    h = np.einsum("ij,ij->i", flat @ Hinv, flat).reshape(n, rows).sum(axis=1) / 3.0   # one GEMM, then row dots
    return np.where(w > 0, w * h, h)


def _preference(model, layout, cols) -> np.ndarray:
    """Which of equal columns to keep: joint zero offsets and compliances first, then shifts, then turns."""
    pref = np.zeros(layout.n)
    pref[:layout.p] = [1.0 if k == "length" else 0.0 for k in model.param_kinds]
    try:
        pref[model.joint_columns()] = 2.0
    except ModelError:  # a mechanism whose joints are not parameters (the 3-PUPS): no offsets to prefer
        pass
    pref[layout.c] = 2.0
    return pref[cols]


def _unknown_names(model, layout) -> list:
    """Names of the unknowns in the order of ``_Layout``."""
    names = list(model.param_names) + list(BASE_NAMES)
    names += [f"target{k}.{a}" for k in range(layout.nt // 3) for a in "xyz"]
    names += [f"target{k}.r{a}" for k in range(layout.nr // 3) for a in "xyz"]
    names += [f"{j}.compliance" for j, m in zip(model.joint_names, layout.cmask) if m]
    return names


def cluster_noise(r, rows, clusters, weights, edf) -> float:
    """Noise (m) of the residuals ``r`` (n * rows,) seen through the means of their measurements' groups
    ``clusters`` (n,): ``sqrt(sum_g n_g |mean_g|^2 / (G rows - edf))`` over the G groups of the measurements
    with a weight (a random effect per group: sigma^2 + n_g tau^2 in expectation, sigma^2 where the visits
    differ by noise only); 0 when the groups leave no degree of freedom."""
    keep = np.asarray(weights) > 0
    R = np.asarray(r, float).reshape(-1, rows)[keep]
    _, inv, cnt = np.unique(np.asarray(clusters)[keep], return_inverse=True, return_counts=True)
    sums = np.zeros((len(cnt), rows))
    np.add.at(sums, inv, R)
    dof = len(cnt) * rows - edf
    return float(np.sqrt(np.sum(sums ** 2 / cnt[:, None]) / dof)) if dof >= 1 else 0.0


def _undetermined(names, free, cov, prior, scale, sigma_position, noise, layout) -> dict:
    """{name: reason} of the estimated parameters and compliances the data cannot tell: set by the prior (its
    posterior std above ``PRIOR_SHARE`` of the prior's), or a near-copy of another unknown (posterior
    correlation beyond ``NEAR_COPY``)."""
    out = {}
    est = [j for j in free if j < layout.p or layout.c.start <= j < layout.c.stop]
    sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
    for j in est:
        if prior[j] > 0:
            prior_sd = sigma_position / np.sqrt(prior[j]) * noise / sigma_position
            if sd[j] > PRIOR_SHARE * prior_sd:
                out[names[j]] = (f"set by the prior: its std {sd[j]:.3g} is {sd[j] / prior_sd * 100:.0f} % of the "
                                 f"prior's; the data hardly tell it")
    if len(free) > 1:
        C = cov[np.ix_(free, free)]
        d = np.sqrt(np.maximum(np.diag(C), 1e-300))
        R = C / np.outer(d, d)
        pos = {j: i for i, j in enumerate(free)}
        for j in est:
            i = pos[j]
            row = np.abs(R[i])
            row[i] = 0.0
            k = int(np.argmax(row))
            if row[k] > NEAR_COPY and names[j] not in out:
                out[names[j]] = (f"a near-copy of {names[free[k]]} (correlation {R[i, k]:+.3f}): only their "
                                 f"combination is determined")
    return out


def _compliance_scale(gravity, layout) -> np.ndarray:
    """Column scale of each estimated compliance: the one that deflects its joint by 1 mrad (or 1 mm) at
    the largest load of the data."""
    if not layout.nc:
        return np.zeros(0)
    top = np.abs(np.asarray(gravity, float)[:, layout.cmask]).max(axis=0)
    return SCALE_WITHOUT_BUDGET / np.where(top > 0, top, 1.0)


def identify_from_normal_equations(model, JtJ, Jtr, rtr, rows, delta=None, sigma_position=1e-5,
                                   tol_rank=1e-6, rule: DecisionRule = DEFAULT_RULE, clusters=None) -> Identification:
    """One regularised least-squares step from accumulated normal equations (``J^T J``, ``J^T r``,
    ``r^T r`` over ``rows`` residuals, unknowns [dx; base], position rows, at the nominal parameters);
    see ``identify``."""
    p = model.n_params
    prior = _prior(delta, sigma_position, p)
    A = JtJ + np.diag(prior)
    Ainv = np.linalg.pinv(A)  # the least-norm answer where the poses leave unknowns undetermined
    x = Ainv @ Jtr
    cov = Ainv * sigma_position ** 2
    scale = column_scale(delta, p)
    N = JtJ * np.outer(scale, scale)
    cols = np.flatnonzero(np.diag(N) > 0)
    lam, V = np.linalg.eigh(N[np.ix_(cols, cols)])
    rank, cond, weight = _identifiability(np.sqrt(np.maximum(lam, 0.0)), V, cols, p + 6, tol_rank)
    rss_after = max(rtr - 2.0 * x @ Jtr + x @ JtJ @ x, 0.0)
    return _result(model, x, cov, rank, cond, weight, cols, delta, float(np.sqrt(rtr / rows)),
                   float(np.sqrt(rss_after / rows)), 1, "linearised", rule=rule)
