"""The written ISO 9283 test report: report.md, report.html, iso9283.json and the plots (drift against time,
vAP per test pose). Every figure is formatted once (``sections``), so the command's stdout, the Markdown and
the HTML print the same digits. Lengths in mm, angles in mrad, as the headers say."""
from __future__ import annotations

import html
from pathlib import Path

import numpy as np

from ..core.jsonio import dumps
from .path_report import HEADS, _mm, segment_rows, stops_line, weaving_line
from .plots import _legend_beside, _name_ticks, _plt, _save, _subplots, _tick_names_height, panels_plot

_mrad = _mm   # rad as mrad: the same scale and digits


def sections(doc) -> list:
    """[(title, note, headers, rows)] of the report, in its order; rows of strings."""
    ori = doc["orientation_measured"]
    out = []
    cond = doc["conditions"]
    out.append(("Test conditions", "as stated with the command (load, speed, temperature, measuring system) and as "
                "the data show", ["condition", "value"],
                [[k.replace("_", " "), str(v) if not isinstance(v, float) else f"{v:g}"] for k, v in cond.items()]
                or [["stated", "none (--load, --speed, --temperature, --measuring-system)"]]))
    if doc["pose"]:
        heads = ["pose", "n", "AP_p mm", "AP_x mm", "AP_y mm", "AP_z mm", "RP_l mm"]
        keys = ["AP_p", "AP_x", "AP_y", "AP_z", "RP_l"]
        if ori:
            heads += ["AP_a mrad", "AP_b mrad", "AP_c mrad", "RP_a mrad", "RP_b mrad", "RP_c mrad"]
            keys += ["AP_a", "AP_b", "AP_c", "RP_a", "RP_b", "RP_c"]
        fitted = doc["frame"]["lower_bound"]
        out.append(("Pose accuracy and repeatability (AP, RP)", "per test pose" + (
            "; AP fitted on the test poses, a lower bound (see the base frame)" if fitted else ""), heads,
                    [[p, v["n"]] + [_mm(v[k]) for k in keys] for p, v in doc["pose"].items()]))
    mdv = {p: v for p, v in doc["multidirectional"].items() if "vAP_p" in v}
    if mdv:
        heads = ["pose", "approaches", "vAP_p mm", "farthest pair"] + (
            ["vAP_a mrad", "vAP_b mrad", "vAP_c mrad"] if ori else [])
        out.append(("Multi-directional pose accuracy variation (vAP)", "the largest distance between the barycentres "
                    "of a test pose approached from different directions", heads,
                    [[p, ", ".join(f"{k} ({n})" for k, n in v["approaches"].items()), _mm(v["vAP_p"]),
                      " / ".join(v["pair"])] + ([_mrad(v[f"vAP_{a}"]) for a in "abc"] if ori else [])
                     for p, v in mdv.items()]))
    d = doc["distance"]
    if d:
        keys = ["p", "x", "y", "z"] + (["a", "b", "c"] if ori else [])
        unit = {k: "mrad" if k in "abc" else "mm" for k in keys}
        out.append((f"Distance accuracy and repeatability (AD, RD) between {d['between'][0]} and {d['between'][1]}",
                    f"{d['n']} cycles; commanded distance {_mm(d['D_c'])} mm, mean attained {_mm(d['D_bar'])} mm; "
                    "the visits paired by cycle", ["characteristic"] + [f"{k} {unit[k]}" for k in keys],
                    [["AD"] + [_mm(d[f"AD_{k}"]) for k in keys], ["RD"] + [_mm(d[f"RD_{k}"]) for k in keys]]))
    if doc["drift"]:
        heads = ["pose", "windows", "window s", "dAP_p mm", "dAP_p mm/h", "dRP_l mm", "dRP_l mm/h"] + (
            ["dAP_a mrad", "dAP_b mrad", "dAP_c mrad"] if ori else [])
        out.append(("Drift of pose characteristics (dAP, dRP)", "between the first and the last window, and per hour "
                    "between their mean stamps", heads,
                    [[p, len(v["windows"]), f"{v['window_s']:g}", _mm(v["dAP_p"]), _mm(v["dAP_p_per_h"]),
                      _mm(v["dRP_l"]), _mm(v["dRP_l_per_h"])] + ([_mrad(v[f"dAP_{a}"]) for a in "abc"] if ori else [])
                     for p, v in doc["drift"].items()]))
    ex = {p: v for p, v in doc["exchangeability"].items() if p != "sources"}
    if ex:
        out.append(("Exchangeability (E)", f"{next(iter(ex.values()))['robots']} robots of the type: this one and "
                    + ", ".join(doc["exchangeability"]["sources"]),
                    ["pose", "E mm", "x span mm", "y span mm", "z span mm"],
                    [[p, _mm(v["E"])] + [_mm(s) for s in v["spread"]] for p, v in ex.items()]))
    comp = {p: v for p, v in (doc.get("compliance") or {}).items() if "compliance_m_per_N" in v}
    if comp:
        def um(v):
            return "-" if v is None else f"{v * 1e6:.4f}"
        torques = any(v["compliance_rad_per_Nm"]["x"] is not None for v in comp.values())
        out.append(("Static compliance", "the displacement along a force per newton at the tool"
                    + (" and the turn about a torque's axis per newton metre" if torques else "")
                    + ", the least-squares slopes over the visits under loads along each axis of the base frame",
                    ["pose", "visits", "x mm/kN", "y mm/kN", "z mm/kN"]
                    + (["x mrad/kNm", "y mrad/kNm", "z mrad/kNm"] if torques else [])
                    + ["largest force N"] + (["largest torque Nm"] if torques else []) + ["residual RMS mm"],
                    [[p, v["n"]] + [um(v["compliance_m_per_N"][a]) for a in "xyz"]
                     + ([um(v["compliance_rad_per_Nm"][a]) for a in "xyz"] if torques else [])
                     + [f"{max(v['max_load'][k] for k in ('fx', 'fy', 'fz')):g}"]
                     + ([f"{max(v['max_load'][k] for k in ('mx', 'my', 'mz')):g}"] if torques else [])
                     + [_mm(v["residual_rms_m"])] for p, v in comp.items()]))
    path = doc.get("path")
    if path:
        out.append(("Path characteristics (AT, RT, CR, CO, AV, RV, FV)",
                    f"{path['cycles']} cycles from {path['source']}, latency {path['latency_s'] * 1e3:.3f} ms; "
                    "the figures of path-report", HEADS, segment_rows(path)))
    w = (path or {}).get("weaving")
    if w:
        out.append(("Weaving deviations (WS, WF)", weaving_line(w) + "; the stroke peak to peak across the weave's "
                    "line, the frequency over its whole periods but the first and the last",
                    ["cycle", "periods", "stroke mm", "commanded mm", "WS %", "frequency Hz", "commanded Hz", "WF %"],
                    [[k + 1, c["periods"], _mm(c["S_a_m"]), _mm(c["S_c_m"]), f"{c['WS'] * 100:+.2f}",
                      f"{c['F_a_hz']:.4f}", f"{c['F_c_hz']:.4f}", f"{c['WF'] * 100:+.3f}"]
                     for k, c in enumerate(w["cycles"])]))
    st = (path or {}).get("stops")
    if st and st["judged"]:
        out.append(("Pose stabilisation time and overshoot", stops_line(st) + "; on the command's clock, so give the "
                    "tracker's latency (--latency) where the robot lags its command", ["stop at s", "rest s",
                    "stabilisation ms", "overshoot mm", "note"],
                    [[f"{s['t_stop_s']:.3f}", f"{s['rest_s']:.3f}",
                      "-" if s["stabilisation_time_s"] is None else f"{s['stabilisation_time_s'] * 1e3:.1f}",
                      _mm(s["overshoot_m"]), s["note"] or ""] for s in st["stops"]]))
    if st and st["positioning"]:
        out.append(("Minimum positioning time", "per distance moved: from the instant the command leaves its rest to "
                    "the stabilisation at the next stop, the least over the moves of that distance",
                    ["distance mm", "moves", "minimum s", "mean s"],
                    [[f"{g['distance_m'] * 1e3:.1f}", g["moves"], f"{g['min_s']:.4f}", f"{g['mean_s']:.4f}"]
                     for g in st["positioning"]]))
    r = doc.get("reorientation")
    if r:
        heads = ["AT_p mm", "RT_p mm", "excursion mm", "AT_a mrad", "AT_b mrad", "AT_c mrad", "RT_a mrad", "RT_b mrad",
                 "RT_c mrad"]
        keys = ["AT_p_m", "RT_p_m", "excursion_m", "AT_a_rad", "AT_b_rad", "AT_c_rad", "RT_a_rad", "RT_b_rad",
                "RT_c_rad"]
        out.append(("Path accuracy on reorientation", f"{r['cycles']} cycles of the tool turning "
                    f"{np.degrees(r['turn_rad']):.1f} deg about its point, from {r['source']}, latency "
                    f"{r['latency_s'] * 1e3:.3f} ms; {r['stations']} stations at equal fractions of each turn",
                    heads, [[_mm(r[k]) for k in keys]]))
    if doc["missing"]:
        out.append(("Not in this report", "what each characteristic needs", ["characteristic", "needs"],
                    [[m["characteristic"], m["needs"]] for m in doc["missing"]]))
    return out


def _md_table(heads, rows) -> list:
    esc = [[str(c).replace("|", "\\|") for c in r] for r in [heads] + rows]
    return ["| " + " | ".join(esc[0]) + " |", "|" + "|".join("---" for _ in heads) + "|"] + \
        ["| " + " | ".join(r) + " |" for r in esc[1:]]


def _title(doc) -> str:
    if doc["campaign"] is None:
        return f"ISO 9283 test report: {doc['robot']}, the stream {doc['source']} alone"
    return (f"ISO 9283 test report: {doc['robot']}, campaign {doc['campaign']}, {doc['measurements']} measurements "
            + (f"({doc['under_load']} under load) " if doc.get("under_load") else "") + f"from {doc['source']}")


def write_iso9283_report(doc, out_dir) -> dict:
    """report.md, report.html, iso9283.json and the plots in ``out_dir``; {kind: path}."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    plots = []
    if doc["drift"]:
        plots.append(plot_drift(doc, out / "drift.png"))
    if any("vAP_p" in v for v in doc["multidirectional"].values()):
        plots.append(plot_vap(doc, out / "vap.png"))
    secs = sections(doc)
    md = [f"# {_title(doc)}", "", f"Base frame: {doc['frame']['words']}.", ""]
    md += [f"WARNING: {w}" for w in doc["warnings"]] + ([""] if doc["warnings"] else [])
    for title, note, heads, rows in secs:
        md += [f"## {title}", "", f"{note}.", ""] + _md_table(heads, rows) + [""]
    md += [f"![{p.stem}]({p.name})" for p in plots] + [""]
    h = ["<!DOCTYPE html>", "<html><head><meta charset='utf-8'>", f"<title>{html.escape(_title(doc))}</title>",
         "<style>body{font-family:sans-serif;max-width:70em;margin:2em auto}table{border-collapse:collapse}"
         "td,th{border:1px solid #999;padding:2px 8px;text-align:right}td:first-child{text-align:left}</style>",
         "</head><body>", f"<h1>{html.escape(_title(doc))}</h1>",
         f"<p><b>Base frame:</b> {html.escape(doc['frame']['words'])}.</p>"]
    h += [f"<p><b>WARNING:</b> {html.escape(w)}</p>" for w in doc["warnings"]]
    for title, note, heads, rows in secs:
        h += [f"<h2>{html.escape(title)}</h2>", f"<p>{html.escape(note)}.</p>", "<table>",
              "<tr>" + "".join(f"<th>{html.escape(str(c))}</th>" for c in heads) + "</tr>"]
        h += ["<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in r) + "</tr>" for r in rows]
        h.append("</table>")
    h += [f"<p><img src='{p.name}' alt='{p.stem}'></p>" for p in plots] + ["</body></html>"]
    files = {"markdown": str(out / "report.md"), "html": str(out / "report.html"), "json": str(out / "iso9283.json"),
             "plots": [str(p) for p in plots]}
    Path(files["markdown"]).write_text("\n".join(md))
    Path(files["html"]).write_text("\n".join(h) + "\n")
    Path(files["json"]).write_text(dumps(doc, indent=1))
    return files


def plot_drift(doc, path) -> Path:
    """AP_p and RP_l (mm) of each window against time (h), a line per test pose."""
    drift = doc["drift"]
    first = min(w["t_s"] for v in drift.values() for w in v["windows"])
    x = {p: (np.array([w["t_s"] for w in v["windows"]]) - first) / 3600.0 for p, v in drift.items()}
    if len({len(v) for v in x.values()}) == 1 and all(np.allclose(v, next(iter(x.values()))) for v in x.values()):
        xs = next(iter(x.values()))
        return panels_plot(xs, [("AP_p [mm]", {p: np.array([w["AP_p"] for w in v["windows"]]) * 1e3
                                               for p, v in drift.items()}),
                                ("RP_l [mm]", {p: np.array([w["RP_l"] for w in v["windows"]]) * 1e3
                                               for p, v in drift.items()})],
                           path, "time since the first window's visits [h]", f"{doc['robot']}: drift (ISO 9283)")
    plt = _plt()
    fig, axes = _subplots(plt, 2, 1, (7.0, 5.2), sharex=True)
    for p, v in drift.items():
        axes[0, 0].plot(x[p], [w["AP_p"] * 1e3 for w in v["windows"]], marker="o", label=p)
        axes[1, 0].plot(x[p], [w["RP_l"] * 1e3 for w in v["windows"]], marker="o", label=p)
    axes[0, 0].set_ylabel("AP_p [mm]")
    axes[1, 0].set_ylabel("RP_l [mm]")
    axes[1, 0].set_xlabel("time since the first window's visits [h]")
    axes[0, 0].set_title(f"{doc['robot']}: drift (ISO 9283)")
    _legend_beside(axes[0, 0])
    return _save(fig, plt, path)


def plot_vap(doc, path) -> Path:
    """Bars of vAP_p (mm) per test pose."""
    per = {p: v for p, v in doc["multidirectional"].items() if "vAP_p" in v}
    plt = _plt()
    width = min(14.0, max(6.0, 0.3 * len(per) + 3.0))
    fig, ((ax,),) = _subplots(plt, 1, 1, (width, 3.4 + _tick_names_height(per)))
    ax.bar(np.arange(len(per)), [v["vAP_p"] * 1e3 for v in per.values()], 0.6)
    _name_ticks(ax, list(per), width - 1.0)
    ax.set_ylabel("vAP_p [mm]")
    ax.set_title(f"{doc['robot']}: multi-directional pose accuracy variation")
    return _save(fig, plt, path)
