"""The report of a calibration from contact (Markdown, mm and mrad as its headers say) and the JSON behind it (SI):
``calibration.json`` is the calibration's own document with the contact figures, ``fit.contact_rms_m``,
``validation.before/after.contact_rms_m`` and the rig with its uncertainties (``contact``)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..core.calibration.contact import ALIAS, INFLATION, TARGET_SHARE
from ..core.calibration.contact_campaign import contact_fit
from ..core.jsonio import dumps
from .text import fmt, table


def contact_document(cal) -> dict:
    """The JSON document of a contact calibration (SI)."""
    doc = cal.to_dict()
    doc["fit"] = contact_fit(cal)
    doc["contact"] = {"rig": cal.model.get("rig"), "held_why": cal.model.get("held_why"),
                      "targets_why": cal.model.get("targets_why"), "noise": cal.model.get("noise"),
                      "undetermined_rig": cal.model.get("undetermined_rig"), "rig_held": cal.model.get("rig_held"),
                      "nominal_targets_m": cal.model.get("nominal_targets"),
                      "nominal_fit_targets_m": cal.model.get("nominal_fit_targets")}
    return doc


def candidate_table(cal) -> str:
    """The candidates as cross-validated: held-out contact RMS with the folds' standard error and scatter (mm)."""
    rows = []
    for s in cal.model.get("candidates", []):
        if "cv_contact_rms_m" not in s:
            rows.append([s["label"], "-", "-", "-", "-", "-", f"failed: {s.get('error')}"])
            continue
        note = "chosen" if s.get("chosen") else ""
        if s.get("not_converged_folds"):
            note = ", ".join(x for x in (note, f"folds {s['not_converged_folds']} did not converge") if x)
        scatter = s.get("fold_scatter_m")
        rows.append([s["label"], s.get("estimated", "-"), fmt(s.get("effective_unknowns"), 3),
                     f"{s['cv_contact_rms_m'] * 1e3:.4f}", f"{s['standard_error_m'] * 1e3:.3f}",
                     "-" if scatter is None else f"{scatter * 1e3:.3f}", note])
    return table(["candidate", "parameters", "effective unknowns", "held-out RMS mm", "+- std error mm",
                  "folds' scatter mm", ""], rows)


def noise_line(cal) -> str:
    """Where the contact noise came from: the rows (robust, after the rig alone and after the parameters) or the
    command line."""
    n = cal.model.get("noise") or {}
    if not n:
        return f"noise: {cal.sigma * 1e3:.4g} mm (residual)"
    first = (f"given {n['rig_only_m'] * 1e3:.4g} mm (--noise)" if n.get("given") else
             f"{n['rig_only_m'] * 1e3:.4g} mm after the rig alone")
    return (f"contact noise (robust, from the rows): {first}, {n['after_parameters_m'] * 1e3:.4g} mm after the "
            f"parameters; uncertainties at the residual noise {n['residual_m'] * 1e3:.4g} mm")


def target_lines(cal) -> list:
    """Which target coordinates were fitted and why, grouped by reason."""
    why = cal.model.get("targets_why") or {}
    groups = {}
    for name, w in why.items():
        groups.setdefault((w["fitted"], w["kind"]), []).append(name)
    words = {(False, "copy"): "held at their nominal places, copies of the rig (a place along a plane touched "
                              "flush, a common height beside the plane's offset)",
             (False, "unseen"): f"held at their nominal places, the contacts hardly see them (std at the noise over "
                                f"{TARGET_SHARE * 100:g} % of their lever arm)",
             (False, "shared"): f"held at their nominal places, fitted they would share the contacts with the "
                                f"parameters (a parameter's std over {INFLATION:g} times larger)",
             (True, "seen"): f"fitted, the contacts see them well (std at the noise under {TARGET_SHARE * 100:g} % of "
                             f"their lever arm)",
             (True, "asked"): "fitted as asked (--fit-targets)",
             (True, "prior"): "fitted with a prior on their nominal places (--target-prior)"}
    return [f"targets {words.get(key, key[1])}: {', '.join(names)}" for key, names in groups.items()]


def elastic_lines(cal) -> list:
    """The joints' compliances of an elastic candidate: what loads them, and each joint's deflection at its largest
    load in the rows (mrad, mm for a prismatic joint), largest first."""
    e = cal.model.get("elastic")
    if not e:
        return []
    posture = (f"its {len(e['posture_from'])} other joints as recorded" if e.get("posture_from") else
               "its other joints at their neutral values (the rows have no columns for them)")
    out = [f"elastic joints, loaded by {e['load']} ({posture}); deflection at the largest load of the rows "
           f"(prior std {e['deflection_prior_rad'] * 1e3:g} mrad):"]
    joints = sorted(e["joints"], key=lambda j: -abs(j["deflection_rad"]))
    out.append("  " + ", ".join(f"{j['joint']} {j['deflection_rad'] * 1e3:+.3g} +- {j['deflection_std_rad'] * 1e3:.2g}"
                                f" at {j['largest_load']:.4g}" for j in joints)
               + " (mrad at N m; mm at N for a prismatic joint)")
    return out


def summary_lines(cal) -> list:
    """The figures as a person reads them: what was identified and how it was chosen, the noise, what was held and
    why, the targets, before and after."""
    v = cal.validation
    out = [f"robot {cal.robot}: {cal.measurements} contacts at {cal.poses} poses; identified "
           f"{cal.model.get('label')}; {cal.convergence.get('words', '')}",
           f"chosen by {cal.model.get('how')}" if cal.model.get("how", "").startswith("the ") else
           f"chosen: {cal.model.get('how')}", noise_line(cal),
           "candidates (" + v["method"] + "):"] + candidate_table(cal).split("\n")
    why = cal.model.get("held_why") or {}
    rig_held = [n for n, w in why.items() if w.startswith("a motion of the rig")]
    near = [n for n, w in why.items() if w.startswith("nearly a motion of the rig")]
    scale = [n for n, w in why.items() if w.startswith("the overall scale")]
    if scale:
        out.append(f"held for the scale (contact has no length standard): {', '.join(scale)}")
    if rig_held:
        out.append(f"held, invisible to contact (a motion of the rig): {', '.join(rig_held)}")
    if near:
        out.append(f"held, nearly a motion of the rig (under {ALIAS * 100:g} % of their effect is not): "
                   f"{', '.join(near)}")
    other = [n for n in cal.held if n not in rig_held and n not in scale and n not in near and n in why]
    if other:
        out.append(f"held, combinations of other parameters: {', '.join(other)}")
    if cal.model.get("undetermined_rig"):
        out.append(f"not determined by the contacts: {', '.join(cal.model['undetermined_rig'])}")
    out += elastic_lines(cal)
    out += target_lines(cal)
    rig = cal.model.get("rig") or {}
    for t in rig.get("targets", []):
        std = t.get("std_m") or [0, 0, 0]
        out.append(f"target {t['name']} in the tool frame: " + ", ".join(
            f"{a} {x * 1e3:+.4f} +- {s * 1e3:.4f}" for a, x, s in zip("xyz", t["xyz_m"], std)) + " mm")
    for p in rig.get("planes", []):
        out.append(f"plane {p['id']} (session {p['session']}): normal [{', '.join(f'{c:+.6f}' for c in p['normal'])}], "
                   f"offset {p['offset_m'] * 1e3:.4f} +- {(p['offset_std_m'] or 0) * 1e3:.4f} mm")
    for p in rig.get("points", []):
        std = p.get("std_m") or [0, 0, 0]
        out.append(f"point {p['id']} (session {p['session']}): " + ", ".join(
            f"{a} {x * 1e3:.4f} +- {s * 1e3:.4f}" for a, x, s in zip("xyz", p["xyz_m"], std)) + " mm")
    se = v.get("standard_error_m")
    out.append(f"contact RMS: fit {cal.position_rms * 1e3:.4f} mm; {v['method']}: before {v['before']['contact_rms_m'] * 1e3:.4f}"
               f" mm, after {v['after']['contact_rms_m'] * 1e3:.4f} mm"
               + (f" +- {se * 1e3:.3f}" if se is not None and np.isfinite(se) else "")
               + f" (max {v['after']['contact_max_m'] * 1e3:.4f} mm; {v['rows_scored']} of {v['rows']} rows scored)")
    for r in cal.rejected:
        out.append(f"rejected: {r['where']} ({r['contact']}, target {r['target']}): {r['reason']}")
    for w in cal.warnings:
        out.append(f"WARNING: {w}")
    for p in cal.plausibility["problems"]:
        out.append(f"REFUSED: {p}")
    return out


def write_contact_report(cal, out_dir, files=None) -> dict:
    """Write calibration.md and calibration.json into ``out_dir``; {kind: path}."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    (out / "calibration.json").write_text(dumps(contact_document(cal), indent=1) + "\n")
    lines = [f"# Calibration of {cal.robot} from contact", "",
             "Distances in mm: point to plane, or point to point (3-D). No tracker: the base frame is the robot's own.",
             ""] + [f"- {line}" for line in summary_lines(cal)] + [""]
    lines += ["| parameter | unit | error | std |", "|---|---|---|---|"]
    for n, k, v, s in zip(cal.names, cal.kinds, cal.dx, cal.std):
        if n not in cal.held:
            lines.append(f"| {n} | {'mm' if k == 'length' else 'mrad'} | {v * 1e3:+.4f} | {s * 1e3:.4f} |")
    for j in (cal.model.get("elastic") or {}).get("joints", []):
        lines.append(f"| {j['joint']}.compliance | mrad/(N m) | {j['compliance'] * 1e3:+.4g} | {j['std'] * 1e3:.4g} |")
    if files:
        lines += ["", "## Files", ""] + [f"- {k}: `{Path(f).name}`" for k, f in files.items()]
    (out / "calibration.md").write_text("\n".join(lines) + "\n")
    return {"json": str(out / "calibration.json"), "report": str(out / "calibration.md"), "plots": []}
