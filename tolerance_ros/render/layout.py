"""Checks the layout of a drawn matplotlib figure: texts that overlap each other, texts that leave the
figure, legends that cover plotted data. Distances are in display pixels of the figure's own dpi."""
from __future__ import annotations

import numpy as np

TOLERANCE_PX = 1.0


def layout_problems(fig, tol=TOLERANCE_PX, dpi=None) -> list:
    """Every layout problem of ``fig``, drawn here with its canvas's renderer (at ``dpi``, the dots per
    inch it is saved with, when given: the figure keeps that dpi), one sentence each: two visible texts or
    legends whose boxes overlap by more than ``tol`` px both ways, a text or legend reaching more than
    ``tol`` px past the figure's edge, a legend over plotted data inside its axes (line segments, markers,
    scatter points, bars). Empty when the figure reads well."""
    if dpi is not None:
        fig.set_dpi(dpi)
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    boxes = [(name, artist.get_window_extent(renderer)) for name, artist in _texts(fig)]
    problems = []
    for i, (a, ba) in enumerate(boxes):
        for b, bb in boxes[i + 1:]:
            w, h = _overlap(ba, bb)
            if w > tol and h > tol:
                problems.append(f"{a} overlaps {b} ({w:.0f} x {h:.0f} px)")
    page = fig.bbox
    for name, box in boxes:
        past = max(page.x0 - box.x0, box.x1 - page.x1, page.y0 - box.y0, box.y1 - page.y1)
        if past > tol:
            problems.append(f"{name} leaves the figure by {past:.0f} px")
    legends = [(_legend_name(lg, "figure"), lg, fig.axes) for lg in fig.legends]
    legends += [(_legend_name(ax.get_legend(), f"axes {k + 1}"), ax.get_legend(), [ax])
                for k, ax in enumerate(fig.axes) if ax.get_legend() is not None]
    for name, legend, axes in legends:
        if legend.get_visible():
            box = legend.get_window_extent(renderer)
            covered = [f"{what} in axes {fig.axes.index(ax) + 1}" for ax in axes for what in _covered(ax, box, tol)]
            if covered:
                problems.append(f"{name} covers data: {', '.join(covered)}")
    return problems


def _texts(fig):
    """(name, artist) of every visible non-empty text of ``fig``; a legend counts as one box."""
    out = [(f"figure text {t.get_text()!r}", t) for t in fig.texts if _shown(t)]
    out += [(_legend_name(lg, "figure"), lg) for lg in fig.legends if lg.get_visible()]
    for k, ax in enumerate(fig.axes):
        where = f"axes {k + 1}"
        for t in (ax.title, getattr(ax, "_left_title", None), getattr(ax, "_right_title", None)):
            if t is not None and _shown(t):
                out.append((f"{where} title {t.get_text()!r}", t))
        for t in ax.texts:
            if _shown(t):
                out.append((f"{where} text {t.get_text()!r}", t))
        for which, axis in (("x", ax.xaxis), ("y", ax.yaxis)):
            if not axis.get_visible():
                continue
            if _shown(axis.label):
                out.append((f"{where} {which} label {axis.label.get_text()!r}", axis.label))
            if _shown(axis.offsetText):
                out.append((f"{where} {which} offset text {axis.offsetText.get_text()!r}", axis.offsetText))
            scale = axis.get_transform()  # the comparison in the axis' own scale (log: decades, not values)
            with np.errstate(all="ignore"):
                lo, hi = sorted(scale.transform(np.asarray(axis.get_view_interval(), float)))
            span = (hi - lo) * 1e-9
            for tick in axis.get_major_ticks() + axis.get_minor_ticks():
                with np.errstate(all="ignore"):
                    at = float(scale.transform(np.array([tick.get_loc()], float))[0])
                if not lo - span <= at <= hi + span:  # NaN (a log axis' 0) is not drawn either
                    continue
                for t in (tick.label1, tick.label2):
                    if _shown(t):
                        out.append((f"{where} {which} tick label {t.get_text()!r}", t))
        legend = ax.get_legend()
        if legend is not None and legend.get_visible():
            out.append((_legend_name(legend, where), legend))
    return out


def _shown(t) -> bool:
    return t.get_visible() and bool(t.get_text().strip())


def _legend_name(legend, where) -> str:
    return f"{where} legend {[t.get_text() for t in legend.get_texts()]}"


def _overlap(a, b):
    """Width and height (px) of the intersection of two boxes; negative where they do not meet."""
    return min(a.x1, b.x1) - max(a.x0, b.x0), min(a.y1, b.y1) - max(a.y0, b.y0)


def _covered(ax, box, tol) -> list:
    """Labels of the data artists of ``ax`` drawn inside ``box`` (display px), within the axes."""
    from matplotlib.collections import Collection, LineCollection
    from matplotlib.patches import Rectangle
    x0, y0 = max(box.x0, ax.bbox.x0) + tol, max(box.y0, ax.bbox.y0) + tol
    x1, y1 = min(box.x1, ax.bbox.x1) - tol, min(box.y1, ax.bbox.y1) - tol
    if x1 <= x0 or y1 <= y0:
        return []
    inner = (x0, y0, x1, y1)
    hits = []
    for line in ax.lines:
        if not line.get_visible():
            continue
        xy = line.get_transform().transform(np.asarray(line.get_xydata(), float))
        drawn = line.get_linestyle() not in ("None", "none", "", " ")
        if (drawn and _segments_hit(xy, inner)) or (line.get_marker() not in (None, "None", "none", "", " ")
                                                     and _points_hit(xy, inner)):
            hits.append(_label(line))
    for coll in ax.collections:
        if not coll.get_visible():
            continue
        if isinstance(coll, LineCollection):
            hit = any(_segments_hit(coll.get_transform().transform(np.asarray(s, float)), inner)
                      for s in coll.get_segments() if len(s))
        elif isinstance(coll, Collection):
            offsets = np.asarray(coll.get_offsets(), float)
            hit = len(offsets) > 0 and _points_hit(coll.get_offset_transform().transform(offsets), inner)
        else:
            hit = False
        if hit:
            hits.append(_label(coll))
    for patch in ax.patches:
        if isinstance(patch, Rectangle) and patch.get_visible():
            r = patch.get_window_extent()
            if min(r.x1, x1) - max(r.x0, x0) > 0 and min(r.y1, y1) - max(r.y0, y0) > 0:
                hits.append(_label(patch))
    return list(dict.fromkeys(hits))


def _label(artist) -> str:
    label = artist.get_label()
    return repr(label) if label and not label.startswith("_") else type(artist).__name__


def _points_hit(xy, inner) -> bool:
    x0, y0, x1, y1 = inner
    ok = np.isfinite(xy).all(axis=1)
    p = xy[ok]
    return bool(np.any((p[:, 0] > x0) & (p[:, 0] < x1) & (p[:, 1] > y0) & (p[:, 1] < y1)))


def _segments_hit(xy, inner) -> bool:
    """True when a polyline (display px) passes through the box ``inner`` = (x0, y0, x1, y1)."""
    if _points_hit(xy, inner):
        return True
    a, b = xy[:-1], xy[1:]
    ok = np.isfinite(a).all(axis=1) & np.isfinite(b).all(axis=1)
    a, b = a[ok], b[ok]
    if not len(a):
        return False
    x0, y0, x1, y1 = inner
    d = b - a
    lo, hi = np.zeros(len(a)), np.ones(len(a))
    for k, (low, high) in enumerate(((x0, x1), (y0, y1))):
        with np.errstate(divide="ignore", invalid="ignore"):
            t0, t1 = (low - a[:, k]) / d[:, k], (high - a[:, k]) / d[:, k]
        flat = d[:, k] == 0
        inside = (a[:, k] > low) & (a[:, k] < high)
        t_in, t_out = np.minimum(t0, t1), np.maximum(t0, t1)
        lo = np.where(flat, np.where(inside, lo, 2.0), np.maximum(lo, t_in))
        hi = np.where(flat, np.where(inside, hi, -1.0), np.minimum(hi, t_out))
    return bool(np.any(lo < hi))
