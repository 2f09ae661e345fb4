"""ISO 9283 weaving deviations of a woven test path (``plan-campaign --path weave``), from each cycle of a stream.

The weave's axes come from the command path of the cycle: its line is the first principal direction of the
command points, its width the second (both lie in the weaving plane). The lateral signal ``y(t)`` is a
path's component along the width. Its upward crossings of the median (each counted once the signal has gone
``HYSTERESIS`` of the half swing below and above it: noise about the median at rest is no crossing) give the
weaving periods; the first and
the last period (the motion speeding up and slowing down) are left out, and at least ``MIN_PERIODS`` must
remain. Over those periods:

- the **stroke** ``S`` is the mean of each period's ``max y - min y`` (m, peak to peak);
- the **frequency** ``F`` is the number of periods over the time they took (Hz).

The command and the attained path each give their own ``S`` and ``F``. ``WS = (S_a - S_c) / S_c`` is the
weaving stroke error and ``WF = (F_a - F_c) / F_c`` the weaving frequency error (fractions; the reports give
them in %).
"""
from __future__ import annotations

import numpy as np

MIN_PERIODS = 3        # weaving periods judged in a cycle, besides the first and the last
MIN_STROKE = 1e-3      # m: a command path swinging less than this across its line is not a weave
HYSTERESIS = 0.2       # of the swing's half width: a crossing counts once the signal has cleared this on each side


def weave_axes(p) -> tuple:
    """(origin (3,), along (3,), across (3,)) of the command points p (k, 3): their mean and first two principal
    directions."""
    p = np.asarray(p, float)
    origin = p.mean(axis=0)
    _, _, Vt = np.linalg.svd(p - origin, full_matrices=False)
    return origin, Vt[0], Vt[1]


def signal_figures(t, y) -> dict | None:
    """(stroke m, frequency Hz, periods) of the lateral signal y (n,) at stamps t (n,), or None when it does not
    swing through ``MIN_PERIODS`` whole periods besides its first and last."""
    t, y = np.asarray(t, float), np.asarray(y, float)
    if len(t) < 8:
        return None
    yc = y - np.median(y)
    h = HYSTERESIS * 0.5 * float(np.percentile(yc, 95) - np.percentile(yc, 5))
    side = np.where(yc > h, 1, np.where(yc < -h, -1, 0))
    seen = np.maximum.accumulate(np.where(side != 0, np.arange(len(yc)), 0))
    side = side[seen]                                   # each sample: the side it was last clearly on
    rise = np.flatnonzero((side[:-1] == -1) & (side[1:] == 1)) + 1
    below = np.maximum.accumulate(np.where(yc < 0, np.arange(len(yc)), 0))
    up = below[rise]                                    # the last sample under the median before each rise
    up = up[(up + 1 < len(yc)) & (yc[np.minimum(up + 1, len(yc) - 1)] >= 0)]
    if len(up) < MIN_PERIODS + 3:
        return None
    tu = t[up] - yc[up] * (t[up + 1] - t[up]) / (yc[up + 1] - yc[up])   # the crossings, interpolated
    keep = slice(1, len(up) - 1)                                        # not the first and last period
    starts, ends = up[keep][:-1], up[keep][1:]
    strokes = [float(np.ptp(y[a:b + 1])) for a, b in zip(starts, ends)]
    times = tu[keep]
    periods = len(times) - 1
    return {"stroke_m": float(np.mean(strokes)), "frequency_hz": periods / float(times[-1] - times[0]),
            "periods": periods}


def weaving(cycles) -> dict | None:
    """WS and WF of the cycles (``path.Cycle``: the command ``t``, ``p`` and the attained ``ta``, ``a``), or None
    when the command does not weave (a lateral swing under ``MIN_STROKE`` or too few periods). Keys: cycles
    [{S_c_m, S_a_m, F_c_hz, F_a_hz, WS, WF, periods}], and their means S_c_m, S_a_m, F_c_hz, F_a_hz, WS, WF."""
    per = []
    for cyc in cycles:
        origin, _, across = weave_axes(cyc.p)
        c = signal_figures(cyc.t, (cyc.p - origin) @ across)
        if c is None or c["stroke_m"] < MIN_STROKE:
            return None
        a = signal_figures(cyc.ta, (cyc.a - origin) @ across)
        if a is None:
            continue
        per.append({"S_c_m": c["stroke_m"], "S_a_m": a["stroke_m"], "F_c_hz": c["frequency_hz"],
                    "F_a_hz": a["frequency_hz"], "WS": a["stroke_m"] / c["stroke_m"] - 1.0,
                    "WF": a["frequency_hz"] / c["frequency_hz"] - 1.0, "periods": a["periods"]})
    if not per:
        return None
    return {"cycles": per, **{k: float(np.mean([p[k] for p in per]))
                              for k in ("S_c_m", "S_a_m", "F_c_hz", "F_a_hz", "WS", "WF")}}
