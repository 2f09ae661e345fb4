"""Compiled (numba) exact worst case of a zonotope's norm: ``errors.worst_case_bound`` one pose at a time (the
numpy version there, batched over poses, is the reference). Cached on disk as ``jit.njit`` says."""
from __future__ import annotations

import math

import numpy as np

from .jit import njit


@njit(fastmath={"reassoc", "contract"})  # the sums over generators vectorised (their order is free)
def zonotope_max(G, Gp, out, signs, want_signs):
    """out[k] = max over s in {-1,+1}^m of |G[k] s| for each pose k (G (n, 3, m) generators), by the cells
    of the arrangement around each line Gp_i x Gp_j (Gp: G perturbed, used only to choose the signs); the
    algorithm and the candidates' order of ``errors.worst_case_bound``, one pose at a time. With
    ``want_signs`` the maximising signs go to ``signs`` (n, m)."""
    n, _, m = G.shape
    for k in range(n):
        best, bi, bj, ba, bb = -1.0, 0, 1, 1.0, 1.0
        for i in range(m):
            pi0, pi1, pi2 = Gp[k, 0, i], Gp[k, 1, i], Gp[k, 2, i]
            for j in range(i + 1, m):
                pj0, pj1, pj2 = Gp[k, 0, j], Gp[k, 1, j], Gp[k, 2, j]
                v0, v1, v2 = pi1 * pj2 - pi2 * pj1, pi2 * pj0 - pi0 * pj2, pi0 * pj1 - pi1 * pj0
                z0, z1, z2 = 0.0, 0.0, 0.0
                for l in range(m):  # every generator; i and j taken out after (a branch-free loop)
                    s = 1.0 - 2.0 * (v0 * Gp[k, 0, l] + v1 * Gp[k, 1, l] + v2 * Gp[k, 2, l] < 0.0)
                    z0 += s * G[k, 0, l]
                    z1 += s * G[k, 1, l]
                    z2 += s * G[k, 2, l]
                si = 1.0 - 2.0 * (v0 * pi0 + v1 * pi1 + v2 * pi2 < 0.0)
                sj = 1.0 - 2.0 * (v0 * pj0 + v1 * pj1 + v2 * pj2 < 0.0)
                z0 -= si * G[k, 0, i] + sj * G[k, 0, j]
                z1 -= si * G[k, 1, i] + sj * G[k, 1, j]
                z2 -= si * G[k, 2, i] + sj * G[k, 2, j]
                for a, b in ((1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)):
                    c0 = z0 + a * G[k, 0, i] + b * G[k, 0, j]
                    c1 = z1 + a * G[k, 1, i] + b * G[k, 1, j]
                    c2 = z2 + a * G[k, 2, i] + b * G[k, 2, j]
                    norm = c0 * c0 + c1 * c1 + c2 * c2
                    if norm > best:
                        best, bi, bj, ba, bb = norm, i, j, a, b
        out[k] = math.sqrt(best)
        if want_signs:
            pi0, pi1, pi2 = Gp[k, 0, bi], Gp[k, 1, bi], Gp[k, 2, bi]
            pj0, pj1, pj2 = Gp[k, 0, bj], Gp[k, 1, bj], Gp[k, 2, bj]
            v0, v1, v2 = pi1 * pj2 - pi2 * pj1, pi2 * pj0 - pi0 * pj2, pi0 * pj1 - pi1 * pj0
            for l in range(m):
                signs[k, l] = -1.0 if v0 * Gp[k, 0, l] + v1 * Gp[k, 1, l] + v2 * Gp[k, 2, l] < 0.0 else 1.0
            signs[k, bi] = ba
            signs[k, bj] = bb


def warm_up():
    """Compile, or load from the cache, zonotope_max in the signature ``worst_case_bound`` calls."""
    G = np.zeros((1, 3, 2))
    zonotope_max(G, G, np.empty(1), np.empty((1, 2)), True)
