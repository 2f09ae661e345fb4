"""Cycles from repetition: a test path is what the command repeats, whether or not the robot rests between
repetitions (SI: s, m).

``period`` finds the period of a motion's command path from its own geometry: on a uniform time grid, the
lag ``L`` that minimises ``D(L) = mean_t |p(t + L) - p(t)|^2`` (its sums by FFT, O(n log n)), the first one
after the path has left its start by ``LEAVE`` times ``SAME`` at which it comes back within ``SAME`` (RMS),
refined to a fraction of a sample by a parabola through its neighbours; None when the motion does not hold
two periods. ``split_runs`` cuts each motion that holds two or more periods into its repetitions (from the
motion's start, each cut moved to the sample nearest the start point within a tenth of a period; or at the
given period, a trajectory file's), then every piece at its cusps: where the path turns back on itself
(more than ``CUSP_ANGLE``) where it slows to rest (the slowest sample of each stretch under ``CUSP_SPEED`` of
the piece's largest speed), so
that a line driven back and forth gives its forward and its return strokes.
"""
from __future__ import annotations

import numpy as np

from .path import arc_length, interp_columns, speeds

SAME = 1e-3              # m RMS: a repetition comes back this close to the path it repeats
LEAVE = 10.0             # a path has left its start when D exceeds (LEAVE x SAME)^2
MIN_PERIOD_S = 0.1       # s: no shorter period is looked for
CUSP_ANGLE = np.radians(120.0)
CUSP_SPEED = 0.1         # of the piece's largest speed
GRID_PER_SAMPLE = 4      # the uniform grid of ``period`` holds at most this many points per sample


def lag_profile(x) -> np.ndarray:
    """(n,) ``D(L) = mean_i |x[i + L] - x[i]|^2`` over the pairs of ``x`` (n, d) sampled uniformly, L = 0..n-1."""
    x = np.asarray(x, float)
    x = x - x.mean(axis=0)
    n = len(x)
    sq = np.einsum("ij,ij->i", x, x)
    head = np.concatenate([[0.0], np.cumsum(sq)])           # head[k] = sum of sq[:k]
    m = 1 << int(np.ceil(np.log2(2 * n)))
    F = np.fft.rfft(x, m, axis=0)
    corr = np.fft.irfft(np.sum(F * np.conj(F), axis=1), m)[:n]    # sum_i x[i] . x[i + L]
    L = np.arange(n)
    total = head[n - L] + (head[n] - head[L]) - 2.0 * corr
    return np.maximum(total, 0.0) / (n - L)


def period(t, p, same: float = SAME) -> float | None:
    """The period (s) of the path ``p`` (k, 3) m sampled at ``t`` (k,) s, or None (see the module docstring)."""
    t, p = np.asarray(t, float), np.asarray(p, float)
    if len(t) < 8:
        return None
    d = np.diff(t)
    d = d[d > 0]
    span = float(t[-1] - t[0])
    if not d.size or span <= 2 * MIN_PERIOD_S:
        return None
    dt = max(float(np.median(d)), span / (GRID_PER_SAMPLE * len(t)))
    n = int(span / dt) + 1
    x = interp_columns(t[0] + np.arange(n) * dt, t, p)
    D = lag_profile(x)
    lo = max(1, int(np.ceil(MIN_PERIOD_S / dt)))
    hi = n // 2 + 1
    if hi <= lo + 1:
        return None
    left = np.flatnonzero(D[lo:hi] > (LEAVE * same) ** 2)
    if not left.size:
        return None
    start = lo + int(left[0])
    back = np.flatnonzero(D[start:hi] < same ** 2)
    if not back.size:
        return None
    a = start + int(back[0])
    above = np.flatnonzero(D[a:hi] >= same ** 2)
    b = a + int(above[0]) if above.size else hi
    k = a + int(np.argmin(D[a:b]))
    frac = 0.0
    if 0 < k < len(D) - 1:
        den = D[k - 1] - 2 * D[k] + D[k + 1]
        frac = float(np.clip(0.5 * (D[k - 1] - D[k + 1]) / den, -0.5, 0.5)) if den > 0 else 0.0
    return (k + frac) * dt


def cusps(t, p, step: float) -> np.ndarray:
    """Indices into ``p`` (k, 3) of its cusps: the slowest sample of each stretch under ``CUSP_SPEED`` of the
    largest speed, where the direction over an arm of arc length on each side turns by more than
    ``CUSP_ANGLE``."""
    t, p = np.asarray(t, float), np.asarray(p, float)
    if len(t) < 5:
        return np.zeros(0, int)
    v = speeds(t, p, step)
    s = arc_length(p)
    arm = min(5e-3, 0.05 * s[-1])
    if not arm > 0:
        return np.zeros(0, int)
    slow = v < CUSP_SPEED * v.max()
    edges = np.flatnonzero(np.diff(np.concatenate([[0], slow.view(np.int8), [0]])))
    low = np.array([i + int(np.argmin(v[i:j])) for i, j in zip(edges[::2], edges[1::2])], dtype=int)
    low = low[(s[low] - arm > 0) & (s[low] + arm < s[-1])] if low.size else low
    if not low.size:
        return low
    here = p[low]
    before = here - interp_columns(s[low] - arm, s, p)
    after = interp_columns(s[low] + arm, s, p) - here
    cosang = np.einsum("ij,ij->i", before, after) / np.maximum(
        np.linalg.norm(before, axis=1) * np.linalg.norm(after, axis=1), 1e-300)
    return low[cosang < np.cos(CUSP_ANGLE)]


def split_runs(t, p, runs, step: float, known_period: float | None = None, phase: float | None = None):
    """(pieces [(i0, i1)] inclusive, how the cycles were found) of the motions ``runs`` of the command ``p``
    (k, 3) m at ``t`` (k,) s: each motion cut into its repetitions and every piece at its cusps (module
    docstring). ``known_period`` (s) and ``phase`` (s, a cycle's start): a trajectory file's cycles, used
    instead of the ones found. ``how``: 'rests' (no motion held a repetition), 'repetition' with the period
    found, or 'trajectory'."""
    t, p = np.asarray(t, float), np.asarray(p, float)
    out, found = [], []
    for a, b in runs:
        cuts = [a]
        T = known_period if known_period is not None else period(t[a:b + 1], p[a:b + 1])
        if T is not None and T > 0:
            t0 = t[a] if phase is None else phase + np.floor((t[a] - phase) / T) * T
            k = 1
            while t0 + k * T < t[b] - 0.1 * T:
                tc = t0 + k * T
                k += 1
                if tc <= t[a] + 0.1 * T:
                    continue
                i = int(np.clip(np.searchsorted(t, tc), a + 1, b - 1))
                if phase is None:                       # the sample nearest the start within T/10
                    w0, w1 = np.searchsorted(t, [tc - 0.1 * T, tc + 0.1 * T])
                    w0, w1 = max(w0, cuts[-1] + 1), min(w1, b)
                    if w1 > w0:
                        i = w0 + int(np.argmin(np.linalg.norm(p[w0:w1] - p[a], axis=1)))
                elif abs(t[i - 1] - tc) < abs(t[i] - tc):
                    i -= 1
                if cuts[-1] < i < b:
                    cuts.append(i)
            if len(cuts) > 1:
                found.append(T)
        cuts.append(b)
        for c0, c1 in zip(cuts[:-1], cuts[1:]):
            inner = [c0 + int(i) for i in cusps(t[c0:c1 + 1], p[c0:c1 + 1], step)]
            edges = [c0] + inner + [c1]
            out += [(int(x0), int(x1)) for x0, x1 in zip(edges[:-1], edges[1:]) if x1 > x0]
    if known_period is not None:
        how = {"method": "trajectory", "period_s": float(known_period)}
    elif found:
        how = {"method": "repetition", "period_s": float(np.median(found))}
    else:
        how = {"method": "rests", "period_s": None}
    return out, how
