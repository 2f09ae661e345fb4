"""Writes an accuracy report (Markdown, PNG plots, and the JSON and CSV behind them) from the dict of
``tolerance_ros.core.accuracy.evaluation.evaluate_file``. Lengths in mm and angles in mrad in the human
report, as its headers say; JSON and CSV in SI."""
from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from ..core.accuracy.verdicts import describe
from ..core.jsonio import dumps


def _plots(res, out, budget_delta, names):
    from . import plots as P
    files = []
    per = {k: v for k, v in res.get("per_pose", {}).items() if "AP_p" in v}
    if per:
        files.append(P.iso_per_pose(per, out / "error_per_pose.png"))
    rows = res.get("rows")
    if rows is not None and np.isfinite(rows["bound"]).any():
        files.append(P.error_vs_bound(rows["bound"], rows["error"], out / "error_vs_bound.png",
                                      rows.get("orientation_bound"), rows.get("orientation_error")))
    ident = res.get("identification")
    if ident and budget_delta is not None:
        errs = {p["name"]: p["error"] for p in ident["parameters"]}
        sel = [j for j, n in enumerate(names) if budget_delta[j] > 0 and n in errs]
        bad = set(ident.get("unidentifiable", []))
        files.append(P.identified_vs_tolerance([names[j] for j in sel],
                                               [abs(errs[names[j]]) / budget_delta[j] for j in sel],
                                               [names[j] in bad for j in sel], out / "identified_vs_tolerance.png"))
    return [str(f) for f in files]


def write_report(res, out_dir, model, budget=None) -> dict:
    """Write report.md, report.json, measurements.csv, per_pose.csv, identification.csv and plots."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    delta = budget.vector_for(model) if budget is not None else None
    files = {"plots": _plots(res, out, delta, list(model.param_names))}
    body = {k: v for k, v in res.items() if k != "rows"}
    (out / "report.json").write_text(dumps(body, indent=1) + "\n")
    files["json"] = str(out / "report.json")
    rows = res.get("rows")
    if rows is not None:
        with (out / "measurements.csv").open("w", newline="") as fh:
            w = csv.writer(fh)
            ori = "orientation_bound" in rows
            measured = rows.get("dphi") is not None
            names = res.get("targets", [""])
            named = len(names) > 1 or names[0]
            w.writerow(["stamp[s]", "pose"] + (["target"] if named else []) + ["dx[m]", "dy[m]", "dz[m]"]
                       + (["drx[rad]", "dry[rad]", "drz[rad]"] if measured else []) + ["error[m]", "bound[m]", "margin[m]"]
                       + (["orientation_error[rad]", "orientation_bound[rad]"] if ori else [])
                       + ["verdict", "exceeded"] + [f"joint:{n}" for n in model.joint_names])
            for i in range(len(rows["error"])):
                w.writerow([f"{rows['stamp'][i]:.6f}", rows["label"][i]] + ([names[rows["target"][i]]] if named else [])
                           + [f"{v:.9g}" for v in rows["dp"][i]]
                           + ([f"{v:.9g}" for v in rows["dphi"][i]] if measured else [])
                           + [f"{rows[k][i]:.9g}" for k in ("error", "bound", "margin")]
                           + ([f"{rows[k][i]:.9g}" for k in ("orientation_error", "orientation_bound")] if ori else [])
                           + [rows["verdict"][i], rows["exceeded"][i]] + [f"{v:.9g}" for v in rows["joints"][i]])
        files["measurements_csv"] = str(out / "measurements.csv")
    if res.get("per_pose"):
        keys = ["n", "AP_p", "AP_x", "AP_y", "AP_z", "RP_l"] + (["AP_a", "AP_b", "AP_c", "RP_a", "RP_b", "RP_c"]
                                                                if res.get("orientation_measured", True) else [])
        with (out / "per_pose.csv").open("w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["pose"] + [k + ("" if k == "n" else ("[m]" if k[-1] in "pxyzl" else "[rad]")) for k in keys])
            for name, v in res["per_pose"].items():
                w.writerow([name] + [v.get(k, "") for k in keys])
        files["per_pose_csv"] = str(out / "per_pose.csv")
    if res.get("identification"):
        with (out / "identification.csv").open("w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["parameter", "error[SI]", "std[SI]", "tolerance[SI]", "identifiable"])
            bad = set(res["identification"].get("unidentifiable", []))
            for j, p in enumerate(res["identification"]["parameters"]):
                tol = "" if delta is None or j >= len(delta) else f"{delta[j]:.9g}"
                w.writerow([p["name"], f"{p['error']:.9g}", f"{p['std']:.9g}", tol, p["name"] not in bad])
        files["identification_csv"] = str(out / "identification.csv")
    (out / "report.md").write_text(markdown(res, model, budget, files))
    files["markdown"] = str(out / "report.md")
    return files


def _registration_line(reg) -> str:
    what = {"base": "the base -> tracker transform estimated from all measurements",
            "base+tool": "the base -> tracker transform and each target's offset on the tool estimated from all "
                         "measurements",
            "none": "none: the measurements are taken as base-frame poses",
            "given": "a given base -> tracker transform"}[reg["method"]]
    line = (f"Registration: {what}; position residual RMS (3-D) {reg['residual_rms_m'] * 1e3:.4f} mm, "
            f"max {reg['residual_max_m'] * 1e3:.4f} mm.")
    if reg.get("targets_estimated"):
        line += " Targets in the tool frame (mm): " + "; ".join(
            f"{t['name'] or 'tool point'} [{', '.join(f'{v * 1e3:.3f}' for v in t['xyz_m'])}]" for t in reg["targets"]) + "."
    return line


def markdown(res, model, budget, files) -> str:
    s = res["summary"]
    L = [f"# Accuracy report: {model.name}", "", f"Measurements: {res['measurements']} from `{res['source']}`"
         + (f"; {len(res['skipped_rows'])} measurements skipped (each with its reason in report.json)" if res["skipped_rows"] else ""),
         ""]
    ident = res.get("identification") or {}
    if budget is not None and ident.get("groups"):
        L += [f"Parts are judged against the budget by the {ident['groups']['rule_words']}.", ""]
    L += ["## Registration", "", _registration_line(res["registration"]), ""]
    pe = s["position_error_m"]
    oe = s.get("orientation_error_rad")
    L += ["## Errors (base frame, after registration, at each measured target)", "",
          f"Position error: mean {pe['mean'] * 1e3:.4f} mm, std {pe['std'] * 1e3:.4f} mm, max {pe['max'] * 1e3:.4f} mm."
          + (f" Orientation error: mean {oe['mean'] * 1e3:.4f} mrad, max {oe['max'] * 1e3:.4f} mrad." if oe else
             " The measurements are points: no orientation was measured."), ""]
    for w in res.get("warnings", []):
        L += [f"**Warning:** {w}", ""]
    if res.get("left_out"):
        L += ["Left out of the registration and the verdicts:", ""]
        L += [f"- {r['where']}: {r['reason']}" for r in res["left_out"]] + [""]
    if res["registration"].get("left_out"):
        L += ["Not used by the registration (judged as measured):", ""]
        L += [f"- {r['where']}: {r['reason']}" for r in res["registration"]["left_out"]] + [""]
    if budget is not None:
        limits = [f"position {budget.limit_position * 1e3:g} mm" if budget.limit_position else None,
                  f"orientation {budget.limit_orientation * 1e3:g} mrad" if budget.limit_orientation else None]
        L += ["## Budget check", "",
              f"Budget criterion '{budget.criterion}', limits {', '.join(x for x in limits if x) or 'none'}: "
              f"{describe(s['verdicts'], s['exceeded'])}.", ""]
    if res.get("per_pose"):
        L += ["## ISO 9283 per test pose (mm, mrad)", "",
              "| pose | n | AP_p | AP_x | AP_y | AP_z | AP_a | AP_b | AP_c | RP_l | RP_a | RP_b | RP_c |",
              "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
        for name, v in res["per_pose"].items():
            if "AP_p" not in v:
                L.append(f"| {name} | {v['n']} | " + " | ".join(["-"] * 11) + " |")
                continue
            L.append(f"| {name} | {v['n']} | " + " | ".join(
                f"{v[k] * 1e3:.4f}" if v[k] is not None else "-" for k in ("AP_p", "AP_x", "AP_y", "AP_z", "AP_a",
                                                                             "AP_b", "AP_c", "RP_l", "RP_a", "RP_b",
                                                                             "RP_c")) + " |")
        L.append("")
    ident = res.get("identification")
    if ident:
        L += ["## Identified parameter errors", "",
              f"Rank {ident.get('rank', '-')} of {ident.get('unknowns', '-')} unknowns"
              + (f", condition {ident['condition']:.3g}" if "condition" in ident else "")
              + f"; residual RMS per axis {ident['residual_rms_before_m'] * 1e3:.4f} mm"
              + (f" -> {ident['residual_rms_after_m'] * 1e3:.4f} mm" if "residual_rms_after_m" in ident else "") + ".",
              ""]
        if ident.get("unidentifiable"):
            L += [f"Not separable from others with these poses: {', '.join(ident['unidentifiable'])}.", ""]
        grp = ident.get("groups")
        oot = ident.get("out_of_tolerance", [])
        if grp:
            L += ["### What the data can see, against the budget", ""] + budget_lines(grp)
            if grp.get("absorbed_by_registration"):
                L += ["", "Absorbed by the registration (no campaign sees them): "
                      + ", ".join(grp["absorbed_by_registration"]) + "."]
            if grp.get("not_seen"):
                L += ["", "Not seen by these measurements: " + ", ".join(grp["not_seen"]) + "."]
            L.append("")
        elif oot:
            L += [f"Proven out of tolerance (decision rule {ident.get('decision_rule')}):", "",
                  "| parameter | identified | u | tolerance | ratio |", "|---|---|---|---|---|"]
            for o in oot:
                unit = "mm" if model.param_kinds[model.param_names.index(o["name"])] == "length" else "mrad"
                L.append(f"| {o['name']} | {o['error'] * 1e3:+.4f} {unit} | {o['std'] * 1e3:.4f} {unit} | "
                         f"{o['tolerance'] * 1e3:.4f} {unit} | {o['ratio']:.2f} |")
            L.append("")
        elif budget is not None:
            L += [f"No identifiable parameter is proven out of tolerance (decision rule "
                  f"{ident.get('decision_rule')}).", ""]
    if files.get("plots"):
        L += ["## Plots", ""] + [f"![{Path(p).stem}]({Path(p).name})" for p in files["plots"]] + [""]
    return "\n".join(L)


def budget_lines(grp) -> list:
    """Markdown lines of the parts judged against a budget (``conformity.judged``): the rule, the counts and one
    table row per group."""
    return ["Each estimated parameter measures itself plus the held parameters it absorbs (to first order); the "
            "group's tolerance is the worst case of its members' tolerances, so that a fault in any of them shows. "
            f"Its decision accounts for the estimate's standard uncertainty: {grp['rule_words']}.", "",
            "Decisions: " + decision_counts(grp["counts"]) + ".", "",
            "| group | unit | error | u | tolerance | abs(error)/tolerance | decision |", "|---|---|---|---|---|---|---|"] \
        + ["| " + " | ".join(r) + " |" for r in group_rows(grp["groups"])] \
        + ["", "Not determined by these data (undecided whatever they read):", ""] * any(g.get("note") for g in
                                                                                      grp["groups"]) \
        + [f"- {group_text(g)}: {g['note']}" for g in grp["groups"] if g.get("note")]


def decisions_text(grp, what: str) -> str:
    """``what`` (e.g. 'identification against the budget'), the counts of the decisions and the rule in one line,
    then the table of the parts decided out or undecided (mm, mrad), for a terminal."""
    from .text import table
    lines = [f"{what}: {decision_counts(grp['counts'])}; {grp['rule_words']}"]
    shown = [r for r, g in zip(group_rows(grp["groups"]), grp["groups"]) if g["decision"] in ("out", "undecided")]
    if shown:
        lines.append(table(["group", "unit", "error", "u", "tolerance", "|error|/tol", "decision"], shown))
    return "\n".join(lines)


def decision_counts(counts: dict) -> str:
    """'1 out, 2 undecided, 17 within, 2 free' (the decisions that occur)."""
    return ", ".join(f"{n} {k}" for k, n in counts.items() if n) or "none"


def group_rows(groups) -> list:
    """[[group, unit, error, u, tolerance, ratio, decision]] of ``conformity.parameter_groups``, in mm or mrad by
    the group's first member; a part the budget leaves free has tolerance 'free'."""
    rows = []
    for g in groups:
        unit = "mm" if g["unit"] == "m" else "mrad"
        free = not np.isfinite(g["tolerance"])
        rows.append([group_text(g), unit, f"{g['error'] * 1e3:+.4f}", f"{g['std'] * 1e3:.4f}",
                     "free" if free else f"{g['tolerance'] * 1e3:.4f}",
                     "-" if free or not np.isfinite(g["ratio"]) else f"{g['ratio']:.2f}", g["decision"]])
    return rows


def group_text(group) -> str:
    """'a6 - 0.09112 x theta6': a group's combination of the members that matter (coefficients in SI ratios)."""
    parts = []
    for k, name in enumerate(group["parameters"]):
        c = group["coefficients"][name]
        parts.append(name if k == 0 else f"{'-' if c < 0 else '+'} {abs(c):.4g} x {name}")
    return " ".join(parts)
