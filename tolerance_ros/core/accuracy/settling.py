"""ISO 9283 pose stabilisation time and pose overshoot at each stop of a tracker's stream (m, s).

At a stop (the command comes to rest at ``t_stop`` after a motion and stays until the next motion; ``rest_instants``
finds that instant between the joint states' samples), the attained
pose is the mean of the points in the last ``FINAL_FRACTION`` of the rest. With the points smoothed by a
cubic Savitzky-Golay filter over ``smooth`` s (the tracker's noise, not the robot's motion) and ``d(t)`` their
distance from the attained pose:

- **stabilisation time**: from ``t_stop`` to the first point after the last one outside the band
  ``d > band`` (0 when none is outside); a stop whose last point outside the band falls within the last
  fraction of its rest did not settle, and is reported so (no time);
- **positioning time**: from the instant the command leaves its rest to the stop's stabilisation (the motion's
  duration and the stabilisation time); the minimum positioning time is the least over the moves of one
  distance;
- **overshoot**: the largest distance past the attained pose along the approach direction (the command's
  direction over its last ``APPROACH`` m before the stop), after the point first entered the band; 0 when it
  never went past.
"""
from __future__ import annotations

import numpy as np

FINAL_FRACTION = 0.2     # of the rest: the points whose mean is the attained pose
MIN_REST = 0.1           # s: a shorter rest is not judged
MIN_POINTS = 20          # tracker points in a rest judged
APPROACH = 1e-3          # m: the command's last stretch before a stop that gives the approach direction
SAME_MOVE = 1e-4         # m: moves this close in length are one distance of the minimum positioning time
NOISE_MARGIN = 1.0       # a swing nearer the band than this many noise standard deviations: uncertain


def _gain(k: int) -> float:
    """The factor by which the cubic Savitzky-Golay filter over k samples divides white noise's standard deviation
    (its centre coefficient's variance reduction, Savitzky & Golay 1964)."""
    return 1.0 if k <= 4 else float(np.sqrt(3.0 * (3 * k * k - 7) / (4.0 * k * (k * k - 4))))


def _window(smooth: float, dt: float, n: int) -> int:
    k = int(round(smooth / dt)) if dt > 0 else 1
    return min(k, n - (1 - n % 2)) | 1 if k > 4 else 1


def _smooth(p, k: int) -> np.ndarray:
    """(n, 3) points smoothed by a cubic Savitzky-Golay filter over k samples (odd; as many as there are at
    most): it keeps the oscillations of a stop (a 40 ms window passes 20 Hz) and takes out most of the noise."""
    if k <= 4:
        return p
    from scipy.signal import savgol_filter
    return savgol_filter(p, k, 3, axis=0, mode="interp")


def stop_figures(t, p, t_stop: float, t_end: float, approach, band: float, smooth: float = 0.04) -> dict:
    """Stabilisation time and overshoot of one stop (see the module docstring): ``t`` (n,) s and ``p`` (n, 3) m the
    tracker's points on the command's clock and in the base frame, ``approach`` (3,) the direction the command
    came in (None: unknown, no overshoot). Keys: t_stop_s, rest_s, points, attained_m, stabilisation_time_s,
    stabilisation_std_s (the noise over the slope of the distance where it crosses the band), overshoot_m,
    settled, margin_m, noise_m, uncertain, note."""
    sel = (t >= t_stop) & (t <= t_end)
    ts, ps = t[sel], p[sel]
    out = {"t_stop_s": float(t_stop), "rest_s": float(t_end - t_stop), "points": int(len(ts)), "attained_m": None,
           "stabilisation_time_s": None, "stabilisation_std_s": None, "overshoot_m": None, "settled": False,
           "margin_m": None, "noise_m": None,
           "uncertain": False, "note": None}
    if t_end - t_stop < MIN_REST or len(ts) < MIN_POINTS:
        out["note"] = (f"a rest of {t_end - t_stop:.3g} s with {len(ts)} tracker point(s): too short to judge (at "
                       f"least {MIN_REST:g} s and {MIN_POINTS} points)")
        return out
    dt = float(np.median(np.diff(ts)))
    k = _window(smooth, dt, len(ts))
    smoothed = _smooth(ps, k)
    final_from = t_stop + (1.0 - FINAL_FRACTION) * (t_end - t_stop)
    tail = ts >= final_from
    if tail.sum() < MIN_POINTS // 4:
        out["note"] = (f"{int(tail.sum())} tracker point(s) in the last {FINAL_FRACTION:.0%} of the rest: its attained "
                       f"pose is not measured (the tracker stopped, or its clock jumped)")
        return out
    final = ps[tail].mean(axis=0)
    d = np.linalg.norm(smoothed - final, axis=1)
    outside = np.flatnonzero(d > band)
    out["attained_m"] = final.tolist()
    if outside.size and ts[outside[-1]] >= final_from:
        out["note"] = (f"still {d[outside[-1]] * 1e3:.4g} mm from its attained pose at "
                       f"{ts[outside[-1]] - t_stop:.3f} s, "
                       f"in the last {FINAL_FRACTION:.0%} of the rest: it did not settle within the band")
        return out
    out["settled"] = True
    settle = 0 if not outside.size else outside[-1] + 1
    out["stabilisation_time_s"] = float(ts[settle] - t_stop) if outside.size else 0.0
    noise = float(np.sqrt(np.mean((ps[tail] - smoothed[tail]) ** 2)))
    after = d[settle:]
    clear = np.flatnonzero(after < band - NOISE_MARGIN * noise)   # the later swings: once clear of the band
    margin = float(band - after[clear[0]:].max()) if clear.size else 0.0
    if outside.size:                                 # and the last swing outside: how far it went past the band
        gaps = np.flatnonzero(np.diff(outside) > 1)
        start = outside[gaps[-1] + 1] if gaps.size else outside[0]
        margin = min(margin, float(d[start:settle].max() - band))
    out.update(margin_m=margin, noise_m=noise, uncertain=bool(margin < NOISE_MARGIN * noise))
    if outside.size and 0 < settle < len(d) - 1:     # the crossing's standard uncertainty: noise over the slope
        slope = abs(d[settle + 1] - d[settle - 1]) / (ts[settle + 1] - ts[settle - 1])
        out["stabilisation_std_s"] = float(noise * _gain(k) / slope) if slope > 0 else None
    else:
        out["stabilisation_std_s"] = 0.0
    if out["uncertain"]:
        out["note"] = (f"a swing came within {margin * 1e3:.4f} mm of the band, under {NOISE_MARGIN:g} times the "
                       f"tracker's noise ({noise * 1e3:.4f} mm): the time may be off by a swing")
    inside = np.flatnonzero(d <= band)
    if approach is not None and inside.size:
        u = np.asarray(approach, float)
        past = (smoothed[inside[0]:] - final) @ u
        out["overshoot_m"] = float(max(0.0, past.max()))
    return out


def rest_instants(t, p) -> tuple:
    """(s, s) the instants a motion sampled at t (k,) leaves its first rest and reaches its last, its samples p
    (k, 3) m running from the last sample at rest to the first at rest again: the square root of the distance from
    a rest grows linearly in time under a constant acceleration, so it is extrapolated to zero from the two
    samples next to the rest (the rest sample itself where they do not rise)."""
    def edge(tt, d):
        r = np.sqrt(d)
        moved = np.flatnonzero(r > 1e-6 * max(r.max(), 1e-300))
        j = int(moved[0]) if moved.size else 0
        if j < 1 or j + 1 >= len(r) or not r[j + 1] > r[j]:
            return float(tt[max(j - 1, 0)])
        at = tt[j] - (tt[j + 1] - tt[j]) * r[j] / (r[j + 1] - r[j])
        lo, hi = sorted((tt[j - 1], tt[j]))                 # between the last sample at rest and the first moved
        return float(min(max(at, lo), hi))
    start = edge(t, np.linalg.norm(p - p[0], axis=1))
    stop = edge(t[::-1], np.linalg.norm(p[::-1] - p[-1], axis=1))
    return max(start, float(t[0])), min(stop, float(t[-1]))


def approach_direction(p_c, i0: int, i1: int):
    """(3,) unit direction of the command path ``p_c`` over its last ``APPROACH`` m before index i1 (its motion
    from i0), or None when it moved less than that."""
    back = np.linalg.norm(p_c[i0:i1 + 1] - p_c[i1], axis=1)
    far = np.flatnonzero(back >= APPROACH)
    if not far.size:
        return None
    v = p_c[i1] - p_c[i0 + far[-1]]
    return v / np.linalg.norm(v)


def stops(t, p, tj, p_c, runs, band: float, smooth: float = 0.04) -> dict:
    """Figures of every stop after a motion ``runs`` [(i0, i1)] of the command (indices into ``tj``, ``p_c``), each
    rest lasting to the next motion or the end of both streams. Keys: band_m, smooth_s, stops [stop_figures ...
    with move_m (the command's distance from its start), motion_s and positioning_time_s (motion_s and the
    stabilisation time)], judged, uncertain, stabilisation_time_s {max, mean}, overshoot_m {max, mean} (None
    when no stop was judged), positioning (``positioning``)."""
    if not (np.isfinite(band) and band > 0):
        raise ValueError(f"band: expected a positive length (m), got {band!r}")
    t_last = min(float(tj[-1]), float(t[-1])) if len(t) else float(tj[-1])
    per = []
    for k, (i0, i1) in enumerate(runs):
        t_end = float(tj[runs[k + 1][0]]) if k + 1 < len(runs) else t_last
        per.append(judge_stop(t, p, motion(tj, p_c, i0, i1), t_end, band, smooth))
    return summary(per, band, smooth)


def motion(tj, p_c, i0: int, i1: int) -> dict:
    """What a stop needs of the motion [i0, i1] of the command before it: start_s and stop_s (``rest_instants``),
    approach (``approach_direction``), move_m (the command's distance from its start)."""
    t0, t1 = rest_instants(tj[i0:i1 + 1], p_c[i0:i1 + 1])
    return {"start_s": t0, "stop_s": t1, "approach": approach_direction(p_c, i0, i1),
            "move_m": float(np.linalg.norm(p_c[i1] - p_c[i0]))}


def judge_stop(t, p, mv: dict, t_end: float, band: float, smooth: float = 0.04) -> dict:
    """``stop_figures`` of the stop after the motion ``mv`` (``motion``), its rest lasting to ``t_end``, with the
    move, the motion's duration and the positioning time (None when it did not settle)."""
    s = stop_figures(t, p, mv["stop_s"], t_end, mv["approach"], band, smooth)
    s["move_m"] = mv["move_m"]
    s["motion_s"] = float(mv["stop_s"] - mv["start_s"])
    s["positioning_time_s"] = None if s["stabilisation_time_s"] is None else s["motion_s"] + s["stabilisation_time_s"]
    return s


def summary(per, band: float, smooth: float = 0.04) -> dict:
    """The stops' figures (``stops``) of the stops ``per`` (``judge_stop``)."""
    judged = [s for s in per if s["settled"]]
    st = [s["stabilisation_time_s"] for s in judged]
    ov = [s["overshoot_m"] for s in judged if s["overshoot_m"] is not None]
    return {"band_m": float(band), "smooth_s": float(smooth), "stops": per, "judged": len(judged),
            "uncertain": sum(s["uncertain"] for s in judged),
            "stabilisation_time_s": {"max": max(st), "mean": float(np.mean(st))} if st else None,
            "overshoot_m": {"max": max(ov), "mean": float(np.mean(ov))} if ov else None,
            "positioning": positioning(judged)}


def positioning(judged) -> list:
    """Minimum positioning time per distance moved: the stops judged grouped by their move (within 1 % or
    ``SAME_MOVE`` m of each other), shortest first: [{distance_m, moves, min_s, mean_s}]."""
    moves = sorted(judged, key=lambda s: s["move_m"])
    groups = []
    for s in moves:
        if groups and s["move_m"] - groups[-1][0]["move_m"] <= max(SAME_MOVE, 0.01 * groups[-1][0]["move_m"]):
            groups[-1].append(s)
        else:
            groups.append([s])
    return [{"distance_m": float(np.mean([s["move_m"] for s in g])), "moves": len(g),
             "min_s": min(s["positioning_time_s"] for s in g),
             "mean_s": float(np.mean([s["positioning_time_s"] for s in g]))} for g in groups]
