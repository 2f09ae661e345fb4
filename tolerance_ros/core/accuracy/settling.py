"""ISO 9283 pose stabilisation time and pose overshoot at each stop of a tracker's stream (m, s).

At a stop (the command comes to rest at ``t_stop`` after a motion and stays until the next motion; ``rest_instant``
finds that instant between the joint states' samples, whatever the profile's end: a ramp, a constant deceleration,
a jerk-limited stop), the attained
pose is the mean of the points in the last ``FINAL_FRACTION`` of the rest. With the points smoothed by a
cubic Savitzky-Golay filter over ``smooth`` s (the tracker's noise, not the robot's motion) and ``d(t)`` their
distance from the attained pose:

- **stabilisation time**: from ``t_stop`` to the instant the distance enters the band ``d <= band`` for good,
  interpolated between the last point outside it and the next (0 when none is outside); a stop whose last point
  outside the band falls within the last fraction of its rest did not settle, and is reported so (no time);
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
    if outside.size:                                 # the band entered for good between two points
        k = outside[-1]
        frac = (d[k] - band) / (d[k] - d[k + 1])
        out["stabilisation_time_s"] = float(ts[k] + frac * (ts[k + 1] - ts[k]) - t_stop)
    else:
        out["stabilisation_time_s"] = 0.0
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


REST_FLOOR = 1e-9        # m (and that share of the move): a command nearer its rest than this is at rest
EDGE_SAMPLES = 6         # the samples next to a rest fitted to find the instant the command reaches it
POWERS = np.arange(1.0, 4.0001, 0.05)   # d ~ (t_s - t)^m: 1 a ramp's end, 2 constant deceleration, 3 jerk-limited


def rest_instant(t, d) -> float:
    """(s) the instant a motion reaches its rest, from samples at ``t`` (k,) s (ascending, up to or past the rest)
    at distances ``d`` (k,) m from the rest position: the last ``EDGE_SAMPLES`` samples still moving (farther than
    ``REST_FLOOR``) are fitted by ``d = c (t_s - t)^m`` (the power m in 1..4 that fits best: 1 the end of a
    ramp, 2 a constant deceleration, 3 a jerk-limited or minimum-jerk stop), extrapolated to d = 0 after the last
    sample moving, at most one interval past the first at rest (which may still creep below the floor). A fraction of a sample, where a speed threshold is tens of
    milliseconds early on a smooth profile."""
    t, d = np.asarray(t, float), np.asarray(d, float)
    moving = np.flatnonzero(d > REST_FLOOR * max(1.0, float(d.max()) if len(d) else 1.0))
    if not moving.size:
        return float(t[0])
    last = int(moving[-1])
    lo = last
    while lo > 0 and last - lo + 1 < EDGE_SAMPLES and d[lo - 1] > d[lo]:   # the stretch still closing in
        lo -= 1
    # the first sample at rest may still creep below the floor: the rest is reached within one more interval
    hi_t = float(2 * t[last + 1] - t[last]) if last + 1 < len(t) else np.inf
    if last - lo + 1 < 2:
        return float(t[last]) if not np.isfinite(hi_t) else hi_t
    ts, ds = t[lo:last + 1], d[lo:last + 1]
    tc = ts - ts[-1]
    Y = ds[None, :] ** (1.0 / POWERS[:, None])                 # (m, k): linear in t for the right power
    A = np.c_[np.ones_like(tc), tc]
    coef, *_ = np.linalg.lstsq(A, Y.T, rcond=None)             # (2, m)
    resid = Y - (A @ coef).T
    spread = np.ptp(Y, axis=1)
    score = np.sqrt(np.mean(resid ** 2, axis=1)) / np.where(spread > 0, spread, 1.0)
    a, b = coef[:, int(np.argmin(score))]
    at = float(ts[-1] - a / b) if b < 0 else float(ts[-1])
    return float(min(max(at, float(ts[-1])), hi_t))


def rest_instants(t, p, p_from=None, p_to=None) -> tuple:
    """(s, s) the instants a motion sampled at t (k,) leaves its first rest and reaches its last, its samples p
    (k, 3) m running from (at least) the last sample at rest to the first at rest again; ``p_from``, ``p_to`` (3,)
    the rest positions (default the first and the last sample): ``rest_instant`` at each end."""
    t, p = np.asarray(t, float), np.asarray(p, float)
    p_from = p[0] if p_from is None else np.asarray(p_from, float)
    p_to = p[-1] if p_to is None else np.asarray(p_to, float)
    stop = rest_instant(t, np.linalg.norm(p - p_to, axis=1))
    start = -rest_instant(-t[::-1], np.linalg.norm(p[::-1] - p_from, axis=1))
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
        lo = runs[k - 1][1] if k else 0
        hi = runs[k + 1][0] if k + 1 < len(runs) else len(tj) - 1
        mv = motion(tj, p_c, i0, i1, lo)
        per.append(judge_stop(t, p, at_rest(mv, tj[i1:hi + 1], p_c[i1:hi + 1]), t_end, band, smooth))
    return summary(per, band, smooth)


TAIL = 400   # the motion's last samples a stop keeps until its rest is seen (``at_rest``)


def motion(tj, p_c, i0: int, i1: int, lo: int | None = None) -> dict:
    """What a stop needs of the motion [i0, i1] of the command before it: start_s (``rest_instants``, the rest
    before it at the middle of [lo, i0]), a provisional stop_s (at p_c[i1]: ``at_rest`` finds it once the rest
    is seen), approach (``approach_direction``), move_m (the command's distance from its start), and the motion's
    last samples (``tail``)."""
    lo = i0 if lo is None else lo
    a = (lo + i0) // 2
    t0, t1 = rest_instants(tj[a:i1 + 1], p_c[a:i1 + 1], p_from=p_c[a])
    k = max(i0, i1 - TAIL)
    return {"start_s": t0, "stop_s": t1, "approach": approach_direction(p_c, i0, i1),
            "move_m": float(np.linalg.norm(p_c[i1] - p_c[i0])), "tail": (tj[k:i1 + 1].copy(), p_c[k:i1 + 1].copy())}


def at_rest(mv: dict, t_rest, p_rest) -> dict:
    """``mv`` (``motion``) with the instant the command reached its rest: the rest's samples ``t_rest`` (r,) s and
    ``p_rest`` (r, 3) m, from the motion's last sample to the next motion (or the streams' end), its position the
    middle sample's (where a smooth profile has stopped creeping in and not yet begun to creep out)."""
    if len(t_rest) < 2:
        return mv
    mid = len(t_rest) // 2
    tt, pp = mv["tail"]
    t = np.concatenate([tt, np.asarray(t_rest, float)[1:mid + 1]])
    d = np.linalg.norm(np.concatenate([pp, np.asarray(p_rest, float)[1:mid + 1]]) - p_rest[mid], axis=1)
    return {**mv, "stop_s": rest_instant(t, d)}


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
