"""Time alignment of a tracker's stream with the command (the joint states' nominal tool path).

The tracker's stamp of a point measured when the joints were at time ``t`` is ``t + tau``: ``tau`` (s) is its
latency against the joint states (positive: the tracker stamps late). It is the shift that minimises the
registration's residual

    S(tau) = min_A sum_k |A c(t_k - tau) - m_k|^2

(``m_k`` the tracker's point stamped ``t_k``, ``c`` the command path interpolated in time, ``A`` the rigid
tracker placement by Kabsch, or the identity for base-frame measurements): a scan over ``+-window`` then a
bounded refinement (``scipy.optimize.minimize_scalar``) around the best. A wrong ``tau`` moves each point
along the path by speed x error, which no rigid ``A`` can absorb on a path that turns or stops.

Its standard uncertainty is the largest of (a) the curvature one, ``sqrt(2 sigma^2 / S'')`` with
``sigma^2 = S / (3N - 7)``, (b) the spread of the shifts estimated on each cycle (or time block) alone
with ``A`` held, ``std / sqrt(count)``, and (c) the spread (``std``) of the shifts estimated on each part of
the path (its segments, over every cycle): (a) trusts the residual to be white noise, (b) sees noise that
differs from cycle to cycle, (c) the bias of a geometric error that repeats along the path (its
along-path component at a speed ``v`` reads as a shift ``e / v``, which differs from one direction of the
path to another).

``coarse_offset`` finds a large offset (a trajectory file's time from start against the tracker's clock)
by the cross-correlation of the two speed profiles, which no frame or geometric error changes.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from .path import interp_columns
from .registration import kabsch

SCAN_POINTS = 10_000      # points of the coarse scan
REFINE_POINTS = 100_000   # points of the refinement and of the curvature
MAX_GROUPS = 60           # cycles (or blocks) estimated one by one


@dataclass
class Latency:
    """``latency_s`` and its standard uncertainty ``std_s`` (the largest of ``std_curvature_s``,
    ``std_cycles_s`` and ``std_parts_s``), the shifts of the cycles and of the parts alone, the residual RMS
    (m, 3-D) at the optimum, the scan."""

    latency_s: float
    std_s: float
    std_curvature_s: float | None
    std_cycles_s: float | None
    std_parts_s: float | None
    per_cycle_s: list
    per_part_s: list
    residual_rms_m: float
    points: int
    window_s: float
    scan_s: list
    scan_rms_m: list

    def to_dict(self) -> dict:
        return asdict(self)


class Resampled:
    """The command path on a uniform time grid (``dt`` s, at most 1 ms), interpolated linearly by arithmetic
    instead of a search: the many evaluations of a latency estimate at a fraction of ``np.interp``'s cost."""

    def __init__(self, tc, pc, dt: float | None = None):
        tc, pc = np.asarray(tc, float), np.asarray(pc, float)
        step = float(np.median(np.diff(tc))) if len(tc) > 1 else 1e-3
        self.dt = dt or min(step, 1e-3)
        self.t0 = float(tc[0])
        n = int(np.floor((tc[-1] - tc[0]) / self.dt)) + 1
        grid = self.t0 + np.arange(n) * self.dt
        self.p = interp_columns(grid, tc, pc)

    def __call__(self, t) -> np.ndarray:
        x = (np.asarray(t, float) - self.t0) / self.dt
        i = np.clip(np.floor(x).astype(np.int64), 0, len(self.p) - 2)
        w = np.clip(x - i, 0.0, 1.0)[:, None]
        return self.p[i] * (1.0 - w) + self.p[i + 1] * w


def _fit(P, M, register: bool):
    """(R, t, sum of squared residuals) of the best rigid map P -> M (identity when not ``register``)."""
    if not register:
        return np.eye(3), np.zeros(3), float(np.sum((P - M) ** 2))
    R, t, _ = kabsch(P, M)
    return R, t, float(np.sum((P @ R.T + t - M) ** 2))


def residual_sum(tau, tm, pm, tc, pc, register: bool = True, command=None) -> float:
    """``S(tau)`` (m^2) over the points ``tm`` (n,) s, ``pm`` (n, 3) m against the command ``tc``, ``pc``
    (or its ``Resampled`` ``command``)."""
    P = command(tm - tau) if command is not None else interp_columns(tm - tau, tc, pc)
    return _fit(P, pm, register)[2]


def _stride(n, cap) -> np.ndarray:
    return np.arange(0, n, max(1, int(np.ceil(n / cap))))


def estimate_latency(tm, pm, tc, pc, window: float = 0.1, center: float = 0.0, register: bool = True,
                     groups=None, parts=None) -> Latency:
    """The latency of the tracker's points (``tm`` (n,) s, ``pm`` (n, 3) m, tracker frame) against the command
    path (``tc`` (k,) s, ``pc`` (k, 3) m, base frame) within ``center +- window`` s. ``groups``: index arrays
    into ``tm`` of the cycles (default: 10 time blocks); ``parts``: index arrays of the parts of the path
    (its segments over every cycle; default none). Only points whose shifted stamps stay inside the
    command's time span for every shift tried are used."""
    from scipy.optimize import minimize_scalar
    tm, pm, tc, pc = (np.asarray(a, float) for a in (tm, pm, tc, pc))
    if not window > 0:
        raise ValueError("latency window: must be > 0")
    lo, hi = center - window, center + window
    inside = (tm - hi >= tc[0]) & (tm - lo <= tc[-1])
    idx = np.flatnonzero(inside)
    if len(idx) < 10:
        raise ValueError(f"latency: only {len(idx)} tracker points lie within the joint states' time span "
                         f"({tc[0]:.3f} s to {tc[-1]:.3f} s, less the {window:g} s window); the two streams do "
                         f"not overlap in time")
    cmd = Resampled(tc, pc)
    scan_i = idx[_stride(len(idx), SCAN_POINTS)]
    ref_i = idx[_stride(len(idx), REFINE_POINTS)]
    step = window / 100.0
    taus = np.arange(lo, hi + 0.5 * step, step)
    S = np.array([residual_sum(x, tm[scan_i], pm[scan_i], tc, pc, register, cmd) for x in taus])
    b = int(np.argmin(S))
    a0, a1 = taus[max(b - 1, 0)], taus[min(b + 1, len(taus) - 1)]
    res = minimize_scalar(lambda x: residual_sum(x, tm[ref_i], pm[ref_i], tc, pc, register, cmd), bounds=(a0, a1),
                          method="bounded", options={"xatol": 1e-6})
    tau = float(res.x)
    P = cmd(tm[ref_i] - tau)
    R, t, S0 = _fit(P, pm[ref_i], register)
    N = len(ref_i)
    h = max(step / 4.0, 1e-4)
    Sp = residual_sum(tau + h, tm[ref_i], pm[ref_i], tc, pc, register, cmd)
    Sm = residual_sum(tau - h, tm[ref_i], pm[ref_i], tc, pc, register, cmd)
    curv = (Sp - 2 * S0 + Sm) / h ** 2
    sigma2 = S0 / max(3 * N - 7, 1)
    u_curv = float(np.sqrt(2 * sigma2 / curv)) if curv > 0 else None   # no minimum: nothing is known
    def alone(sets):
        sets = [np.asarray(g, int) for g in sets]
        sets = [g[inside[g]] for g in sets]
        sets = [g for g in sets if len(g) >= 10]
        if len(sets) > MAX_GROUPS:
            sets = [sets[i] for i in np.linspace(0, len(sets) - 1, MAX_GROUPS).round().astype(int)]
        out = []
        for g in sets:
            g = g[_stride(len(g), REFINE_POINTS // 10)]
            r = minimize_scalar(lambda x: float(np.sum((cmd(tm[g] - x) @ R.T + t - pm[g]) ** 2)),
                                bounds=(tau - 4 * step, tau + 4 * step), method="bounded", options={"xatol": 1e-6})
            out.append(float(r.x))
        return out

    per = alone(np.array_split(idx, 10) if groups is None else groups)
    u_cyc = float(np.std(per, ddof=1) / np.sqrt(len(per))) if len(per) >= 3 else None
    per_part = alone(parts) if parts is not None else []
    u_part = float(np.std(per_part, ddof=1)) if len(per_part) >= 2 else None
    u = max(u_curv, u_cyc or 0.0, u_part or 0.0) if u_curv is not None else float(window)
    return Latency(tau, u, u_curv, u_cyc, u_part, per, per_part,
                   float(np.sqrt(S0 / N)), int(len(idx)), float(window), taus.tolist(),
                   np.sqrt(S / len(scan_i)).tolist())


def coarse_offset(tm, pm, tc, pc, dt: float = 0.01) -> float:
    """The shift (s) of the tracker's stamps against the command's by the cross-correlation of their speed
    profiles, both averaged in bins of ``dt`` s (no frame or small geometric error changes a speed)."""
    def profile(t, p, t0, n):
        k = np.clip(((t - t0) / dt).astype(int), 0, n - 1)
        cnt = np.bincount(k, minlength=n)
        mean = np.column_stack([np.bincount(k, p[:, j], minlength=n) for j in range(3)]) / np.maximum(cnt, 1)[:, None]
        have = cnt > 0
        x = np.arange(n)
        mean = interp_columns(x, x[have], mean[have])
        v = np.zeros(n)
        v[1:-1] = np.linalg.norm(mean[2:] - mean[:-2], axis=1) / (2 * dt)
        return v - v.mean()

    t0 = min(tm[0], tc[0])
    n = int(np.ceil((max(tm[-1], tc[-1]) - t0) / dt)) + 1
    vm, vc = profile(np.asarray(tm, float), np.asarray(pm, float), t0, n), profile(np.asarray(tc, float),
                                                                                   np.asarray(pc, float), t0, n)
    m = 1 << int(np.ceil(np.log2(2 * n)))
    xc = np.fft.irfft(np.fft.rfft(vm, m) * np.conj(np.fft.rfft(vc, m)), m)
    lag = int(np.argmax(xc))
    lag = lag - m if lag > m // 2 else lag
    return lag * dt
