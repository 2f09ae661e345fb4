"""Error bounds of the end effector for a tolerance vector, batched over poses.

Every function takes ``J``, an ``(n, k, p)`` block of parameter-error Jacobian rows (``k = 3``: the
position rows in m per unit, or the orientation rows in rad per unit) and tolerances ``delta`` ``(p,)``
(m or rad, each parameter within ``+-delta_j``), and returns ``(n,)`` bounds in the unit of the rows.

- ``paper_bound``: Gao et al.'s extreme-value criterion ``|J delta|``, all errors at ``+delta_j``
  (or at a given sign vector). It is not a bound over sign choices: errors of opposite effect cancel.
- ``worst_case_bound``: the exact worst case over every sign combination, ``max_s |J (s * delta)|``, the
  maximum-norm point of the zonotope spanned by the generators ``g_j = J_j delta_j``.
- ``per_axis_bound``: ``sqrt(sum_k (sum_j |J_kj| delta_j)^2)``, a cheap upper bound of the worst case.
- ``direction_bounds``: a lower and an upper bound of the worst case within a few per cent of each other,
  from the zonotope's support function in ``DIRECTIONS`` directions (a pruning aid of the exact one).
- ``rss_bound``: the statistical root-sum-square ``(k/3) sqrt(sum_j |J_j|^2 delta_j^2)`` (Gao et al.
  eq. 10 for the default ``k = 3``, ``delta_j = 3 sigma_j``). For independent normal errors with
  ``sigma_j = delta_j / 3`` it is a guaranteed quantile: ``P(|dP| <= bound) >= 2 Phi(k) - 1`` for any
  Jacobian whenever ``k >= 1.24``, because ``|dP|^2`` is a weighted sum of chi-square variables whose
  tail beyond 1.54 times its mean is largest when one weight carries everything (Szekely and
  Bakirov, 2003), i.e. when ``|dP|`` is a one-dimensional normal.

Always ``rss <= worst case <= per-axis`` and ``paper <= worst case``.
"""
from __future__ import annotations

import numpy as np

from . import interrupt
from .models import kernels as compiled

_PERTURB = 1e-9
WORST_CASE_CHUNK = 32
"""Poses per chunk of the numpy worst case: its (chunk, pairs, generators) arrays stay in the cache."""


def _check(J, delta):
    J = np.asarray(J, dtype=float)
    delta = np.asarray(delta, dtype=float)
    if J.ndim != 3:
        raise ValueError(f"J: expected shape (n, k, p), got {J.shape}")
    if delta.shape != (J.shape[2],):
        raise ValueError(f"delta: expected shape ({J.shape[2]},), got {delta.shape}")
    if not (np.isfinite(delta).all() and (delta >= 0).all()):
        raise ValueError("delta: tolerances must be finite and >= 0")
    return J, delta


def error_norms(J, dx) -> np.ndarray:
    """(n,) ``|J dx|`` for parameter errors ``dx`` of shape (p,) or (n, p)."""
    J = np.asarray(J, dtype=float)
    dx = np.asarray(dx, dtype=float)
    e = J @ dx if dx.ndim == 1 else np.einsum("nkp,np->nk", J, dx)
    return np.sqrt(np.einsum("nk,nk->n", e, e))


def paper_bound(J, delta, signs=None) -> np.ndarray:
    """(n,) ``|J (s * delta)|`` with all signs +1 unless ``signs`` ((p,) or (n, p)) is given."""
    J, delta = _check(J, delta)
    dx = delta if signs is None else np.asarray(signs, dtype=float) * delta
    return error_norms(J, dx)


def per_axis_bound(J, delta) -> np.ndarray:
    """(n,) upper bound ``sqrt(sum_k (sum_j |J_kj| delta_j)^2)``."""
    J, delta = _check(J, delta)
    s = np.abs(J) @ delta
    return np.sqrt(np.einsum("nk,nk->n", s, s))


DIRECTIONS = 64
"""Directions (a hemisphere's; with their opposites the whole sphere) of ``direction_bounds``."""


def _directions(count=DIRECTIONS):
    """(count, 3) unit vectors over a hemisphere (a Fibonacci lattice) and the cosine of their covering angle:
    every unit vector lies within that angle of one of them or of its opposite. The angle is the largest
    circumradius of the spherical Delaunay triangles of the vectors and their opposites, read off the
    facets of their convex hull (each facet's plane lies at that cosine from the centre); computed once."""
    cached = _DIRECTIONS.get(count)
    if cached is None:
        from scipy.spatial import ConvexHull
        k = np.arange(count) + 0.5
        z = k / count
        r = np.sqrt(1.0 - z * z)
        phi = np.pi * (1.0 + 5.0 ** 0.5) * k
        U = np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)
        cos_cover = float((-ConvexHull(np.vstack([U, -U])).equations[:, 3]).min())
        cached = _DIRECTIONS[count] = (U, cos_cover)
    return cached


_DIRECTIONS = {}


def direction_bounds(J, delta, count=DIRECTIONS):
    """((n,) lower, (n,) upper) bounds of ``worst_case_bound`` for 3 rows. The worst case is the largest norm
    of the zonotope, i.e. the largest of its support function ``h(u) = sum_j |u . J_j| delta_j`` over unit
    vectors u. ``max h`` over ``count`` directions is a lower bound (the vertex of signs ``sign(u . J_j)``
    reaches it), and that maximum divided by the cosine of the directions' covering angle an upper bound
    (the largest vertex lies within that angle of a direction u, so ``h(u)`` is at least its norm times the
    cosine): about 3 % apart with the default 64 directions, for O(count p) work a pose against the exact
    O(p^3)."""
    J, delta = _check(J, delta)
    if J.shape[1] != 3:
        raise ValueError("direction_bounds: expected 3 rows (position or orientation rows)")
    U, cos_cover = _directions(count)
    lower = np.abs(np.matmul(U, J * delta)).sum(axis=2).max(axis=1)
    return lower, lower / cos_cover


def rss_bound(J, delta, k_sigma: float = 3.0) -> np.ndarray:
    """(n,) statistical bound ``(k_sigma / 3) sqrt(sum_j |J_j|^2 delta_j^2)`` (eq. 10 for k_sigma = 3)."""
    J, delta = _check(J, delta)
    return (k_sigma / 3.0) * np.sqrt(np.einsum("nkp,nkp,p->n", J, J, delta ** 2))


def k_for_confidence(confidence: float) -> float:
    """Coverage factor ``k`` with ``2 Phi(k) - 1 = confidence`` (0.9973 -> 3.0); needs confidence >= 0.785."""
    from scipy.stats import norm
    if not 0.785 <= confidence < 1.0:
        raise ValueError(f"confidence: expected a value in [0.785, 1), got {confidence}")
    return float(norm.ppf(0.5 + confidence / 2.0))


def confidence_for_k(k_sigma: float) -> float:
    """Confidence ``2 Phi(k) - 1`` guaranteed by the RSS bound with coverage factor ``k``."""
    from scipy.stats import norm
    return float(2.0 * norm.cdf(k_sigma) - 1.0)


_NOISE = {}  # generators m -> (rows, 3, m) draws of default_rng(12345).standard_normal, grown on demand
_NOISE_CAP = 1 << 22  # values kept per generator count (32 MiB); a larger block draws its own


def _perturbation(n, m):
    """(n, 3, m) standard normals: the first n * 3 * m draws of ``default_rng(12345)``, the same for every call
    (a block's perturbation does not depend on its length or on the calls before it); kept between calls."""
    table = _NOISE.get(m)
    if table is None or len(table) < n:
        rows = n if n * 3 * m > _NOISE_CAP else max(n, min(4096, _NOISE_CAP // (3 * m)))
        table = np.random.default_rng(12345).standard_normal((rows, 3, m))
        table.flags.writeable = False
        if rows * 3 * m <= _NOISE_CAP:
            _NOISE[m] = table
    return table[:n]


def worst_case_bound(J, delta, return_signs: bool = False, max_chunk_bytes: float = 64e6, backend: str = "numba"):
    """(n,) exact ``max over s in {-1,+1}^p of |J (s * delta)|``; optionally the maximising signs (n, p).

    The maximum of a norm over a zonotope sits at a vertex, and each vertex is ``sum_j s_j g_j`` for the
    sign vector of a cell of the arrangement of the planes ``u . g_j = 0``. Every cell has a corner on a
    line ``g_i x g_j``; at that corner the signs of all other generators are fixed and the four
    choices of ``(s_i, s_j)`` enumerate the cells around it. Degenerate layouts (parallel or coplanar
    generators, which robot Jacobians have by construction) are resolved by a 1e-9 relative
    perturbation used only to choose the candidate sign vectors; every candidate is evaluated on the
    unperturbed generators, so the result is an attained value and is exact in generic position
    (within 2e-9 relative otherwise). O(n p^3) work: ``backend`` 'numba' runs the compiled kernel
    ``zonotope_kernel.zonotope_max`` (10x faster) when the kernels are available, 'numpy' (the reference, and
    the fallback) the batched numpy code below.
    """
    J, delta = _check(J, delta)
    n, k, p = J.shape
    if k > 3:
        raise ValueError("worst_case_bound: rows must be at most 3 (position or orientation rows)")
    G = J * delta
    if k < 3:
        G = np.concatenate([G, np.zeros((n, 3 - k, p))], axis=1)
    active = np.flatnonzero(np.any(G != 0.0, axis=(0, 1)))
    out = np.zeros(n)
    signs = np.ones((n, p))
    m = active.size
    if m == 0:
        return (out, signs) if return_signs else out
    Ga = G[:, :, active]
    if m == 1:
        out[:] = np.linalg.norm(Ga[:, :, 0], axis=1)
        return (out, signs) if return_signs else out
    scale = np.abs(Ga).max(axis=(1, 2), keepdims=True)
    Gp = Ga + _PERTURB * np.where(scale > 0, scale, 1.0) * _perturbation(n, m)
    kernels = compiled.get("zonotope") if backend == "numba" else None
    best_s = np.ones((n, m))
    if kernels is not None:
        for a in range(0, n, 256):
            interrupt.check()
            b = min(n, a + 256)
            kernels.zonotope_max(np.ascontiguousarray(Ga[a:b]), np.ascontiguousarray(Gp[a:b]), out[a:b],
                                 best_s[a:b], return_signs)
    else:
        _worst_case_numpy(Ga, Gp, out, best_s, return_signs, max_chunk_bytes)
    if return_signs:
        signs[:, active] = best_s
        return out, signs
    return out


def _worst_case_numpy(Ga, Gp, out, best_s, return_signs, max_chunk_bytes):
    """The numpy reference of ``worst_case_bound`` into ``out`` (n,) and, with ``return_signs``, ``best_s``
    (n, m): the compiled kernel's candidates, in chunks of poses small enough for the cache. For each line ``v = gp_i x gp_j`` the other generators' signs are
    ``sign(v . gp_l)``; of the four corners ``z + a g_i + b g_j`` the largest norm is chosen from
    ``|z|^2 + |g_i|^2 + |g_j|^2 + 2 (a z.g_i + b z.g_j + a b g_i.g_j)``, and the value is the norm of the
    chosen corner, computed from its coordinates."""
    n, _, m = Ga.shape
    ii, jj = np.triu_indices(m, 1)
    npairs = ii.size
    pairs = np.arange(npairs)
    combos = np.array([[1.0, 1.0], [1.0, -1.0], [-1.0, 1.0], [-1.0, -1.0]])
    chunk = int(max(1, min(WORST_CASE_CHUNK, max_chunk_bytes // (8 * npairs * (m + 8)))))
    g_all = np.ascontiguousarray(Ga.transpose(0, 2, 1))            # (n, m, 3)
    gp_all = np.ascontiguousarray(Gp.transpose(0, 2, 1))
    for a in range(0, n, chunk):
        interrupt.check()  # a long evaluation stops at the caller's deadline (a no-op outside interrupt.watching)
        b = min(n, a + chunk)
        c = b - a
        g, gp = g_all[a:b], gp_all[a:b]
        A, B = gp[:, ii], gp[:, jj]                                 # (c, pairs, 3)
        V = np.empty_like(A)
        V[..., 0] = A[..., 1] * B[..., 2] - A[..., 2] * B[..., 1]
        V[..., 1] = A[..., 2] * B[..., 0] - A[..., 0] * B[..., 2]
        V[..., 2] = A[..., 0] * B[..., 1] - A[..., 1] * B[..., 0]
        S = np.matmul(V, Gp[a:b])                                   # (c, pairs, m)
        S = np.copysign(1.0, np.add(S, 0.0, out=S), out=S)     # -0.0 + 0.0 = +0.0: a zero counts +1 (the kernel)
        S[:, pairs, ii] = 0.0
        S[:, pairs, jj] = 0.0
        Z = np.matmul(S, g)                                         # (c, pairs, 3)
        gi, gj = g[:, ii], g[:, jj]
        X = np.einsum("cqk,cqk->cq", Z, gi)
        Y = np.einsum("cqk,cqk->cq", Z, gj)
        W = np.einsum("cqk,cqk->cq", gi, gj)
        corner = np.stack([X + Y + W, X - Y - W, -X + Y - W, -X - Y + W], axis=2)   # (c, pairs, 4)
        sq = (np.einsum("cqk,cqk->cq", Z, Z) + np.einsum("cqk,cqk->cq", gi, gi)
              + np.einsum("cqk,cqk->cq", gj, gj))[:, :, None] + 2.0 * corner
        arg = np.argmax(sq.reshape(c, -1), axis=1)
        qbest, rbest = np.divmod(arg, 4)
        rows = np.arange(c)
        z = Z[rows, qbest] + combos[rbest, 0:1] * gi[rows, qbest] + combos[rbest, 1:2] * gj[rows, qbest]
        out[a:b] = np.sqrt(np.einsum("ck,ck->c", z, z))
        if return_signs:
            s = S[rows, qbest]
            s[rows, ii[qbest]] = combos[rbest, 0]
            s[rows, jj[qbest]] = combos[rbest, 1]
            best_s[a:b] = s


CRITERIA = ("paper", "worst-case", "per-axis", "rss")
"""Every named bound, spelled the same in Python, the command line, JSON and files."""
LIMIT_CRITERIA = ("paper", "worst-case", "rss")
"""The criteria a design limit is judged by (budgets, allocation); per-axis is only a cheap upper bound."""
DEFAULT_LIMIT_CRITERION = "worst-case"
"""What an allocation is held to unless told otherwise: the exact worst case over every error sign, the
one criterion that guarantees the limit (the paper's ``|J delta|`` lets errors of opposite effect cancel)."""


def criterion_bound(J, delta, criterion: str, k_sigma: float = 3.0) -> np.ndarray:
    """(n,) bound of one named criterion: 'paper', 'worst-case', 'per-axis' or 'rss' (coverage k_sigma)."""
    if criterion == "paper":
        return paper_bound(J, delta)
    if criterion == "worst-case":
        return worst_case_bound(J, delta)
    if criterion == "per-axis":
        return per_axis_bound(J, delta)
    if criterion == "rss":
        return rss_bound(J, delta, k_sigma)
    raise ValueError(f"criterion: expected one of {CRITERIA}, got {criterion!r}")


def bounds(J, delta, worst_case: bool = True) -> dict:
    """All bounds at once, keyed by criterion name (``CRITERIA``) -> (n,) arrays."""
    out = {"paper": paper_bound(J, delta)}
    if worst_case:
        out["worst-case"] = worst_case_bound(J, delta)
    out["per-axis"] = per_axis_bound(J, delta)
    out["rss"] = rss_bound(J, delta)
    return out
