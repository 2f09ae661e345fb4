"""Searches over the joint space: the largest error of a tolerance set (its supremum), the largest
Jacobian column norms (for the eq. 18 ceilings), and the pose-selection index F (eq. 25).

Every search is a seeded Monte Carlo sample followed by multi-start local optimisation (L-BFGS-B
within the joint limits, batched central-difference gradients) from the best samples.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import interrupt


@dataclass
class SearchResult:
    """Largest value found: ``value`` at ``q`` (dof,), the local maxima (m, dof) and their values."""

    value: float
    q: np.ndarray
    maxima_q: np.ndarray
    maxima: np.ndarray
    sample_max: float
    samples: int
    evaluations: int


def _chunked(f, q, chunk=5000):
    out = []
    for a in range(0, len(q), chunk):
        interrupt.check()
        out.append(f(q[a:a + chunk]))
    return np.concatenate(out) if out else np.zeros(0)


def top_samples(f, q, k, upper=None):
    """Indices and values of the ``k`` largest ``f`` over the rows of ``q``.

    With ``upper`` (a cheap upper bound of f), f is evaluated only where the bound can still beat the
    k-th best exact value, in decreasing order of the bound; the result is the same.
    """
    n = len(q)
    k = min(k, n)
    if upper is None:
        v = _chunked(f, q)
        idx = np.argsort(-v, kind="stable")[:k]
        return idx, v[idx], n
    ub = _chunked(upper, q)
    order = np.argsort(-ub, kind="stable")
    vals = np.full(n, -np.inf)
    done, evaluated = 0, 0
    step = max(4 * k, 256)
    while done < n:
        interrupt.check()
        block = order[done:done + step]
        vals[block] = f(q[block])
        evaluated += len(block)
        done += len(block)
        kth = np.sort(vals[np.isfinite(vals)])[-k] if np.isfinite(vals).sum() >= k else -np.inf
        if done < n and ub[order[done]] < kth:
            break
    idx = np.argsort(-vals, kind="stable")[:k]
    return idx, vals[idx], evaluated


def maximize(model, f, n_samples=20000, n_starts=12, seed=0, q_extra=None, upper=None, h=1e-6,
             maxiter=200, tick=None) -> SearchResult:
    """Largest value of ``f`` (vectorised: (m, dof) -> (m,)) over the joint space of ``model``;
    ``tick(done, total)`` after the samples and after each local search."""
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    q = model.sample_joints(n_samples, rng) if n_samples else np.zeros((0, model.dof))
    idx, vals, evals = top_samples(f, q, n_starts, upper)
    starts = q[idx]
    total = 1 + len(starts) + (len(np.atleast_2d(q_extra)) if q_extra is not None and len(q_extra) else 0)
    if tick:
        tick(1, total)
    if q_extra is not None and len(q_extra):
        starts = np.vstack([starts, np.atleast_2d(q_extra)])
    bounds, to_joints, from_joints = model.search_space()
    lo, hi = bounds[:, 0], bounds[:, 1]
    starts_x = starts if from_joints is None else from_joints(starts)
    dof = len(lo)
    eye = np.eye(dof) * h
    counter = {"n": 0}

    def g(x):
        """f at search coordinates x (m, k); unreachable points are -inf."""
        if to_joints is None:
            return f(x)
        qq = to_joints(x)
        ok = ~np.isnan(qq).any(axis=1)
        out = np.full(len(x), -np.inf)
        if ok.any():
            out[ok] = f(qq[ok])
        return out

    def fun(x):
        interrupt.check()
        pts = np.vstack([x, x + eye, x - eye])
        pts = np.clip(pts, lo, hi)
        v = g(pts)
        counter["n"] += len(pts)
        if not np.isfinite(v[0]):
            return 1e300, np.zeros(dof)
        v = np.where(np.isfinite(v), v, v[0])
        step = pts[1:dof + 1] - pts[dof + 1:]
        span = np.einsum("ii->i", step)
        grad = (v[1:dof + 1] - v[dof + 1:]) / np.where(span > 0, span, 1.0)
        return -v[0], -grad

    maxima_q, maxima = [], []
    for x0 in starts_x:
        from scipy.optimize import minimize  # here: importing scipy.optimize takes 1 s (a node's start)
        res = minimize(fun, x0, jac=True, method="L-BFGS-B", bounds=list(zip(lo, hi)),
                       options={"maxiter": maxiter, "ftol": 1e-15, "gtol": 1e-12})
        x = np.clip(res.x, lo, hi)
        value = float(g(x[None])[0])
        if not np.isfinite(value):  # the search left the reachable set: keep its start
            x, value = x0, float(g(np.asarray(x0)[None])[0])
        maxima_q.append(x if to_joints is None else to_joints(x[None])[0])
        maxima.append(value)
        if tick:
            tick(1 + len(maxima), total)
    maxima_q, maxima = np.array(maxima_q), np.array(maxima)
    sample_best = float(vals[0]) if len(vals) else -np.inf
    order = np.argsort(-maxima, kind="stable")
    maxima_q, maxima = maxima_q[order], maxima[order]
    if len(maxima) and maxima[0] >= sample_best:
        best_q, best = maxima_q[0], float(maxima[0])
    else:
        best_q, best = q[idx[0]], sample_best
    return SearchResult(best, best_q, maxima_q, maxima, sample_best, n_samples, evals + counter["n"])


def column_maxima(model, rows="position", n_samples=20000, n_starts=2, seed=0) -> np.ndarray:
    """(p,) largest ``|J_j|`` over the joint space for each parameter (sampled, then refined locally)."""
    rng = np.random.default_rng(seed)
    q = model.sample_joints(n_samples, rng)
    mu = np.concatenate([np.linalg.norm(model.error_jacobian(q[a:a + 5000]).select(rows), axis=1)
                         for a in range(0, len(q), 5000)])
    out = mu.max(axis=0)
    scale = max(float(out.max()), 1e-300)
    for j in np.flatnonzero(out > 1e-12 * scale):
        starts = q[np.argsort(-mu[:, j])[:n_starts]]
        res = maximize(model, lambda x, j=j: np.linalg.norm(model.error_jacobian(x).select(rows)[:, :, j], axis=1),
                       n_samples=0, n_starts=0, q_extra=starts, seed=rng)
        out[j] = max(out[j], res.value)
    out[out <= 1e-12 * scale] = 0.0
    return out


def pose_index(model, q, length_unit_m=1e-3) -> np.ndarray:
    """(n,) Gao et al.'s eq. 25 index ``F = |sum_j J_j|``: the position error (m) when every length
    error is 1 mm (``length_unit_m``) and every angle error 1 rad."""
    J = model.error_jacobian(q).position
    unit = np.array([length_unit_m if k == "length" else 1.0 for k in model.param_kinds])
    return np.linalg.norm(J @ unit, axis=1)


def select_poses(model, count=50, seed=0, n_samples=20000) -> np.ndarray:
    """(count, dof) configurations of locally maximal F (eq. 25), best first."""
    res = maximize(model, lambda x: pose_index(model, x), n_samples=n_samples, n_starts=count, seed=seed)
    return res.maxima_q[:count]
