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

``coarse_offset`` finds an offset of any size (a tracker hundreds of milliseconds late, a trajectory file's time
from start against the tracker's clock) by the cross-correlation of the two speed profiles, which no frame or
geometric error changes; the fine search then looks within ``FINE_WINDOW_S`` of it. An estimate at the edge of
its search window is never a result: ValueError names the window.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from .path import interp_columns
from .registration import kabsch

SCAN_POINTS = 10_000      # points of the coarse scan
REFINE_POINTS = 100_000   # points of the refinement and of the curvature
MAX_GROUPS = 60           # cycles (or blocks) estimated one by one
COARSE_BIN_S = 0.01       # s: the bins of the coarse search's speed profiles
FINE_WINDOW_S = 0.05      # s: the fine search's half-width about the coarse estimate (5 of its bins)
COARSE_TIE = 0.02         # shifts whose speed correlation is within this share of the best are tied


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
    instead of a search: the many evaluations of a latency estimate at a fraction of ``np.interp``'s cost.
    When the stamps span far more time than their samples would fill (long holes), the grid would outgrow
    them: the path is then interpolated by ``np.interp`` instead, in memory bounded by the samples."""

    GRID_PER_SAMPLE = 20          # grid points per sample, at most (plus GRID_SPARE)
    GRID_SPARE = 100_000

    def __init__(self, tc, pc, dt: float | None = None):
        tc, pc = np.asarray(tc, float), np.asarray(pc, float)
        d = np.diff(tc)
        d = d[d > 0]
        step = float(np.median(d)) if d.size else 1e-3
        self.dt = dt or min(step, 1e-3)
        self.t0 = float(tc[0])
        n = int(np.floor((tc[-1] - tc[0]) / self.dt)) + 1 if tc.size else 0
        if n > self.GRID_PER_SAMPLE * len(tc) + self.GRID_SPARE:
            self.tc, self.pc, self.p = tc, pc, None
            return
        grid = self.t0 + np.arange(n) * self.dt
        self.p = interp_columns(grid, tc, pc)

    def __call__(self, t) -> np.ndarray:
        if self.p is None:
            return interp_columns(np.asarray(t, float), self.tc, self.pc)
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


GEOMETRY_POINTS = 20_000  # points of the fit of the robot's own errors (``geometry``)


def _geometry_fit(tau, tm, pm, idx, R, t, cmd, geometry, register: bool, window: float):
    """(latency s, its curvature uncertainty s or None, (n, 3) m the points' part the robot's errors explain) with
    the robot's own errors (``geometry(times) -> (n, 3, k)``, the columns of its position error per parameter at the
    points commanded then, and a small turn of the registration when ``register``) fitted with the latency: the
    residual left once they are projected out, ``S'(tau)``, minimised within ``tau +- window`` on at most
    ``GEOMETRY_POINTS`` points (the columns taken at ``tau``: they change with the joints, not with a fraction of
    a millisecond). Its curvature gives the uncertainty where the robot's errors and a shift can stand in for each
    other (a circle at constant speed: a shift is a turn of the circle)."""
    from scipy.optimize import minimize_scalar
    from ..identification import base_jacobian
    fit = idx[_stride(len(idx), GEOMETRY_POINTS)]

    def columns(i):
        G = geometry(tm[i] - tau)
        return np.concatenate([G, base_jacobian(cmd(tm[i] - tau))[:, :3]], axis=2) if register else G
    A = columns(fit)
    A = A.reshape(-1, A.shape[2])
    U, sv, _ = np.linalg.svd(A, full_matrices=False)
    Q = U[:, sv > 1e-9 * sv[0]] if sv.size and sv[0] > 0 else U[:, :0]
    base = (pm[fit] - t) @ R

    def S(x):
        r = (base - cmd(tm[fit] - x)).reshape(-1)
        return float(r @ r - np.sum((Q.T @ r) ** 2))
    res = minimize_scalar(S, bounds=(tau - window, tau + window), method="bounded", options={"xatol": 1e-7})
    tau2 = float(res.x)
    S0 = S(tau2)
    h = max(window / 400.0, 1e-5)
    curv = (S(tau2 + h) - 2 * S0 + S(tau2 - h)) / h ** 2
    sigma2 = max(S0, 0.0) / max(3 * len(fit) - 7 - Q.shape[1], 1)
    u = float(np.sqrt(2 * sigma2 / curv)) if curv > 0 else None
    r = (base - cmd(tm[fit] - tau2)).reshape(-1)
    x = np.linalg.lstsq(A, r, rcond=1e-9)[0]
    out = np.zeros_like(pm)
    for k in range(0, len(idx), GEOMETRY_POINTS):
        i = idx[k:k + GEOMETRY_POINTS]
        out[i] = np.einsum("nij,j->ni", columns(i), x) @ R.T
    return tau2, u, out


def estimate_latency(tm, pm, tc, pc, window: float = 0.1, center: float = 0.0, register: bool = True,
                     groups=None, parts=None, usable=None, geometry=None) -> Latency:
    """The latency of the tracker's points (``tm`` (n,) s, ``pm`` (n, 3) m, tracker frame) against the command
    path (``tc`` (k,) s, ``pc`` (k, 3) m, base frame) within ``center +- window`` s. ``groups``: index arrays
    into ``tm`` of the cycles (default: 10 time blocks); ``parts``: index arrays of the parts of the path
    (its segments over every cycle; default none). Only points whose shifted stamps stay inside the
    command's time span for every shift tried are used, and of those only the ``usable`` ones (a function of
    (stamps, lo, hi) giving a mask: those whose shifted stamps stay in one epoch of the command).

    ``geometry`` (times (n,) s -> (n, 3, k), the columns of the tool point's position error per parameter of the
    robot at the joints commanded then): the robot's own errors are fitted with the latency (``_geometry_fit``),
    and the spreads over the cycles and the parts are taken of the points with them taken out. An error along the path reads as a shift (e / v:
    0.05 mm at 0.15 m/s is 0.3 ms), and so biases the latency of an as-built robot; the error of a parameter
    repeats wherever the robot is, moving or not, where a latency moves a point only while it moves."""
    from scipy.optimize import minimize_scalar
    tm, pm, tc, pc = (np.asarray(a, float) for a in (tm, pm, tc, pc))
    if not window > 0:
        raise ValueError("latency window: must be > 0")
    lo, hi = center - window, center + window
    inside = (tm - hi >= tc[0]) & (tm - lo <= tc[-1])
    if usable is not None:
        inside &= usable(tm, lo, hi)
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
    if b in (0, len(taus) - 1):
        raise ValueError(f"latency: the best shift lies at the edge of the search window {lo * 1e3:+.1f} ms to "
                         f"{hi * 1e3:+.1f} ms, so the latency may lie beyond it: widen the window, or give the "
                         f"latency")
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
    first = Latency(tau, u, u_curv, u_cyc, u_part, per, per_part, float(np.sqrt(S0 / N)), int(len(idx)),
                    float(window), taus.tolist(), np.sqrt(S / len(scan_i)).tolist())
    if geometry is None:
        return first
    w = min(window, max(10 * u, 20 * step, 1e-3))
    tau2, u_geo, explained = _geometry_fit(tau, tm, pm, idx, R, t, cmd, geometry, register, w)
    again = estimate_latency(tm, pm - explained, tc, pc, w, tau2, register, groups, parts, usable)
    u2 = max(u_geo if u_geo is not None else w, again.std_cycles_s or 0.0, again.std_parts_s or 0.0)
    return Latency(tau2, u2, u_geo, again.std_cycles_s, again.std_parts_s, again.per_cycle_s, again.per_part_s,
                   again.residual_rms_m, again.points, first.window_s, first.scan_s, first.scan_rms_m)


def _speed_profile(t, p, t0: float, n: int, dt: float):
    """(n,) speed (m/s) of the path ``p`` (k, 3) at ``t`` (k,) s in bins of ``dt`` s from ``t0``, less its mean
    where known, and (n,) whether it is known: a bin inside the stream, not in one of its holes (an interval
    over ten times the median one and 50 ms)."""
    d = np.diff(t)
    hole = max(10.0 * float(np.median(d)) if d.size else 0.0, 0.05)
    centre = t0 + (np.arange(n) + 0.5) * dt
    after = np.searchsorted(t, centre)
    inside = (after > 0) & (after < len(t))
    i = np.clip(after, 1, len(t) - 1)
    known = inside & (t[i] - t[i - 1] <= hole)
    x = interp_columns(centre, t, p)
    v = np.zeros(n)
    v[1:-1] = np.linalg.norm(x[2:] - x[:-2], axis=1) / (2 * dt)
    known[1:-1] &= known[:-2] & known[2:]
    known[[0, -1]] = False
    if known.any():
        v[known] -= v[known].mean()
    v[~known] = 0.0
    return v, known


def coarse_offset(tm, pm, tc, pc, dt: float = COARSE_BIN_S, tie: float = COARSE_TIE) -> float:
    """The shift (s) of the tracker's stamps against the command's by the cross-correlation of their speed
    profiles (``_speed_profile``; no frame or small geometric error changes a speed) over every shift that
    leaves them overlapping for half the shorter stream or more: a latency of any size. Where the path
    repeats, shifts by its period correlate almost as well (a stream that holds more cycles than the other
    matches at several): of the peaks within ``tie`` of the best, the nearest zero. The bins widen when the
    stamps span more time than ``4 x`` the samples would fill (memory bounded by the samples). ValueError
    when no shift leaves them overlapping so."""
    tm, pm, tc, pc = (np.asarray(a, float) for a in (tm, pm, tc, pc))
    t0 = min(tm[0], tc[0])
    span = max(tm[-1], tc[-1]) - t0
    dt = max(dt, span / (4 * (len(tm) + len(tc)) + 100_000))
    n = int(np.ceil(span / dt)) + 2
    (vm, km), (vc, kc) = _speed_profile(tm, pm, t0, n, dt), _speed_profile(tc, pc, t0, n, dt)
    m = 1 << int(np.ceil(np.log2(2 * n)))

    def corr(a, b):
        return np.fft.irfft(np.fft.rfft(a, m) * np.conj(np.fft.rfft(b, m)), m)

    xc = corr(vm, vc)
    overlap = corr(km.astype(float), kc.astype(float)) * dt
    lags = np.arange(m)
    lags = np.where(lags > m // 2, lags - m, lags) * dt
    shorter = min(km.sum(), kc.sum()) * dt
    ok = overlap >= 0.5 * shorter - 1.5 * dt
    if not ok.any() or not shorter > 0:
        raise ValueError(f"latency: no shift of the tracker's stamps leaves the two streams overlapping for half the "
                         f"shorter one ({shorter:.3g} s of known speed): they cannot be aligned (another recording?)")
    best = float(xc[ok].max())
    peak = ok & (xc >= np.roll(xc, 1)) & (xc >= np.roll(xc, -1))
    near = peak & (xc >= best - tie * abs(best))
    return float(lags[near][np.argmin(np.abs(lags[near]))])
