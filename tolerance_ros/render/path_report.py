"""The written path report: path_report.md, path_report.json and the plots (the command path with the
attained barycentres and the budget's tube, magnified; AT_p, RT_p and the bound along the path)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..core.accuracy.streams import describe_tidied
from ..core.ingest import describe_gaps
from ..core.jsonio import dumps
from .plots import _legend_beside, _plt, _save, _subplots, panels_plot
from .text import table


def _mm(v, digits=4):
    return "-" if v is None else f"{v * 1e3:.{digits}f}"


def _pct(v):
    return "-" if v is None else f"{v * 100:+.3f}" if v is not None else "-"


def segment_rows(doc) -> list:
    """One table row per segment and one over them: AT_p, RT_p, CR, CO (mm), AV, RV (%), FV (mm/s)."""
    rows = []
    for s in doc["segments"] + [dict(doc["overall"], name="all", length_m=doc["path_length_m"])]:
        rows.append([s["name"], f"{s['length_m'] * 1e3:.1f}", _mm(s["AT_p_m"]), _mm(s["RT_p_m"]), _mm(s["CR_m"]),
                     _mm(s["CO_m"]), _pct(s["AV"]), "-" if s["RV"] is None else f"{s['RV'] * 100:.3f}",
                     f"{s['FV_m_s'] * 1e3:.2f}", _mm(s.get("bound_max_m"))])
    return rows


HEADS = ["segment", "length mm", "AT_p mm", "RT_p mm", "CR mm", "CO mm", "AV %", "RV %", "FV mm/s", "bound mm"]


def _cycles_from(how) -> str:
    """How the cycles were cut, in words (none for cycles between rests)."""
    if not how or how["method"] == "rests":
        return ""
    if how["method"] == "trajectory":
        return f"; cycles of the trajectory's period {how['period_s']:.3f} s"
    return f"; cycles found by the command's repetition (period {how['period_s']:.3f} s, no rest between them)"


def weaving_line(w) -> str:
    """The weaving deviations, in words."""
    return (f"weaving over {len(w['cycles'])} cycle(s): stroke {w['S_a_m'] * 1e3:.4f} mm against "
            f"{w['S_c_m'] * 1e3:.4f} mm commanded (WS {w['WS'] * 100:+.2f} %), frequency {w['F_a_hz']:.4f} Hz against "
            f"{w['F_c_hz']:.4f} Hz (WF {w['WF'] * 100:+.3f} %)")


def stops_line(st) -> str:
    """The stops' pose stabilisation time and overshoot, in words."""
    unsettled = [s for s in st["stops"] if s["note"] and s["rest_s"] > 0]
    head = (f"{st['judged']} of {len(st['stops'])} stop(s) settled within the {st['band_m'] * 1e3:.4g} mm band")
    if st["stabilisation_time_s"] is None:
        return head + (f"; {unsettled[0]['note']}" if unsettled else "")
    ov = st["overshoot_m"]
    return (head + f": pose stabilisation time max {st['stabilisation_time_s']['max'] * 1e3:.1f} ms, mean "
            f"{st['stabilisation_time_s']['mean'] * 1e3:.1f} ms"
            + (f"; pose overshoot max {ov['max'] * 1e3:.4f} mm, mean {ov['mean'] * 1e3:.4f} mm" if ov else ""))


def summary_lines(doc) -> list:
    """The report's lines of text (the command's stdout and the top of path_report.md)."""
    lat = doc["latency"]
    out = doc["outside"]
    lines = [f"robot {doc['robot']}: {doc['points']} tracker points from {doc['source']}, {doc['joint_states']} "
             f"joint states; {doc['cycles']} cycles of a {doc['path_length_m'] * 1e3:.1f} mm path at "
             f"{doc['speed_m_s'] * 1e3:.1f} mm/s in {len(doc['segments'])} segment(s)"
             + (f", {doc['other_motions']} other motion(s)" if doc["other_motions"] else "")
             + _cycles_from(doc.get("cycles_from"))]
    ignored = (doc.get("command") or {}).get("ignored_columns")
    if ignored:
        lines.append(f"joint-state columns of joints {doc['robot']} does not have, read past: {', '.join(ignored[:10])}"
                     + (f" and {len(ignored) - 10} more" if len(ignored) > 10 else ""))
    lines += [line for line in (describe_tidied(name, s) for name, s in (doc.get("streams") or {}).items()) if line]
    if (doc.get("command") or {}).get("kind") == "trajectory":
        lines.append(f"the trajectory starts at {doc['latency_s']:.6f} s +- {doc['latency_std_s'] * 1e3:.3f} ms on the "
                     f"tracker's clock (no latency is measurable without the joint states' stamps); registration "
                     f"residual RMS {doc['registration']['residual_rms_m'] * 1e3:.4f} mm")
    elif lat.get("given"):
        lines.append(f"latency {doc['latency_s'] * 1e3:.3f} ms (given)")
    else:
        lines.append(f"latency {doc['latency_s'] * 1e3:.3f} ms +- {doc['latency_std_s'] * 1e3:.3f} ms (standard "
                     f"uncertainty; the tracker stamps late by this against the joint states); registration residual "
                     f"RMS {doc['registration']['residual_rms_m'] * 1e3:.4f} mm")
    lines.append(f"not on the test path: {out['points']} points ({out['at_rest']} at rest, {out['other_motions']} "
                 f"during other motions, "
                 + (f"{out['not_judged']} in cycles not judged, " if out.get("not_judged") else "")
                 + f"{out['outside_joint_states']} outside the joint states' time span"
                 + (f", {out['left_out']} left out as repeated or not finite" if out.get("left_out") else "") + ")")
    lines += [line for line in (describe_gaps(name, g) for name, g in (doc.get("stream_gaps") or {}).items()) if line]
    lines += doc.get("not_judged") or []
    st = doc.get("stops")
    if st and st["stops"]:
        lines.append(stops_line(st))
    w = doc.get("weaving")
    if w:
        lines.append(weaving_line(w))
    b = doc.get("budget")
    if b:
        lines.append(f"budget ({b['criterion']} bound): the bound along the path reaches {b['bound_max_m'] * 1e3:.4f} mm"
                     + (f" against the {b['limit_position_m'] * 1e3:.4f} mm limit" if b["limit_position_m"] else "")
                     + f"; {b['stations_outside_bound']} station(s) with AT above it")
    return lines


def plot_path(doc, path) -> Path:
    """The command path, the barycentres and the tube of the bound, in the path's plane, the deviations
    magnified so that the largest shows."""
    plt = _plt()
    C = np.vstack([np.asarray(s["along"]["command_m"]) for s in doc["segments"]])
    B = np.vstack([np.asarray(s["along"]["barycentre_m"]) for s in doc["segments"]])
    centre = C.mean(axis=0)
    U, S, Vt = np.linalg.svd(C - centre, full_matrices=False)
    axes2 = Vt[:2]
    c2, b2 = (C - centre) @ axes2.T, (B - centre) @ axes2.T
    bound = np.concatenate([s["along"].get("bound_m") or [np.nan] * len(s["along"]["AT_m"]) for s in doc["segments"]])
    extent = np.ptp(c2, axis=0).max()
    dev = np.nanmax(np.concatenate([np.linalg.norm(b2 - c2, axis=1), bound]))
    k = float(10 ** np.floor(np.log10(0.05 * extent / dev))) if dev > 0 else 1.0
    fig, ax = _subplots(plt, 1, 1, (7.0, 5.5))
    ax = ax[0, 0]
    ax.plot(c2[:, 0] * 1e3, c2[:, 1] * 1e3, label="command", color="C0", linewidth=1.0)
    shown = c2 + k * (b2 - c2)
    ax.plot(shown[:, 0] * 1e3, shown[:, 1] * 1e3, label=f"barycentre (deviation x{k:g})", color="C1", linewidth=1.0,
            linestyle="--")
    if np.isfinite(bound).any():
        t = np.gradient(c2, axis=0)
        n = np.column_stack([-t[:, 1], t[:, 0]]) / np.maximum(np.linalg.norm(t, axis=1), 1e-300)[:, None]
        for sign, label in ((1, f"bound tube (x{k:g})"), (-1, None)):
            edge = c2 + sign * k * bound[:, None] * n
            ax.plot(edge[:, 0] * 1e3, edge[:, 1] * 1e3, label=label, color="0.5", linewidth=0.8, linestyle=":")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("along the path's first axis [mm]")
    ax.set_ylabel("second axis [mm]")
    ax.set_title(f"{doc['robot']}: command path and attained barycentres")
    _legend_beside(ax)
    return _save(fig, plt, path)


def plot_along(doc, path) -> Path:
    """AT and RT at every station, with the bound, against the arc length of the path."""
    x, at, rt, bd = [], [], [], []
    for s in doc["segments"]:
        x += s["along"]["s_m"]
        at += s["along"]["AT_m"]
        rt += s["along"]["RT_m"] or [np.nan] * len(s["along"]["AT_m"])
        bd += s["along"].get("bound_m") or [np.nan] * len(s["along"]["AT_m"])
    x, at, rt, bd = (np.asarray(v, float) for v in (x, at, rt, bd))
    first = {"AT (barycentre)": at * 1e3}
    if np.isfinite(bd).any():
        first["budget's bound"] = bd * 1e3
    return panels_plot(x * 1e3, [("AT [mm]", first), ("RT [mm]", {"RT": rt * 1e3})], path,
                       "arc length along the path [mm]", f"{doc['robot']}: path accuracy and repeatability")


def write_path_report(doc, out_dir) -> dict:
    """path_report.json, path_report.md and the two plots in ``out_dir``; {kind: path}."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files = {"json": str(out / "path_report.json"), "markdown": str(out / "path_report.md"),
             "plots": [str(plot_path(doc, out / "path.png")), str(plot_along(doc, out / "along.png"))]}
    md = ["# Path report", "", *[f"- {line}" for line in summary_lines(doc)], "",
          "ISO 9283 path characteristics (AT_p, RT_p: max over the stations; CR, CO: the corner at the segment's "
          "start, max over the cycles; AV, RV: of the mean speed; FV: max over the cycles):", "",
          table(HEADS, segment_rows(doc)), ""]
    if doc.get("refused"):
        md += [f"REFUSED: {doc['refused']}", ""]
    md += ["![path](path.png)", "", "![along](along.png)", ""]
    Path(files["markdown"]).write_text("\n".join(md))
    Path(files["json"]).write_text(dumps(doc, indent=1))
    return files
