"""Precision synthesis: allocate tolerances that keep the end-effector error within a design limit.

``allocate(model, limit, ...)`` sets up the problem (``build_problem``), solves it with the paper's
GA (``solver='ga'``) or the exact active-set method (``solver='active-set'``), and verifies the
result independently (``verify_allocation``): searched supremum under every criterion, Monte Carlo
verification (Table 4 style), the paper's sign control of correlated pairs (Table 5 style), ISO 286
grades of sized lengths, and warnings. Returns an ``Allocation`` (scipy-style: ``success``,
``status``, ``message``, the answer and diagnostics).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from .. import analysis, threads
from ..budget import Budget
from ..iso286 import coarsest_grade
from .active_set import solve_active_set
from .ga import TABLE2, solve_ga
from ..errors import DEFAULT_LIMIT_CRITERION, LIMIT_CRITERIA
from .problem import MODELS, InfeasibleError, SynthesisError, SynthesisProblem, build_problem
from .search import maximize, select_poses

SOLVERS = ("active-set", "ga")
PHYSICAL = {"length": (1e-9, 1.0), "angle": (1e-9, np.pi)}  # tolerances that make physical sense, m and rad
MC_DISTRIBUTION = {"paper": "fixed", "worst-case": "extreme", "rss": "normal"}

__all__ = ["DEFAULT_LIMIT_CRITERION", "Allocation", "InfeasibleError", "MODELS", "SOLVERS", "SynthesisError",
           "SynthesisProblem", "TABLE2", "allocate", "build_problem", "select_poses", "supremum", "verify_allocation"]


@dataclass
class Allocation:
    """Result of an allocation (SI; ``table`` and reports convert for humans)."""

    delta: np.ndarray
    problem: SynthesisProblem
    model_type: str
    solver: str
    success: bool
    status: str
    message: str
    time_s: float
    cost: float
    index_I: float
    verification: dict
    history: list = field(default_factory=list)
    warnings: list = field(default_factory=list)
    seed: int = 0
    mc_position: np.ndarray | None = None  # (n_mc,) position errors of the Monte Carlo verification, m

    @property
    def names(self):
        return self.problem.model.param_names

    def position_suprema(self) -> dict:
        """{criterion: searched supremum of the position error, m} of the verification ({} without one)."""
        return {c: v["position"]["value"] for c, v in self.verification.get("supremum", {}).items()}

    def budget(self, source=None) -> Budget:
        """The allocation as a tolerance budget (free parameters listed as such)."""
        p = self.problem
        return Budget.from_vector(p.model, self.delta, free=~p.active, limit_position=p.limit,
                                  limit_orientation=p.orientation_limit, criterion=p.criterion,
                                  source=source or f"tolerance-ros allocate ({self.model_type}, {self.solver})",
                                  meta={"success": self.success, "status": self.status, "message": self.message,
                                        "cost_index": self.cost, "index_I_m": self.index_I, "seed": self.seed,
                                        "searched_supremum_m": self.position_suprema(),
                                        "warnings": list(self.warnings)})

    def table(self) -> list:
        """Rows like the paper's Table 3: name, unit, floor, ceiling, tolerance, ISO grade, flags."""
        p = self.problem
        rows = []
        for j, n in enumerate(p.model.param_names):
            free = not p.active[j]
            grade = None
            if p.model.param_kinds[j] == "length" and not free:
                size = abs(float(p.model.nominal[j])) * 1e3
                if 0 < size <= 3150:
                    grade = coarsest_grade(self.delta[j], size)
            rows.append({"name": n, "unit": p.model.param_units[j], "floor": float(p.floors[j]),
                         "ceiling": None if free else float(p.ceilings[j]),
                         "tolerance": None if free else float(self.delta[j]), "free": free,
                         "at_floor": bool(not free and self.delta[j] <= p.floors[j] * (1 + 1e-6)),
                         "at_ceiling": bool(not free and self.delta[j] >= p.ceilings[j] * (1 - 1e-6)),
                         "iso_grade": grade,
                         "nominal_size_mm": abs(float(p.model.nominal[j])) * 1e3
                         if p.model.param_kinds[j] == "length" else None})
        return rows

    def shortfalls(self) -> list:
        """Why the allocation does not meet its target, in words ([] when it does)."""
        out = [] if self.status in ("converged", "done") else [f"the solver stopped: {self.message}"]
        p = self.problem
        for j in np.flatnonzero(p.active):
            lo, hi = PHYSICAL[p.model.param_kinds[j]]
            if not lo <= self.delta[j] <= hi:
                out.append(f"the tolerance of {p.model.param_names[j]}, {self.delta[j]:.3g} {p.model.param_units[j]}, "
                           f"is outside the physical range [{lo:g}, {hi:g}] {p.model.param_units[j]}")
        for rows, s in self.verification.get("supremum", {}).get(self.problem.criterion, {}).items():
            if not s["pass"]:
                unit = "mm" if rows == "position" else "mrad"
                out.append(f"the {rows} error reaches {s['value'] * 1e3:.4f} {unit} under its own "
                           f"'{self.problem.criterion}' criterion, over the limit {s['limit'] * 1e3:g} {unit}")
        return out

    def limit_check(self) -> dict:
        """The figures every allocation is judged by beside its position limit, whatever its criterion (m):
        searched worst case over every error sign, RSS, paper, and the Monte Carlo pass rate."""
        ver = self.verification
        if not ver:
            return {}
        sup = self.position_suprema()
        mc = ver["monte_carlo"]
        return {"limit_m": self.problem.limit, "criterion": self.problem.criterion,
                "worst_case_m": sup["worst-case"], "rss_m": sup["rss"], "paper_m": sup["paper"],
                "worst_case_within": bool(sup["worst-case"] <= self.problem.limit),
                "monte_carlo_pass_rate": mc["position_m"]["pass_rate"], "monte_carlo_distribution": mc["distribution"],
                "monte_carlo_poses": mc["poses"]}

    def to_dict(self) -> dict:
        return {"ok": self.success, "shortfalls": self.shortfalls(), "limit_check": self.limit_check(),
                "status": self.status, "message": self.message, "model": self.model_type, "solver": self.solver,
                "seed": self.seed, "time_s": self.time_s, "problem": self.problem.to_dict(), "cost_index": self.cost,
                "index_I_m": self.index_I, "parameters": self.table(),
                "verification": self.verification, "warnings": self.warnings, "history": self.history}


SOLVE_SHARE = 0.8  # of an allocation's progress: the solve; the rest is the verification
SEARCH_SHARE = 0.9  # of a verification's progress: the supremum searches; the rest is the Monte Carlo


def supremum(problem: SynthesisProblem, delta, criterion=None, rows="position", n_samples=20000, n_starts=12,
             seed=0, tick=None) -> dict:
    """Largest error of ``delta`` over the joint space under a criterion (search: sample + local);
    ``tick(done, total)`` as the search goes (``search.maximize``)."""
    model = problem.model
    crit = criterion or problem.criterion
    d = np.where(problem.active, delta, 0.0)
    res = maximize(model, lambda q: problem.values(model.error_jacobian(q).select(rows), d, crit),
                   n_samples=n_samples, n_starts=n_starts, seed=seed,
                   upper=(lambda q: problem.upper(model.error_jacobian(q).select(rows), d, crit))
                   if crit == "worst-case" else None, tick=tick)
    return {"value": res.value, "q": res.q, "sample_max": res.sample_max, "samples": res.samples,
            "starts": len(res.maxima), "evaluations": res.evaluations}


def verify_allocation(problem: SynthesisProblem, delta, n_mc=10000, seed=0, n_samples=20000, n_starts=12,
                      correlation_threshold=0.7, distribution=None, progress=None) -> dict:
    """Independent checks of a tolerance set: supremum under every criterion, Monte Carlo, sign control.

    The Monte Carlo is ``analysis.monte_carlo(n=n_mc, seed=seed)``, poses and errors: what ``tolerance-ros verify
    --samples n_mc --seed seed --errors <distribution>`` computes for the same tolerances.
    """
    return _verify(problem, delta, n_mc, seed, n_samples, n_starts, correlation_threshold, distribution, progress)[0]


def _verify(problem, delta, n_mc, seed, n_samples=20000, n_starts=12, correlation_threshold=0.7, distribution=None,
            progress=None):
    """(verification dict, the Monte Carlo Verification with its per-pose errors); ``progress(share)`` with
    the share of the searches done."""
    model = problem.model
    d = np.where(problem.active, delta, 0.0)
    sup = {}
    searches = len(LIMIT_CRITERIA) * len(problem.rows)
    for c, crit in enumerate(LIMIT_CRITERIA):
        sup[crit] = {}
        for r, (rows, lim) in enumerate(problem.rows):
            k = c * len(problem.rows) + r
            tick = None if progress is None else \
                (lambda done, total, k=k: progress(SEARCH_SHARE * (k + done / total) / searches))
            s = supremum(problem, d, crit, rows, n_samples, n_starts, seed, tick)
            s["limit"] = lim
            s["pass"] = bool(s["value"] <= lim)
            sup[crit][rows] = s
    dist = distribution or MC_DISTRIBUTION[problem.criterion]
    searched = SEARCH_SHARE if progress is not None else 1.0
    mc = analysis.monte_carlo(model, d, n=n_mc, distribution=dist, seed=seed, limit_position=problem.limit,
                              limit_orientation=problem.orientation_limit, chunk=max(1000, n_mc // 10),
                              progress=None if progress is None else
                              (lambda done, total: progress(searched + (1 - searched) * done / total)))
    q = mc.q
    J = model.error_jacobian(model.sample_joints(2000, np.random.default_rng(seed + 3))).position
    pairs = analysis.correlated_pairs(analysis.correlation(J), model.param_names, correlation_threshold)
    signs = analysis.sign_control(model.param_names, pairs)
    ctl = analysis.monte_carlo(model, d, distribution="fixed", signs=signs, q=q, limit_position=problem.limit)
    return {"supremum": sup,
            "monte_carlo": {"distribution": dist, "poses": n_mc, "seed": seed, "position_m": mc.summary["position"],
                            "orientation_rad": mc.summary["orientation"]},
            "sign_control": {"pairs": [{"parameters": [a, b], "rho": r} for a, b, r in pairs],
                             "negative": [n for n, s in zip(model.param_names, signs) if s < 0],
                             "position_m": ctl.summary["position"]}}, mc


def _warnings(problem, delta, ver) -> list:
    """Every verification figure over its limit, said in words (mm, mrad)."""
    out = []
    sup = ver["supremum"]
    lim = problem.limit
    paper, worst = sup["paper"]["position"]["value"], sup["worst-case"]["position"]["value"]
    if paper <= lim < worst:
        out.append(f"meets the limit only because errors of opposite effect are assumed to cancel: with "
                   f"every error at +delta the largest error is {paper * 1e3:.4f} mm, but over all error signs it "
                   f"reaches {worst * 1e3:.4f} mm (limit {lim * 1e3:g} mm)")
    for crit, rows in sup.items():
        for what, s in rows.items():
            explained = crit == "worst-case" and what == "position" and paper <= lim < worst
            if not s["pass"] and not explained:
                scale, unit = 1e3, "mm" if what == "position" else "mrad"
                out.append(f"the searched supremum of the {what} error under the '{crit}' criterion, "
                           f"{s['value'] * scale:.4f} {unit}, exceeds the limit {s['limit'] * scale:g} {unit}"
                           + (" (the allocation's own criterion)" if crit == problem.criterion else ""))
    mc = ver["monte_carlo"]
    for what, key, scale, unit in (("position", "position_m", 1e3, "mm"), ("orientation", "orientation_rad", 1e3,
                                                                             "mrad")):
        s = mc[key]
        if s.get("pass_rate", 1.0) < 1.0:
            out.append(f"{s['failures']} of {s['n']} Monte Carlo poses ({mc['distribution']} errors) exceed the "
                       f"{what} limit {s['limit'] * scale:g} {unit}; the largest error is {s['max'] * scale:.4f} {unit}")
    ctl = ver["sign_control"]["position_m"]
    if ctl.get("pass_rate", 1.0) < 1.0:
        out.append(f"with the paper's sign control of correlated pairs, {ctl['failures']} of {ctl['n']} poses exceed "
                   f"the limit {lim * 1e3:g} mm; the largest error is {ctl['max'] * 1e3:.4f} mm")
    return out


def allocate(model, limit, model_type="min-cost", solver="active-set", criterion=DEFAULT_LIMIT_CRITERION,
             orientation_limit=None, floors=None, k_sigma=3.0, seed=0, n_mc=10000, problem=None, progress=None,
             solver_options=None, verify=True) -> Allocation:
    """Allocate tolerances (see the module docstring). ``limit`` in m, ``orientation_limit`` in rad; the
    default criterion, the worst case over every error sign, guarantees the limit (the paper's does not);
    ``solver_options`` go to the solver (``solve_active_set``: n_check, n_starts, ...; ``solve_ga``). The
    numerical libraries run on one thread meanwhile: their pools only slow these small problems down,
    by a factor of 5 on a loaded machine."""
    with threads.limited(1):
        return _allocate(model, limit, model_type, solver, criterion, orientation_limit, floors, k_sigma, seed, n_mc,
                         problem, progress, solver_options, verify)


def _allocate(model, limit, model_type, solver, criterion, orientation_limit, floors, k_sigma, seed, n_mc, problem,
              progress, solver_options, verify) -> Allocation:
    if model_type not in MODELS:
        raise SynthesisError(f"model: expected one of {MODELS}, got {model_type!r}")
    if solver not in SOLVERS:
        raise SynthesisError(f"solver: expected one of {SOLVERS}, got {solver!r}")
    t0 = time.perf_counter()
    if progress is not None:
        progress(0, 10 ** 6)  # the job has started: the ceilings' search below takes a few seconds
    if problem is None:
        problem = build_problem(model, limit, orientation_limit, criterion, floors, k_sigma, seed=seed)
    # progress in millionths: the solve up to SOLVE_SHARE (all of it without the verification), then the
    # verification's searches
    share, total = (SOLVE_SHARE if verify else 1.0), 10 ** 6
    solving = None if progress is None else (lambda done, of: progress(int(total * share * done / of), total))
    checking = None if progress is None else (lambda f: progress(int(total * (share + (1 - share) * f)), total))
    if solver == "active-set":
        raw = solve_active_set(problem, model_type, seed=seed, progress=solving, **(solver_options or {}))
    else:
        raw = solve_ga(problem, model_type, seed=seed, progress=solving, **(solver_options or {}))
    delta = raw["delta"]
    solve_time = time.perf_counter() - t0
    ver, mc = _verify(problem, delta, n_mc, seed, progress=checking) if verify else ({}, None)
    if progress is not None:
        progress(total, total)
    warns = _warnings(problem, delta, ver) if verify else []
    res = Allocation(delta, problem, model_type, solver, False, raw["status"], raw["message"], solve_time,
                     problem.cost(delta), problem.index_I(delta), ver, raw.get("history", []), warns, seed,
                     None if mc is None else mc.position)
    res.success = not res.shortfalls()
    return res
