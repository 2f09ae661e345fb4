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
    lines = [f"# Calibration of {cal.robot}", "",
             f"{cal.measurements} measurements at {cal.poses} test poses ({cal.sources.get('measurements', '')}); "
             f"registration '{cal.registration}'. Identified {cal.unknowns - 6} parameter errors and the base "
             f"correction (6) from {cal.rows} equations; condition number of the scaled Jacobian "
             f"{cal.fit_condition:.1f}; residual noise {cal.sigma * 1e6:.2f} um (residual RMS "
             f"{cal.residual_rms_before * 1e3:.4f} mm before, {cal.residual_rms_after * 1e3:.4f} mm after the "
             f"fit).", "",
             "Held at nominal (not identifiable from these poses): " + (", ".join(cal.held) or "none") + ".", "",
             "## Validation on held-out poses", "", v["method"] + ".", "",
             "| | before | after |", "|---|---|---|"]
    lines += [f"| {a} | {b} | {c} |" for a, b, c in summary_rows(v)]
    lines += ["", f"Position error RMS reduced by {v['improvement'] * 100:.1f} %.", "",
              "![validation](validation.png)", "", "## Identified parameters", "",
              "| parameter | unit | error | std | abs(error)/std | absorbs (held parameters, first order) |",
              "|---|---|---|---|---|---|"]
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
    """[[figure, before, after]] of a validation, mm and mrad."""
    rows = []
    for key, label in (("position_rms_m", "position RMS [mm]"), ("position_max_m", "position max [mm]"),
                       ("orientation_rms_rad", "orientation RMS [mrad]"),
                       ("orientation_max_rad", "orientation max [mrad]"),
                       ("AP_p_mean_m", "AP_p mean [mm]"), ("AP_p_max_m", "AP_p max [mm]")):
        b, a = validation["before"][key], validation["after"][key]
        if b is not None:
            rows.append([label, _mm(b), _mm(a)])
    return rows


def parameter_rows(cal) -> list:
    """[[name, unit, error, std, |error|/std, absorbs]] of the identified parameters (mm, mrad)."""
    rows = []
    for n, k, e, s in zip(cal.names, cal.kinds, cal.dx, cal.std):
        if n in cal.held:
            continue
        al = ", ".join(f"{c:+.4g} x {h}" for h, c in cal.aliases.get(n, {}).items())
        rows.append([n, "mm" if k == "length" else "mrad", f"{e * 1e3:+.5f}", f"{s * 1e3:.5f}",
                     f"{abs(e) / s:.1f}" if s > 0 else "-", al])
    return rows
