"""The report of a calibration from contact (Markdown, mm and mrad as its headers say) and the JSON behind it (SI):
``calibration.json`` is the calibration's own document with the contact figures, ``fit.contact_rms_m``,
``validation.before/after.contact_rms_m`` and the rig with its uncertainties (``contact``)."""
from __future__ import annotations

from pathlib import Path

from ..core.calibration.contact_campaign import contact_fit
from ..core.jsonio import dumps


def contact_document(cal) -> dict:
    """The JSON document of a contact calibration (SI)."""
    doc = cal.to_dict()
    doc["fit"] = contact_fit(cal)
    doc["contact"] = {"rig": cal.model.get("rig"), "held_why": cal.model.get("held_why"),
                      "undetermined_rig": cal.model.get("undetermined_rig"), "rig_held": cal.model.get("rig_held"),
                      "nominal_targets_m": cal.model.get("nominal_targets"),
                      "nominal_fit_targets_m": cal.model.get("nominal_fit_targets")}
    return doc


def summary_lines(cal) -> list:
    """The figures as a person reads them: what was identified, what was held and why, before and after."""
    v = cal.validation
    out = [f"robot {cal.robot}: {cal.measurements} contacts at {cal.poses} poses; identified "
           f"{cal.model.get('label')} ({cal.model.get('how')}); {cal.convergence.get('words', '')}",
           "candidates (held-out contact RMS, mm): " + ", ".join(
               f"{s['label']} {s['cv_contact_rms_m'] * 1e3:.4f}" if "cv_contact_rms_m" in s else
               f"{s['label']} failed ({s.get('error')})" for s in cal.model.get("candidates", []))]
    why = cal.model.get("held_why") or {}
    rig_held = [n for n, w in why.items() if w.startswith("a motion of the rig")]
    scale = [n for n, w in why.items() if w.startswith("the overall scale")]
    if scale:
        out.append(f"held for the scale (contact has no length standard): {', '.join(scale)}")
    if rig_held:
        out.append(f"held, invisible to contact (a motion of the rig): {', '.join(rig_held)}")
    other = [n for n in cal.held if n not in rig_held and n not in scale]
    if other:
        out.append(f"held, combinations of other parameters: {', '.join(other)}")
    if cal.model.get("undetermined_rig"):
        out.append(f"not determined by the contacts: {', '.join(cal.model['undetermined_rig'])}")
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
    out.append(f"contact RMS: fit {cal.position_rms * 1e3:.4f} mm; {v['method']}: before {v['before']['contact_rms_m'] * 1e3:.4f}"
               f" mm, after {v['after']['contact_rms_m'] * 1e3:.4f} mm (max {v['after']['contact_max_m'] * 1e3:.4f} mm; "
               f"{v['rows_scored']} of {v['rows']} rows scored)")
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
    if files:
        lines += ["", "## Files", ""] + [f"- {k}: `{Path(f).name}`" for k, f in files.items()]
    (out / "calibration.md").write_text("\n".join(lines) + "\n")
    return {"json": str(out / "calibration.json"), "report": str(out / "calibration.md"), "plots": []}
