"""Writes the human report of a calibration (Markdown and PNG plots) and the JSON behind it. Lengths in
mm and angles in mrad in the report, as its headers say; the JSON in SI."""
from __future__ import annotations

from pathlib import Path

from ..core.jsonio import dumps


def _mm(v):
    """A length (m) in mm or an angle (rad) in mrad, as text; '-' for None."""
    return "-" if v is None else f"{v * 1e3:.4f}"


def write_calibration_report(cal, out_dir, files=None) -> dict:
    """Write calibration.md, calibration.json, validation.png and parameters.png into ``out_dir``;
    ``files`` (kind -> path) are listed in the report. Returns {kind: path}."""
    from . import plots as P
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written = {"plots": [str(P.validation_before_after(cal.validation, out / "validation.png",
                                                       f"{cal.robot}: {cal.validation['method']}")),
                         str(P.identified_with_uncertainty(cal.names, cal.kinds, cal.dx, cal.std, set(cal.held),
                                                           out / "parameters.png"))]}
    (out / "calibration.json").write_text(dumps(cal.to_dict(), indent=1) + "\n")
    written["json"] = str(out / "calibration.json")
    v = cal.validation
    lines = [f"# Calibration of {cal.robot}", ""]
    if not cal.plausibility["ok"]:
        lines += ["**Refused** (written as `calibration.refused.yaml`, no calibrated robot file):", ""]
        lines += [f"- {p}" for p in cal.plausibility["problems"]] + [""]
    lines += [f"{cal.measurements} measurements at {cal.poses} test poses ({cal.sources.get('measurements', '')}); "
              f"registration '{cal.registration}'; "
              f"{'measured frames' if cal.has_orientation else 'measured points (no orientation)'}. Identified "
              f"{cal.model.get('label', 'the parameters')}: " + fit_summary(cal) + ".", "",
              "Every RMS here is of the 3-D position error; a per-axis figure says so.", "",
              "Held at nominal (not identifiable from these poses): " + (", ".join(cal.held) or "none") + ".", ""]
    if cal.warnings:
        lines += ["Warnings:", ""] + [f"- {w}" for w in cal.warnings] + [""]
    lines += ["## What to identify", "", f"{cal.model.get('how', '')}, compared on "
              f"{cal.model.get('compared_on', 'every measurement')}; {v['method']}.", "",
              "| candidate | unknowns | held-out RMS (3-D) [mm] | held-out max [mm] | |", "|---|---|---|---|---|"]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in candidate_rows(cal)]
    if cal.rejected or cal.suspect:
        lines += ["", "Measurements beyond the rejection threshold:", ""]
        lines += ["- " + line for line in row_lines(cal.rejected, "rejected") + row_lines(cal.suspect, "suspect")]
    if cal.load:
        lines += ["", f"Elastostatic term loaded by {cal.load.get('description', cal.load.get('model'))}."]
    rep = cal.repeatability or {}
    if rep:
        lines += ["", f"What is left: residual RMS (3-D) {_mm(rep['residual_rms_m'])} mm"
                  + (f" beside the repeat scatter of repeated poses {_mm(rep['scatter_m'])} mm; not explained by noise "
                     f"{_mm(rep['unexplained_m'])} mm." if rep.get("scatter_m") is not None else
                     "; no pose was repeated, so the noise floor is not measured.")]
    lines += ["", "## Validation on held-out poses", "", v["method"] + ".", "",
              "| | before | after |", "|---|---|---|"]
    lines += [f"| {a} | {b} | {c} |" for a, b, c in summary_rows(v)]
    lines += ["", f"Position error RMS (3-D, every measurement) reduced by {v['improvement'] * 100:.1f} %.", "",
              "![validation](validation.png)", "", "## Identified parameters", "",
              "| parameter | unit | error | std | abs(error)/std | absorbs (held parameters, first order) | note |",
              "|---|---|---|---|---|---|---|"]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in parameter_rows(cal)]
    b = cal.base
    lines += ["", f"Base correction: xyz [{', '.join(f'{x * 1e3:+.4f}' for x in b[:3])}] mm, rotation vector "
                  f"[{', '.join(f'{x * 1e3:+.4f}' for x in b[3:])}] mrad"
              + ("; it absorbs " + "; ".join(f"{k}: " + ", ".join(f"{c:+.4g} x {h}" for h, c in a.items())
                                             for k, a in cal.aliases.items() if k.startswith("base."))
                 if any(k.startswith("base.") for k in cal.aliases) else "") + ".", "",
              "![parameters](parameters.png)", ""]
    if files:
        lines += ["## Files", ""] + [f"- {k}: `{Path(f).name}`" for k, f in files.items()] + [""]
    (out / "calibration.md").write_text("\n".join(lines))
    written["report"] = str(out / "calibration.md")
    return written


def summary_rows(validation) -> list:
    """[[figure, before, after]] of a validation, mm and mrad: over every measurement, and over the kept ones
    beside when some were left out (each row named)."""
    rows = []
    kept = validation.get("kept_measurements")
    blocks = [("", "before", "after")]
    if kept is not None:
        blocks = [(f", all {validation['measurements']}", "before", "after"),
                  (f", kept {kept}", "before_kept", "after_kept")]
    for key, label in (("position_rms_m", "position RMS (3-D) [mm]"), ("position_max_m", "position max [mm]"),
                       ("orientation_rms_rad", "orientation RMS [mrad]"),
                       ("orientation_max_rad", "orientation max [mrad]"),
                       ("AP_p_mean_m", "AP_p mean [mm]"), ("AP_p_max_m", "AP_p max [mm]")):
        for suffix, bk, ak in blocks:
            b, a = validation[bk].get(key), validation[ak].get(key)
            if b is not None:
                rows.append([label + suffix, _mm(b), _mm(a)])
    return rows


def fit_summary(cal) -> str:
    """One sentence on the final fit: unknowns, equations, its 3-D residual RMS and max, the noise per axis,
    the condition number and how its loop ended."""
    from .text import length_text
    conv = cal.convergence or {}
    out = f"{cal.unknowns} unknowns from {cal.rows} equations"
    if cal.position_rms is not None:
        out += (f"; in-sample position RMS (3-D) {cal.position_rms * 1e3:.4f} mm, max {cal.position_max * 1e3:.4f} mm "
                f"over the kept measurements")
    out += f"; residual noise {length_text(cal.sigma)} per axis"
    if cal.fit_condition is not None and cal.fit_condition == cal.fit_condition:
        out += f"; condition number of the scaled fit {cal.fit_condition:.4g}"
    if conv.get("words"):
        out += f"; {conv['words']}"
    return out


def row_lines(rows, kind) -> list:
    """One line per rejected or suspect measurement."""
    return [f"{kind}: {r.get('where') or 'row ' + str(r['row'])}" + (f" (pose {r['pose']})" if r.get("pose") else "")
            + (f", target {r['target']}" if r.get("target") else "") + f": {r['reason']}" for r in rows]


def parameter_rows(cal) -> list:
    """[[name, unit, error, std, |error|/std, absorbs, note]] of the identified parameters (mm, mrad); the note
    says what the data cannot tell (set by the prior, a near-copy of another parameter)."""
    rows = []
    notes = getattr(cal, "undetermined", None) or {}
    for n, k, e, s in zip(cal.names, cal.kinds, cal.dx, cal.std):
        if n in cal.held:
            continue
        al = ", ".join(f"{c:+.4g} x {h}" for h, c in cal.aliases.get(n, {}).items())
        rows.append([n, "mm" if k == "length" else "mrad", f"{e * 1e3:+.5f}", f"{s * 1e3:.5f}",
                     f"{abs(e) / s:.1f}" if s > 0 else "-", al, "NOT DETERMINED: " + notes[n] if n in notes else ""])
    return rows


def candidate_rows(cal) -> list:
    """[[candidate, unknowns, held-out RMS mm, held-out max mm, chosen]] of the cross-validated candidates."""
    rows = []
    for s in cal.model.get("candidates", []):
        if "cv_position_rms_m" not in s:
            rows.append([s["label"], "-", "-", "-", f"failed: {s.get('error', '')}"])
            continue
        rows.append([s["label"], s["unknowns"], _mm(s["cv_position_rms_m"]), _mm(s["cv_position_max_m"]),
                     "chosen" if s["label"] == cal.model.get("label") else ""])
    return rows


def target_rows(cal) -> list:
    """[[target, x, y, z, std]] of the targets' points in the tool frame, mm."""
    std = cal.targets_std
    return [[n or "(tool point)"] + [f"{v * 1e3:.3f}" for v in X[:3, 3]]
            + ([", ".join(f"{s * 1e3:.3f}" for s in std[k])] if std is not None else ["-"])
            for k, (n, X) in enumerate(zip(cal.targets.names, cal.targets.X))]
