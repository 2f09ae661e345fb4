"""The exact solver: convex programming over an active set of worst poses, grown by adversarial search.

Every criterion is a norm of a linear map of the tolerances at each pose, so the problem is convex
with infinitely many constraints (one per pose). Iterate:
1. solve the convex program with the constraints of the poses collected so far (SLSQP, tolerances
   scaled by their floors, analytic gradients; for 'worst-case' each constraint carries the signs of
   the worst vertex at the pose);
2. look for violations: a seeded check sample of the joint space first, then multi-start local
   maximisation from its worst poses; add the worst violators (with their current worst signs);
3. stop when the search finds no pose above the limit.
The result is then verified independently by ``verify_allocation``.
"""
from __future__ import annotations

import time

import numpy as np

from .. import interrupt
from ..budget import Budget
from ..errors import direction_bounds, paper_bound, per_axis_bound, rss_bound, worst_case_bound
from .problem import COST_UNIT, MODELS, InfeasibleError, SynthesisError, SynthesisProblem
from .search import maximize

MARGIN = 1e-7  # the program is solved against limit * (1 - MARGIN), so a found supremum stays <= limit


class _Constraints:
    """Quadratic constraints ``x' M x <= 1`` in the scaled variables x = delta_active / floors."""

    def __init__(self, p):
        self.M = np.zeros((0, p, p))
        self.keys = []

    def add(self, M, key):
        self.M = np.concatenate([self.M, M[None]], axis=0)
        self.keys.append(key)

    def __len__(self):
        return len(self.keys)


def solve_active_set(problem: SynthesisProblem, objective="min-cost", seed=0, n_check=20000, n_starts=12,
                     max_iter=80, add_per_iter=12, progress=None, log=None) -> dict:
    """Solve the allocation exactly; returns a dict with 'delta' (p,) and diagnostics (see module doc)."""
    if objective not in MODELS:
        raise SynthesisError(f"model: expected one of {MODELS}, got {objective!r}")
    t0 = time.perf_counter()
    model = problem.model
    a = problem.active
    tau, ceil = problem.floors[a], problem.ceilings[a]
    unit = np.array([COST_UNIT[k] for k in model.param_kinds])[a]
    K, alpha, w = problem.K[a], problem.alpha[a], problem.weights[a]
    pa = int(a.sum())
    rng = np.random.default_rng(seed)
    q_check = model.sample_joints(n_check, rng)
    J_check = {rows: model.error_jacobian(q_check).select(rows)[:, :, a] for rows, _ in problem.rows}
    cons = {rows: _Constraints(pa) for rows, _ in problem.rows}
    limits = dict(problem.rows)

    def forms(rows, J, delta_a):
        M = problem.quadratic_forms(J, delta_a)
        target = (limits[rows] * (1.0 - MARGIN)) ** 2
        return M * np.outer(tau, tau) / target

    scale0 = _objective(np.ones(pa), objective, K, alpha, tau, unit, w, 1.0)[0]
    x = np.minimum(ceil / tau, 1e6)
    history = []
    report = _Progress(progress)
    # Feasibility: with every tolerance at its floor the criterion must stay within the limit.
    for r, (rows, lim) in enumerate(problem.rows):
        res = maximize(model, lambda qq, rows=rows: _values(problem, model.error_jacobian(qq).select(rows)[:, :, a], tau),
                       n_samples=min(n_check, 5000), n_starts=n_starts, seed=rng,
                       tick=lambda done, total, r=r: report.feasibility((r + done / total) / len(problem.rows)),
                       upper=(lambda qq, rows=rows: per_axis_bound(model.error_jacobian(qq).select(rows)[:, :, a], tau))
                       if problem.criterion == "worst-case" else None)
        if res.value > lim * (1.0 - MARGIN):
            contrib = _largest_contributors(model, res.q, rows, tau, a)
            scale, unit = (1e3, "mm") if rows == "position" else (1e3, "mrad")
            raise InfeasibleError(
                f"infeasible: with every tolerance at its floor the {problem.criterion} {rows} error reaches "
                f"{res.value * scale:.4g} {unit} (limit {lim * scale:.4g} {unit}) at q = "
                f"{np.round(res.q, 4).tolist()}; the floors of {contrib} contribute most there: lower the floors "
                f"(--floor-length, --floor-angle or --floor NAME=VALUE on the command line, \"floors\" in a "
                f"request) or raise the limit")
    status, message = "max_iter", f"stopped after {max_iter} iterations"
    cheapest = False
    _record_best(problem, tau, "the joint-space search of the feasibility check (every tolerance at its floor)")
    for it in range(max_iter):
        interrupt.check()
        delta_a = x * tau
        added = 0
        worst_ratio = 0.0
        values = {}
        for rows, lim in problem.rows:
            J = J_check[rows]
            v = values[rows] = _values(problem, J, delta_a, top=max(add_per_iter, n_starts), tick=report.nudge)
            ratio = float(v.max() / lim)
            worst_ratio = max(worst_ratio, ratio)
            bad = np.flatnonzero(v > lim * (1.0 - MARGIN) * (1.0 + 1e-9))
            if bad.size:
                pick = bad[np.argsort(-v[bad])[:add_per_iter]]
                Ms = forms(rows, J[pick], delta_a)
                for k, i in enumerate(pick):
                    cons[rows].add(Ms[k], ("check", int(i)))
                added += len(pick)
        if not added:
            # No violation in the check sample: search the joint space from its worst poses.
            for rows, lim in problem.rows:
                res = maximize(model, lambda qq, rows=rows: _values(
                    problem, model.error_jacobian(qq).select(rows)[:, :, a], delta_a), n_samples=0, n_starts=0,
                    q_extra=q_check[np.argsort(-values[rows])[:n_starts]], seed=rng,
                    tick=report.search)
                over = res.maxima > lim * (1.0 - MARGIN) * (1.0 + 1e-9)
                if over.any():
                    Jq = model.error_jacobian(res.maxima_q[over]).select(rows)[:, :, a]
                    Ms = forms(rows, Jq, delta_a)
                    for k in range(len(Ms)):
                        cons[rows].add(Ms[k], ("search", it, k))
                    added += int(over.sum())
        n_cons = sum(len(c) for c in cons.values())
        obj = _objective(x, objective, K, alpha, tau, unit, w, 1.0)[0]
        history.append({"iteration": it, "constraints": n_cons, "objective": float(obj), "check_max_ratio": worst_ratio,
                        "added": added, "elapsed_s": time.perf_counter() - t0})
        if log:
            log(history[-1])
        report.iteration()
        if not added and (objective != "optimal-precision" or cheapest):
            status, message = "converged", "no pose of the joint-space search exceeds the limit"
            _record_best(problem, np.clip(x * tau, tau, ceil), "the joint-space search of the active-set solver "
                                                                "(not the final verification)")
            break
        cheapest = cheapest or not added   # optimal-precision: the cheapest of the most precise, from now on
        x = _solve_program(x, cons, objective, K, alpha, tau, unit, w, scale0, ceil, cheapest)
    report.done()
    delta = np.zeros(model.n_params)
    delta[a] = np.clip(x * tau, tau, ceil)
    return {"delta": delta, "status": status, "message": message, "history": history,
            "iterations": len(history), "constraints": sum(len(c) for c in cons.values()),
            "time_s": time.perf_counter() - t0}


class _Progress:
    """The solver's progress as ``progress(done, TOTAL)``, never backwards: the feasibility search (its local
    searches, one by one) up to FEASIBILITY; then, as the number of iterations is not known in advance,
    ``u / (u + HALF)`` of the way on to LAST after ``u`` units of work (an iteration ITERATION units, a
    block of exact worst cases or a local search one); the end is 100 %."""

    FEASIBILITY, LAST, TOTAL, HALF, ITERATION = 0.2, 0.95, 10 ** 6, 40.0, 10.0

    def __init__(self, progress):
        self.progress, self.fraction, self.units = progress, 0.0, 0.0

    def _emit(self, fraction):
        self.fraction = max(self.fraction, min(fraction, 1.0))
        if self.progress:
            self.progress(int(self.fraction * self.TOTAL), self.TOTAL)

    def _work(self, units):
        self.units += units
        self._emit(self.FEASIBILITY + (self.LAST - self.FEASIBILITY) * self.units / (self.units + self.HALF))

    def feasibility(self, share):
        self._emit(self.FEASIBILITY * share)

    def iteration(self):
        self._work(self.ITERATION)

    def nudge(self):
        self._work(1.0)

    def search(self, done, total):
        self._work(1.0)

    def done(self):
        self._emit(1.0)


def _record_best(problem, delta_active, verified_by):
    """Keep a verified tolerance set (active parameters) as the best result so far, for a timeout."""
    delta = np.zeros(problem.model.n_params)
    delta[problem.active] = delta_active
    budget = Budget.from_vector(problem.model, delta, free=~problem.active, limit_position=problem.limit,
                                limit_orientation=problem.orientation_limit, criterion=problem.criterion,
                                source="best verified result before the allocation stopped")
    interrupt.record_best({"budget": budget.to_dict(), "cost_index": problem.cost(delta), "verified_by": verified_by})


def _values(problem, J, delta_a, top=0, tick=None):
    """Criterion values with J restricted to the active columns. With ``top`` (for the worst case) only the
    values that can rank among the ``top`` largest are computed exactly, the others bounded from below:
    the ``top`` largest of the result are the exact ``top`` largest, whatever the bounds (``_top_exact``)."""
    c = problem.criterion
    if c == "paper":
        return paper_bound(J, delta_a)
    if c == "rss":
        return rss_bound(J, delta_a, problem.k_sigma)
    if not top:
        return worst_case_bound(J, delta_a)
    return _top_exact(J, delta_a, top, tick)


BLOCK = 512  # poses a step of ``_top_exact``


def _top_exact(J, delta_a, top, tick=None):
    """(n,) worst cases, exact where they can rank among the ``top`` largest, lower bounds elsewhere.

    In decreasing order of the per-axis upper bound, block by block: the direction bounds of the block
    (``errors.direction_bounds``, about 3 % apart), until the per-axis bound falls below the ``top``-th
    largest lower bound so far; then the exact worst case of the poses whose upper bound still reaches the
    ``top``-th largest value (in decreasing order of that bound, the threshold rising as exact values come
    in). Every value is at most the exact one, so a pose left out lies below the ``top`` exact ones: they
    are the largest of the result, and a pose above a limit is among them or below them. ``tick()``
    after each block."""
    n = len(J)
    upper = per_axis_bound(J, delta_a)
    out = rss_bound(J, delta_a)  # a lower bound where nothing better is computed
    order = np.argsort(-upper, kind="stable")
    top = min(top, n)

    def kth(values):
        return np.partition(values, -top)[-top] if len(values) >= top else -np.inf

    seen = 0
    while seen < n:
        blk = order[seen:seen + BLOCK]
        if upper[blk[0]] * (1.0 + SLACK) < kth(out[order[:seen]]):
            break
        lo, hi = direction_bounds(J[blk], delta_a)
        out[blk] = np.maximum(out[blk], lo)
        upper[blk] = np.minimum(upper[blk], hi)
        seen += len(blk)
    threshold = kth(out[order[:seen]])
    cand = order[:seen][upper[order[:seen]] * (1.0 + SLACK) >= threshold]
    cand = cand[np.argsort(-upper[cand], kind="stable")]
    for start in range(0, len(cand), 256):
        blk = cand[start:start + 256]
        if upper[blk[0]] * (1.0 + SLACK) < threshold:
            break
        out[blk] = worst_case_bound(J[blk], delta_a)
        threshold = kth(out[order[:seen]])
        if tick:
            tick()
    return out


SLACK = 1e-6  # relative: the bounds are compared with a margin above rounding (and the exact value's 2e-9)


def _objective(x, objective, K, alpha, tau, unit, w, scale):
    if objective == "min-cost":
        base = K * (tau * unit) ** (-alpha)
        f = np.sum(base * x ** (-alpha))
        g = -alpha * base * x ** (-alpha - 1.0)
    else:
        f = -np.sum(w * tau * unit * x)
        g = -w * tau * unit
    return f / scale, g / scale


def _solve_program(x0, cons, objective, K, alpha, tau, unit, w, scale, ceil, cheapest=False):
    """The convex program on the constraints so far, from x0 (scaled tolerances); with ``cheapest`` (optimal
    precision) the cheapest of the sets within ``TIE`` of its best precision."""
    Ms = np.concatenate([c.M for c in cons.values()], axis=0)
    m, p = Ms.shape[:2]
    flat = Ms.reshape(m * p, p)  # one matrix product per call (an einsum over three operands is 3-5x slower)
    hi = np.minimum(ceil / tau, 1e6)
    bounds = list(zip(np.ones_like(hi), hi))
    if objective == "optimal-precision":
        scale = abs(_objective(hi, objective, K, alpha, tau, unit, w, 1.0)[0]) or 1.0

    def fun(x):
        interrupt.check()
        return _objective(x, objective, K, alpha, tau, unit, w, scale)

    def cfun(x):
        return 1.0 - (flat @ x).reshape(m, p) @ x

    def cjac(x):
        return -2.0 * (flat @ x).reshape(m, p)

    x = _minimize(fun, cfun, cjac, x0, hi, bounds)
    if objective == "optimal-precision" and cheapest:
        # The precision objective is linear: its optimum is often a face, not a point, and which point of it
        # SLSQP ends on would depend on rounding. Among the equally precise sets, the cheapest (the cost is
        # strictly convex): one answer, whatever the arithmetic.
        value = -_objective(x, objective, K, alpha, tau, unit, w, scale)[0]
        cost_scale = _objective(np.ones_like(hi), "min-cost", K, alpha, tau, unit, w, 1.0)[0]
        lin = w * tau * unit / scale

        def cost(x):
            interrupt.check()
            return _objective(x, "min-cost", K, alpha, tau, unit, w, cost_scale)

        def cfun2(x):
            return np.r_[cfun(x), (lin @ x - value * (1.0 - TIE)) / max(value, 1e-300)]

        def cjac2(x):
            return np.vstack([cjac(x), lin / max(value, 1e-300)])
        x = _minimize(cost, cfun2, cjac2, x, hi, bounds, feasible=cfun)
    return x


TIE = 1e-9  # optimal-precision: the sets within this share of the best precision are equals; the cheapest wins


def _minimize(fun, cfun, cjac, x0, hi, bounds, feasible=None):
    """SLSQP from x0 (made feasible first) under ``cfun >= 0``; the answer pulled back along the ray to the
    floors until ``feasible`` (default ``cfun``) holds."""
    feasible = feasible or cfun
    x_start = np.clip(x0, 1.0, hi)
    # Start from a feasible point: shrink towards the floors until every constraint holds.
    for _ in range(60):
        if np.all(cfun(x_start) >= 0):
            break
        x_start = 1.0 + (x_start - 1.0) * 0.7
    else:
        x_start = np.ones_like(hi)
    from scipy.optimize import minimize  # here: importing scipy.optimize takes 1 s (a node's start)
    res = minimize(fun, x_start, jac=True, method="SLSQP", bounds=bounds,
                   constraints=[{"type": "ineq", "fun": cfun, "jac": cjac}],
                   options={"maxiter": 500, "ftol": 1e-14})
    x = np.clip(res.x, 1.0, hi)
    # SLSQP may end a hair outside; pull back along the ray to the floors until feasible.
    viol = feasible(x)
    if np.any(viol < 0):
        lo_t, hi_t = 0.0, 1.0
        for _ in range(60):
            mid = (lo_t + hi_t) / 2
            if np.all(feasible(1.0 + (x - 1.0) * mid) >= 0):
                lo_t = mid
            else:
                hi_t = mid
        x = 1.0 + (x - 1.0) * lo_t
    return x


def _largest_contributors(model, q, rows, tau, a, count=4):
    J = model.error_jacobian(q[None]).select(rows)[0][:, a]
    contrib = np.linalg.norm(J, axis=0) * tau
    names = np.array(model.param_names)[a]
    return ", ".join(names[np.argsort(-contrib)[:count]])
