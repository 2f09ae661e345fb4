"""ISO 9283 path characteristics of a command path driven ``n`` times (SI: m, s, m/s; AV and RV fractions).

The command path is the nominal tool path of the commanded joints, sampled at the joint states' stamps.
A run is cut into motions where the command moves (speed above ``rest_speed``); the motions that start
and end where the most frequent one does and have its length (within ``same``) are the ``n`` cycles of
the test path, the others (an approach, the return of a line) are other motions. The test path is cut
into segments at its corners (where its direction turns by more than ``corner_angle`` within a short arc).
Each segment carries ``m`` calculation points ("stations") evenly spread, ``(i + 1/2) / m`` of the way, over
the segment less ``END_MARGIN`` at each end (the corner zone, judged by CR and CO); at each,
the plane normal to the command path holds one attained point per cycle (where the attained path crosses
the plane, interpolated between samples). With ``c_i`` the command point, ``x_ij`` the attained point of
cycle ``j`` and ``d_ij = x_ij - c_i`` (its component in the plane):

- path accuracy ``AT_p = max_i |d_bar_i|``, ``d_bar_i`` the barycentre's deviation (mean over cycles);
- path repeatability ``RT_p = max_i (l_bar_i + 3 S_li)``, ``l_ij = |d_ij - d_bar_i|``,
  ``S_li = sqrt(sum_j (l_ij - l_bar_i)^2 / (n - 1))`` (None for one cycle);
- at a corner ``C`` (the meeting point of the incoming and outgoing command lines) of each cycle: the corner
  round-off ``CR``, the least distance from ``C`` to the attained path, and the corner overshoot ``CO``,
  the largest deviation of the attained path past the corner beyond the outgoing command line on the side
  of the incoming motion (0 when it stays inside); a segment reports the corner at its start, the largest
  over the cycles (None for a segment that starts at rest);
- over the stations where the command cruises (speed >= ``CRUISE`` of its largest in the segment, and farther
  than ``speed x speed_window`` from the segment's ends, where a central difference would cut a corner), with
  ``v_ij`` the attained speed, ``v_bar_j`` its mean in cycle ``j``, ``v_bar`` the mean of those and ``v_c``
  the command speed: path velocity accuracy ``AV = (v_bar - v_c) / v_c``, repeatability
  ``RV = 3 S_v / v_c`` with ``S_v = sqrt(sum_j (v_bar_j - v_bar)^2 / (n - 1))`` (None for one cycle), and
  fluctuation ``FV = max_j (max_i v_ij - min_i v_ij)`` in m/s. Speeds are central differences over
  ``+-speed_window`` s.

Per cycle and segment: ``AT_p`` of that cycle alone (``max_i |d_ij|``), CR, CO, its mean speed and FV.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

CRUISE = 0.95        # the cruise stations of a segment: command speed >= this share of its largest
SAME = 1e-3          # m: motions are cycles of one path when their ends agree this well (length: 1 %)
CORNER_ANGLE = np.radians(30.0)
END_MARGIN = 2e-3    # m: stations keep this far (at most 5 % of the segment) from a segment's ends


def interp_columns(x, t, Y) -> np.ndarray:
    """(n, d) the columns of ``Y`` (k, d), sampled at ``t`` (k,) increasing, interpolated linearly at ``x`` (n,)
    (held at the ends)."""
    return np.column_stack([np.interp(x, t, Y[:, k]) for k in range(Y.shape[1])])


def arc_length(p) -> np.ndarray:
    """(n,) cumulative length (m) of the polyline ``p`` (n, 3)."""
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))])


def speeds(t, p, h: float) -> np.ndarray:
    """(n,) speed (m/s) at stamps ``t`` of the path ``p`` (n, 3): ``|p(t + h) - p(t - h)| / 2h``, one-sided
    at the ends, ``p`` interpolated linearly in time."""
    lo, hi = np.maximum(t - h, t[0]), np.minimum(t + h, t[-1])
    d = interp_columns(hi, t, p) - interp_columns(lo, t, p)
    return np.linalg.norm(d, axis=1) / np.maximum(hi - lo, 1e-12)


def motions(t, p, rest_speed: float = 1e-3, min_rest: float = 0.05, min_length: float = 1e-3,
            step: float | None = None) -> list:
    """[(i0, i1)] index ranges (inclusive) of the command's motions: runs of speed (central differences over
    ``+-step`` s, default the median sampling interval) above ``rest_speed`` m/s joined across pauses shorter
    than ``min_rest`` s, at least ``min_length`` m long, with the rest sample at each end."""
    v = speeds(t, p, step if step is not None else 0.0 if len(t) < 3 else float(np.median(np.diff(t))))
    moving = v > rest_speed
    edges = np.flatnonzero(np.diff(np.concatenate([[0], moving.view(np.int8), [0]])))
    runs = [[a, b - 1] for a, b in zip(edges[::2], edges[1::2])]
    merged = []
    for a, b in runs:
        if merged and t[a] - t[merged[-1][1]] < min_rest:
            merged[-1][1] = b
        else:
            merged.append([a, b])
    s = arc_length(p)
    out = []
    for a, b in merged:
        a, b = max(a - 1, 0), min(b + 1, len(t) - 1)
        if s[b] - s[a] >= min_length:
            out.append((int(a), int(b)))
    return out


def hole_in_motion(gaps, tj, i0: int, i1: int, tm, j0: int, j1: int) -> str | None:
    """Why the motion ``tj[i0..i1]`` cannot be judged, or None: a gap (``gaps``: ``{"joint_states": StampGaps,
    "points": StampGaps}``) in its joint states, or in the tracker's stamps ``tm`` across its points ``[j0, j1)``
    (one more on each side): interpolated across lost messages, its figures would be wrong."""
    span = f"the motion from {tj[i0]:.3f} s to {tj[i1]:.3f} s"
    joints = gaps["joint_states"].hole(tj[i0:i1 + 1])
    if joints is not None:
        return f"{span} was not judged: a gap of {joints:.3g} s in its joint states (messages lost, or never sent)"
    points = gaps["points"].hole(tm[max(j0 - 1, 0):min(j1 + 1, len(tm))])
    if points is not None:
        return f"{span} was not judged: a gap of {points:.3g} s in the tracker's points across it"
    return None


def cycles_of(p, runs, same: float = SAME, reverse: bool = False):
    """(indices of the runs that are cycles of the test path, indices of the other motions): the test path is
    the most frequent motion (start, end within ``same`` m, length within 1 %); with ``reverse``, the motion that
    drives it backwards (a line's return strokes; ValueError when there is none)."""
    if not runs:
        return [], []
    sig = [(p[a], p[b], arc_length(p[a:b + 1])[-1]) for a, b in runs]
    groups = []
    for k, (s0, s1, L) in enumerate(sig):
        for g in groups:
            r0, r1, RL = sig[g[0]]
            if np.linalg.norm(s0 - r0) <= same and np.linalg.norm(s1 - r1) <= same and abs(L - RL) <= 0.01 * RL:
                g.append(k)
                break
        else:
            groups.append([k])
    best = max(groups, key=len)
    if reverse:
        s0, s1, L = sig[best[0]]
        back = [g for g in groups if g is not best and np.linalg.norm(sig[g[0]][0] - s1) <= same
                and np.linalg.norm(sig[g[0]][1] - s0) <= same and abs(sig[g[0]][2] - L) <= 0.01 * L]
        if not back:
            raise ValueError("reverse: no motion drives the test path backwards (its return strokes)")
        best = max(back, key=len)
    return best, [k for k in range(len(runs)) if k not in best]


def corners(p, angle: float = CORNER_ANGLE, arm: float | None = None) -> np.ndarray:
    """(k,) arc lengths (m) of the corners of the polyline ``p`` (n, 3): where the directions over ``arm`` m
    before and after turn by more than ``angle`` rad; in each such stretch, the point of the polyline
    nearest the meeting point of the legs on either side."""
    s = arc_length(p)
    L = s[-1]
    if not L > 0:
        return np.zeros(0)
    arm = arm or min(5e-3, 0.02 * L)
    grid = np.arange(0.0, L, arm / 5.0)
    if len(grid) < 3:
        return np.zeros(0)

    def at(x):
        return interp_columns(np.clip(x, 0.0, L), s, p)

    before, here, after = at(grid - arm), at(grid), at(grid + arm)
    a, b = here - before, after - here
    na, nb = np.linalg.norm(a, axis=1), np.linalg.norm(b, axis=1)
    ok = (na > 0.5 * arm) & (nb > 0.5 * arm)
    cosang = np.einsum("ij,ij->i", a, b) / np.maximum(na * nb, 1e-300)
    turn = ok & (cosang < np.cos(angle))
    edges = np.flatnonzero(np.diff(np.concatenate([[0], turn.view(np.int8), [0]])))
    out = []
    for i, j in zip(edges[::2], edges[1::2]):
        lo, hi = grid[i] - arm, grid[j - 1] + arm          # the legs meet between lo and hi
        a0, a1, b0, b1 = at(np.array([lo - arm, lo, hi, hi + arm]))
        la, lb = np.linalg.norm(a1 - a0), np.linalg.norm(b1 - b0)
        sel = np.flatnonzero((s >= lo) & (s <= hi))
        if len(sel) < 2 or la < 0.5 * arm or lb < 0.5 * arm:   # a leg cut short by an end of the path
            out.append(0.5 * (lo + hi))
            continue
        C = _line_meet(a1, (a1 - a0) / la, b0, (b1 - b0) / lb)
        if len(sel) < 2:
            out.append(0.5 * (lo + hi))
            continue
        A, B = p[sel[:-1]], p[sel[1:]]
        AB = B - A
        tt = np.clip(np.einsum("ij,ij->i", C - A, AB) / np.maximum(np.einsum("ij,ij->i", AB, AB), 1e-300), 0, 1)
        k = int(np.argmin(np.linalg.norm(A + tt[:, None] * AB - C, axis=1)))
        out.append(float(s[sel[k]] + tt[k] * (s[sel[k + 1]] - s[sel[k]])))
    return np.array(out)


def _line_meet(p0, u0, p1, u1) -> np.ndarray:
    """The point nearest both lines ``p0 + a u0`` and ``p1 + b u1`` (the middle of their common normal)."""
    A = np.column_stack([u0, -u1])
    ab = np.linalg.lstsq(A, p1 - p0, rcond=None)[0]
    return 0.5 * (p0 + ab[0] * u0 + p1 + ab[1] * u1)


@dataclass
class Cycle:
    """One cycle: command stamps ``t`` (k,) s, points ``p`` (k, 3) m, arc length ``s`` (k,); the attained
    samples' aligned stamps ``ta`` (n,), points ``a`` (n, 3) m (base frame)."""

    t: np.ndarray
    p: np.ndarray
    s: np.ndarray
    ta: np.ndarray
    a: np.ndarray


def _tangents(p, s) -> np.ndarray:
    """(k, 3) unit tangents of a polyline by central differences; at rest the nearest moving one."""
    d = np.zeros_like(p)
    d[1:-1] = p[2:] - p[:-2]
    d[0], d[-1] = p[1] - p[0], p[-1] - p[-2]
    n = np.linalg.norm(d, axis=1)
    good = n > 1e-12
    if not good.any():
        raise ValueError("the command path does not move")
    idx = np.flatnonzero(good)
    near = idx[np.clip(np.searchsorted(idx, np.arange(len(p))), 0, len(idx) - 1)]
    return d[near] / n[near, None]


WINDOW = 64  # attained samples looked at on each side of a station for its plane's crossing


def station_points(cyc: Cycle, sigma, lo, hi, speed_window: float):
    """Attained points ``x`` (m, 3) in the normal planes at arc lengths ``sigma`` (m,) of one cycle's command
    (each station's tangent taken within its segment ``[lo, hi]``), the command points ``c`` (m, 3), unit
    tangents ``u`` (m, 3), attained and command speeds (m,) m/s, and each attained sample's along-path
    coordinate (n,) m (its command's arc length at its stamp plus its offset along the tangent)."""
    t, p, s = cyc.t, cyc.p, cyc.s

    def at(x):
        return interp_columns(x, s, p)

    u_c = _tangents(p, s)
    sa = np.interp(cyc.ta, t, s)
    ca = interp_columns(cyc.ta, t, p)
    ua = u_c[np.clip(np.searchsorted(t, cyc.ta), 0, len(t) - 1)]
    along = sa + np.einsum("ij,ij->i", cyc.a - ca, ua)
    mono = np.maximum.accumulate(along)
    c = at(sigma)
    delta = 1e-4
    u = at(np.minimum(sigma + delta, hi)) - at(np.maximum(sigma - delta, lo))
    u /= np.linalg.norm(u, axis=1)[:, None]
    n = len(cyc.a)
    if n < 2:
        raise ValueError("a cycle without tracker points along it: the tracker stopped or the streams do not overlap")
    k0 = np.clip(np.searchsorted(mono, sigma), 0, n - 1)
    win = np.clip(k0[:, None] + np.arange(-WINDOW, WINDOW + 1)[None], 0, n - 1)       # (m, w)
    f = np.einsum("mwj,mj->mw", cyc.a[win] - c[:, None], u)
    cross = (f[:, :-1] <= 0) & (f[:, 1:] > 0) & (win[:, 1:] > win[:, :-1])
    dist = np.where(cross, np.abs(np.arange(-WINDOW, WINDOW)[None] + 0.5), np.inf)
    j = np.argmin(dist, axis=1)
    found = np.isfinite(dist[np.arange(len(j)), j])
    jn = np.argmin(np.abs(f), axis=1)
    k = np.where(found, win[np.arange(len(j)), j], win[np.arange(len(j)), jn])
    k1 = np.minimum(k + 1, n - 1)
    f0 = np.einsum("mj,mj->m", cyc.a[k] - c, u)
    f1 = np.einsum("mj,mj->m", cyc.a[k1] - c, u)
    w = np.where(found & (f1 > f0), np.clip(-f0 / np.where(f1 > f0, f1 - f0, 1.0), 0.0, 1.0), 0.0)
    x = cyc.a[k] + w[:, None] * (cyc.a[k1] - cyc.a[k])
    va = speeds(cyc.ta, cyc.a, speed_window)
    v = va[k] + w * (va[k1] - va[k])
    vc = np.interp(sigma, s, speeds(t, p, speed_window))
    return x, c, u, v, vc, mono


def corner_figures(cyc: Cycle, along, sc: float, before: float, after: float):
    """(CR, CO) m of one cycle at the corner at arc length ``sc`` of its command; the legs are looked at over
    ``before`` and ``after`` m."""
    s, p = cyc.s, cyc.p

    def at(x):
        return np.array([np.interp(x, s, p[:, k]) for k in range(3)])

    q = 0.25
    a0, a1 = at(sc - before), at(sc - q * before)
    b0, b1 = at(sc + q * after), at(sc + after)
    u_in, u_out = (a1 - a0) / np.linalg.norm(a1 - a0), (b1 - b0) / np.linalg.norm(b1 - b0)
    C = _line_meet(a1, u_in, b0, u_out)
    near = np.flatnonzero((along >= sc - before) & (along <= sc + after))
    if len(near) < 2:
        return None, None
    P = cyc.a[near[0]:near[-1] + 1]
    A, B = P[:-1], P[1:]
    AB = B - A
    tt = np.clip(np.einsum("ij,ij->i", C - A, AB) / np.maximum(np.einsum("ij,ij->i", AB, AB), 1e-300), 0.0, 1.0)
    CR = float(np.min(np.linalg.norm(A + tt[:, None] * AB - C, axis=1)))
    n_out = u_in - (u_in @ u_out) * u_out
    n_out /= np.linalg.norm(n_out)
    past = cyc.a[(along >= sc) & (along <= sc + after)]
    CO = float(max(0.0, np.max((past - C) @ n_out))) if len(past) else 0.0
    return CR, CO


def segment_bounds(length: float, corner_s) -> np.ndarray:
    """(k + 1,) arc lengths of the segments' ends: 0, the corners, the path's length."""
    return np.concatenate([[0.0], np.asarray(corner_s, float), [length]])


def _layout(bounds, stations):
    """(first station's arc length per segment, their span, fractions) of the stations of ``bounds``."""
    lengths = np.diff(bounds)
    margin = np.minimum(END_MARGIN, 0.05 * lengths)
    return bounds[:-1] + margin, lengths - 2 * margin, (np.arange(stations) + 0.5) / stations


def cycle_stations(cyc: Cycle, bounds, stations: int = 100, speed_window: float = 0.01) -> dict:
    """What one cycle contributes to the figures (its stations' attained and command points, tangents and
    speeds, and each corner's CR and CO), all a path's figures need of it: an on-line monitor keeps this
    instead of the cycle's samples. ``bounds`` as ``path_characteristics``."""
    if stations < 2:
        raise ValueError("stations: at least 2 per segment")
    bounds = np.asarray(bounds, float)
    nseg = len(bounds) - 1
    first, span, frac = _layout(bounds, stations)
    scale = cyc.s[-1] / bounds[-1]
    sig = np.concatenate([(first[k] + frac * span[k]) * scale for k in range(nseg)])
    lo = np.repeat(bounds[:-1], stations) * scale
    hi = np.repeat(bounds[1:], stations) * scale
    x, c, u, v, vc, along = station_points(cyc, sig, lo, hi, speed_window)
    corner = [(None, None)] + [corner_figures(cyc, along, bounds[k] * scale, 0.5 * (bounds[k] - bounds[k - 1]) * scale,
                                              0.5 * (bounds[k + 1] - bounds[k]) * scale) for k in range(1, nseg)]
    return {"x": x, "c": c, "u": u, "v": v, "vc": vc, "corner": corner}


def path_characteristics(cycles: list, bounds, stations: int = 100, speed_window: float = 0.01) -> list:
    """ISO 9283 path figures per segment (see the module docstring) of ``cycles`` (``Cycle``, one command
    path driven n times) cut at ``bounds`` (k + 1,) m of the first cycle's arc length (scaled to each
    cycle's length). Returns one dict per segment: SI figures, per-cycle figures and per-station arrays."""
    if not cycles:
        raise ValueError("no cycle of the test path")
    return figures([cycle_stations(c, bounds, stations, speed_window) for c in cycles], bounds, stations,
                   speed_window)


def figures(per: list, bounds, stations: int = 100, speed_window: float = 0.01) -> list:
    """The figures per segment from the cycles' ``cycle_stations``."""
    if not per:
        raise ValueError("no cycle of the test path")
    bounds = np.asarray(bounds, float)
    nseg, n = len(bounds) - 1, len(per)
    first, span, frac = _layout(bounds, stations)
    out = []
    X = np.stack([r["x"] for r in per])          # (n, k m, 3)
    Cm = np.stack([r["c"] for r in per])
    U = np.stack([r["u"] for r in per])
    V = np.stack([r["v"] for r in per])          # (n, k m)
    VC = np.stack([r["vc"] for r in per])
    D = X - Cm
    D -= np.einsum("nij,nij->ni", D, U)[..., None] * U     # the deviation in the normal plane
    for k in range(nseg):
        sl = slice(k * stations, (k + 1) * stations)
        d = D[:, sl]
        dbar = d.mean(axis=0)
        AT_i = np.linalg.norm(dbar, axis=1)
        if n >= 2:
            l = np.linalg.norm(d - dbar, axis=2)
            RT_i = l.mean(axis=0) + 3.0 * l.std(axis=0, ddof=1)
        else:
            RT_i = np.full(stations, np.nan)
        vc_ref = VC[:, sl].mean(axis=0)
        s_k = first[k] + frac * span[k]
        clear = np.minimum(s_k - bounds[k], bounds[k + 1] - s_k) > vc_ref.max() * speed_window
        cruise = (vc_ref >= CRUISE * vc_ref.max()) & clear
        if not cruise.any():
            cruise = vc_ref >= CRUISE * vc_ref.max()
        v = V[:, sl][:, cruise]
        v_c = float(VC[:, sl][:, cruise].mean())
        vbar_j = v.mean(axis=1)
        vbar = float(vbar_j.mean())
        FV_j = v.max(axis=1) - v.min(axis=1)
        CR_j = [r["corner"][k][0] for r in per]
        CO_j = [r["corner"][k][1] for r in per]
        known = [c for c in CR_j if c is not None]
        seg = {
            "name": f"S{k + 1}", "length_m": float((bounds[k + 1] - bounds[k])), "stations": stations, "cycles": n,
            "AT_p_m": float(AT_i.max()), "RT_p_m": float(RT_i.max()) if n >= 2 else None,
            "CR_m": float(max(known)) if known else None,
            "CO_m": float(max(c for c in CO_j if c is not None)) if known else None,
            "AV": (vbar - v_c) / v_c, "RV": float(3.0 * vbar_j.std(ddof=1) / v_c) if n >= 2 else None,
            "FV_m_s": float(FV_j.max()), "v_c_m_s": v_c, "v_mean_m_s": vbar,
            "per_cycle": [{"cycle": j, "AT_p_m": float(np.linalg.norm(d[j], axis=1).max()), "CR_m": CR_j[j],
                           "CO_m": CO_j[j], "v_mean_m_s": float(vbar_j[j]), "FV_m_s": float(FV_j[j])}
                          for j in range(n)],
            "along": {"s_m": s_k.tolist(), "AT_m": AT_i.tolist(),
                      "RT_m": RT_i.tolist() if n >= 2 else None,
                      "command_m": Cm[:, sl].mean(axis=0).tolist(),
                      "barycentre_m": (Cm[:, sl].mean(axis=0) + dbar).tolist()},
        }
        out.append(seg)
    return out


def overall(segments: list) -> dict:
    """Figures over every segment: the largest AT_p, RT_p, CR, CO, |AV|-largest AV, RV, FV."""
    def top(key, absolute=False):
        vals = [s[key] for s in segments if s[key] is not None]
        if not vals:
            return None
        return float(max(vals, key=abs) if absolute else max(vals))
    return {"AT_p_m": top("AT_p_m"), "RT_p_m": top("RT_p_m"), "CR_m": top("CR_m"), "CO_m": top("CO_m"),
            "AV": top("AV", True), "RV": top("RV"), "FV_m_s": top("FV_m_s")}
