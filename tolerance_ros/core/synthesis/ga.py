"""The genetic algorithm of Gao et al. (2023), sections 4.2-4.3, with their Table 2 settings.

The paper does not state its operators; this implementation uses common real-coded choices:
binary tournament selection, arithmetic crossover of consecutive parents with probability ``pc``
(one mixing coefficient per pair), uniform-reset mutation of each gene with probability ``pm``, and
one elite. Many independent runs are evolved at once as a batch (same operators, independent
streams), which is how the paper's "Tol = 1000" repeated solves stay affordable.

- ``P1`` minimum cost: penalty fitness (eq. 26) ``cost + k (Delta_E - g)`` when ``Delta_E > [Delta]``,
  with ``Delta_E`` the largest criterion value over the 50 poses of highest index F (eq. 25),
  ``g = [Delta]`` and ``k = 1e6`` per mm.
- ``P2`` optimal precision, the iterative procedure of section 4.3 as printed: round k picks a pose
  by a GA on F (step 2), sets ``I_min`` to the index of the floors (step 3), solves
  ``min |Delta_E(pose) - [Delta]|`` by GA until a solution has ``I <= I_min``, at most ``Tol`` times
  (steps 4-5; since ``I(floors)`` is the largest index any feasible tolerance set can have, the first
  solve is accepted, so ``Tol`` is only a bound), takes the element-wise minimum over rounds (step 6),
  and lets a GA (``P3``) search the joint space for the largest error (step 7); rounds stop when it is
  within the limit (step 8). Reading step 5 instead as "keep the lowest I of Tol solves" drives every
  round to the loosest point of the level set, and on the paper's arm the rounds then never converge
  (P3 still finds 2-5 mm after 40 rounds), unlike the paper's k = 20.
Seeded: the same seed gives the same answer.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from .. import interrupt
from ..errors import worst_case_bound
from .problem import SynthesisProblem
from .search import pose_index


@dataclass(frozen=True)
class GASettings:
    """Population, generations, crossover and mutation probabilities (Table 2)."""

    population: int = 30
    generations: int = 500
    crossover: float = 0.8
    mutation: float = 0.02


TABLE2 = {"P1": GASettings(30, 500, 0.8, 0.02), "P2": GASettings(30, 200, 0.8, 0.02),
          "P3": GASettings(30, 30, 0.8, 0.02)}
PENALTY_PER_M = 1e9  # k of eq. 26: 1e6 per mm


def ga_minimize(fitness, lo, hi, settings: GASettings, rng, runs: int = 1):
    """Minimise ``fitness`` ((runs, pop, d) -> (runs, pop)) within [lo, hi]; ``runs`` independent GAs.

    Returns (best x (runs, d), best f (runs,), best f per generation (generations + 1, runs)).
    """
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    d, pop = lo.size, settings.population
    X = lo + (hi - lo) * rng.random((runs, pop, d))
    F = fitness(X)
    r = np.arange(runs)[:, None]
    history = [F.min(axis=1)]
    for _ in range(settings.generations):
        interrupt.check()
        e = np.argmin(F, axis=1)
        elite_x, elite_f = X[np.arange(runs), e], F[np.arange(runs), e]
        i1 = rng.integers(pop, size=(runs, pop))
        i2 = rng.integers(pop, size=(runs, pop))
        win = np.where(F[r, i1] <= F[r, i2], i1, i2)
        P = X[r, win]
        A, B = P[:, 0::2], P[:, 1::2]
        m = min(A.shape[1], B.shape[1])
        A, B = A[:, :m], B[:, :m]
        cross = rng.random((runs, m, 1)) < settings.crossover
        lam = rng.random((runs, m, 1))
        C1 = np.where(cross, lam * A + (1 - lam) * B, A)
        C2 = np.where(cross, (1 - lam) * A + lam * B, B)
        children = np.concatenate([C1, C2], axis=1)
        if children.shape[1] < pop:
            children = np.concatenate([children, P[:, children.shape[1]:]], axis=1)
        mut = rng.random(children.shape) < settings.mutation
        children = np.where(mut, lo + (hi - lo) * rng.random(children.shape), children)
        children[:, 0] = elite_x
        X = children
        F = fitness(X)
        F[:, 0] = elite_f
        history.append(F.min(axis=1))
    best = np.argmin(F, axis=1)
    return X[np.arange(runs), best], F[np.arange(runs), best], np.array(history)


def _criterion_batch(problem: SynthesisProblem, J, D):
    """(N,) largest criterion value over poses J (m, 3, p) for each tolerance row of D (N, p)."""
    if problem.criterion == "paper":
        m, k, p = J.shape
        E = (np.ascontiguousarray(J).reshape(m * k, p) @ D.T).reshape(m, k, -1)
        return np.sqrt(np.einsum("mkn,mkn->mn", E, E)).max(axis=0)
    if problem.criterion == "rss":
        s = np.einsum("mkp,mkp->mp", J, J)
        return (problem.k_sigma / 3.0) * np.sqrt(D ** 2 @ s.T).max(axis=1)
    return np.array([worst_case_bound(J, d).max() for d in D])


def ga_poses(problem: SynthesisProblem, f, rng, settings: GASettings, runs: int):
    """(runs, dof) joint configurations maximising ``f`` ((m, dof) -> (m,)) by GA (Table 2, P3)."""
    lim = problem.model.joint_limits
    dof = problem.model.dof

    def fit(X):
        return -f(X.reshape(-1, dof)).reshape(X.shape[:2])

    x, fbest, _ = ga_minimize(fit, lim[:, 0], lim[:, 1], settings, rng, runs)
    return x, -fbest


def solve_ga(problem: SynthesisProblem, objective="min-cost", seed=0, n_poses=50, tol_runs=1000, max_rounds=50,
             settings=None, progress=None) -> dict:
    """The paper's GA procedures (module docstring); returns a dict with 'delta' and diagnostics."""
    t0 = time.perf_counter()
    settings = {**TABLE2, **(settings or {})}
    rng = np.random.default_rng(seed)
    model, a = problem.model, problem.active
    lo, hi = problem.floors[a], problem.ceilings[a]
    L = problem.limit
    if problem.orientation_limit is not None:
        raise NotImplementedError("the paper's GA handles a position limit only; use the active-set solver")
    if objective == "min-cost":
        q_sel, _ = ga_poses(problem, lambda q: pose_index(model, q), rng, settings["P3"], n_poses)
        J = model.error_jacobian(q_sel).position[:, :, a]

        def fitness(X):
            D = X.reshape(-1, X.shape[2])
            cost = _cost_batch(problem, D)
            e = _criterion_batch(problem, J, D)
            return (cost + PENALTY_PER_M * np.maximum(e - L, 0.0)).reshape(X.shape[:2])

        x, f, hist = ga_minimize(fitness, lo, hi, settings["P1"], rng, 1)
        if progress:
            progress(1, 1)
        delta = np.zeros(model.n_params)
        delta[a] = x[0]
        return {"delta": delta, "status": "done", "message": f"GA P1 over {n_poses} poses selected by F",
                "history": [{"generation": g, "best_fitness": float(v)} for g, v in enumerate(hist[:, 0])],
                "poses": q_sel, "time_s": time.perf_counter() - t0, "rounds": 1}
    # Optimal precision: section 4.3, step by step.
    kept, rounds, sup, hist = [], 0, np.inf, []
    unit = np.array([1e3 if k == "length" else 1.0 for k in np.array(model.param_kinds)[a]])
    w = problem.weights[a] * unit

    def index_I(X):
        return np.sum(w * np.abs(X - hi), axis=-1)

    for k in range(1, max_rounds + 1):                                   # step 8 loops back to step 2
        rounds = k
        q_k, _ = ga_poses(problem, lambda q: pose_index(model, q), rng, settings["P3"], 1)   # step 2
        Jk = model.error_jacobian(q_k).position[:, :, a]

        def fitness(X):                                                  # eq. 20 at the selected pose
            D = X.reshape(-1, X.shape[2])
            return np.abs(_criterion_batch(problem, Jk, D) - L).reshape(X.shape[:2])

        I_min = index_I(lo)                                              # step 3
        for m in range(1, tol_runs + 1):                                 # steps 4-5, at most Tol solves
            X, _, _ = ga_minimize(fitness, lo, hi, settings["P2"], rng, 1)
            if index_I(X[0]) <= I_min:
                kept.append(X[0])
                break
        d_opt = np.min(np.array(kept), axis=0)                           # step 6
        full = np.zeros(model.n_params)
        full[a] = d_opt

        def err(q):
            return problem.values(model.error_jacobian(q).position, full)

        _, found = ga_poses(problem, err, rng, settings["P3"], 1)        # step 7
        sup = float(found[0])
        hist.append({"round": k, "solves": m, "ga_max_error": sup, "index_I": problem.index_I(full),
                     "cost": problem.cost(full)})
        if progress:
            progress(k, max_rounds)
        if sup <= L:                                                     # step 8
            break
    delta = np.zeros(model.n_params)
    delta[a] = np.min(np.array(kept), axis=0)
    status = "done" if sup <= L else "max_rounds"
    return {"delta": delta, "status": status,
            "message": f"section 4.3 procedure, {rounds} rounds, GA max error {sup * 1e3:.4f} mm",
            "history": hist, "time_s": time.perf_counter() - t0, "rounds": rounds}


def _cost_batch(problem, D):
    a = problem.active
    unit = np.array([1e3 if k == "length" else 1.0 for k in problem.model.param_kinds])[a]
    return np.sum(problem.K[a] * (D * unit) ** (-problem.alpha[a]), axis=1)
