"""``tolerance-ros``: the accuracy jobs from the command line, without ROS.

Every subcommand takes a robot (a shipped name such as ``gao2023_7dof``, or a YAML/URDF path), prints
a readable table (lengths in mm where the header says so), and with ``--json`` prints one JSON
document on stdout in SI units instead. Progress goes to stderr. Every length or angle option carries
its unit (``1.4mm``, ``0.3mrad``); a bare number is an error.

Exit codes: 0 done; 2 bad input (one line on stderr naming the option, file or field); 3 done, but
the target was not met (an allocation that misses its limit, a verification or a report with
errors over the limit; the last line on stderr says what failed); 1 an internal error (a bug).
"""
from __future__ import annotations

from .core.threads import cap_environment

cap_environment()  # before numpy loads: BLAS pools of one thread (see core/threads.py)

import argparse  # noqa: E402
import os  # noqa: E402
import re  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from .core import analysis, errors  # noqa: E402
from .core.accuracy.verdicts import describe  # noqa: E402
from .core.budget import load_budget  # noqa: E402
from .core.jsonio import dumps  # noqa: E402
from .core.models import load_robot  # noqa: E402
from .core.resources import ConfigNotFound, shipped  # noqa: E402
from .core.synthesis.problem import InfeasibleError  # noqa: E402
from .core.threads import limited  # noqa: E402
from .core.units import UnitError, parse_quantity  # noqa: E402
from .render.text import Progress, fmt, table  # noqa: E402

EXIT_OK, EXIT_INTERNAL, EXIT_INPUT, EXIT_TARGET_MISSED = 0, 1, 2, 3


class CLIError(Exception):
    """A user error reported as one line on stderr (and as a JSON error with --json)."""


class UsageError(CLIError):
    """An argument the parser cannot read (unknown option, missing value)."""


class Parser(argparse.ArgumentParser):
    """argparse, but a usage error becomes a UsageError (one line, or JSON with --json), not an exit."""

    def error(self, message):
        raise UsageError(f"{message} (see '{self.prog} --help')")


def quantity(text, kind, option, positive=True):
    """SI value of an option written with its unit (``1.4mm``); None stays None; CLIError otherwise."""
    if text is None:
        return None
    try:
        value = parse_quantity(text, kind, field=option)
    except UnitError as exc:
        raise CLIError(str(exc)) from None
    if positive and not value > 0:
        raise CLIError(f"{option}: must be > 0, got {text!r}")
    return value


def load_model(args):
    """The model of ``--robot`` (with ``--tip-link`` / ``--base-link``); says which tip it took when the
    choice was made for the user (a URDF whose only moving leaf link is the tip)."""
    model = load_robot(args.robot, getattr(args, "tip_link", None), getattr(args, "base_link", None))
    if getattr(model, "tip_chosen", False) and not args.quiet:
        print(f"robot {model.name}: tip link {model.tip_link!r}, the only leaf link the joints move "
              f"(choose another with --tip-link)", file=sys.stderr)
    return model


def missed(args, what: str):
    """Record that the run's target was not met (exit code 3; ``what`` is printed last on stderr)."""
    args.missed.append(what)


def _joints(args, model):
    if args.joints:
        rows = []
        for i, text in enumerate(args.joints):
            try:
                vals = [float(v) for v in text.replace(",", " ").split()]
            except ValueError:
                raise CLIError(f"--joints[{i}]: expected {model.dof} numbers separated by commas, got {text!r}") from None
            rows.append(vals)
        lens = {len(r) for r in rows}
        if lens != {model.dof}:
            raise CLIError(f"--joints: expected {model.dof} values per configuration "
                           f"({', '.join(model.joint_names)}), got {sorted(lens)}")
        q = np.array(rows)
        if args.deg:
            q = np.where([t == "revolute" for t in model.joint_types], np.deg2rad(q), q)
        return model.check_joints(q, "--joints", allow_out_of_limits=True)
    return model.sample_joints(args.random, args.seed)


# ---------------------------------------------------------------- subcommands


def cmd_robots(args):
    names = shipped("robots")
    out = []
    for n in names:
        try:
            m = load_robot(n)
            out.append({"name": n, "kind": type(m).__name__, "dof": m.dof, "parameters": m.n_params})
        except Exception as exc:  # a broken shipped file must not hide the others
            out.append({"name": n, "error": str(exc)})
    if args.json:
        return {"robots": out}
    print(table(["robot", "model", "dof", "parameters"],
                [[r["name"], r.get("kind", "error: " + r.get("error", "")), r.get("dof", ""), r.get("parameters", "")]
                 for r in out]))


def cmd_jacobian(args):
    model = load_model(args)
    q = _joints(args, model)
    T, EJ = model.fk_and_jacobian(q)
    outside = model.out_of_limits(q)
    if args.json:
        return {"robot": model.name, "joint_names": list(model.joint_names), "joints": q,
                "out_of_limits": outside.any(axis=1), "poses": T, "parameters": list(EJ.names),
                "units": list(EJ.units), "rows": ["dx", "dy", "dz", "drx", "dry", "drz"],
                "jacobian": EJ.J}
    for k in range(q.shape[0]):
        p = T[k, :3, 3] * 1e3
        flag = "  (outside joint limits)" if outside[k].any() else ""
        print(f"pose {k}: q = [{', '.join(f'{v:.4f}' for v in q[k])}]{flag}")
        print(f"  tool position [mm]: {p[0]:.3f} {p[1]:.3f} {p[2]:.3f}")
        rows = []
        for j, (n, u) in enumerate(zip(EJ.names, EJ.units)):
            col = EJ.J[k, :, j]
            rows.append([n, u] + [f"{v * 1e3:.5f}" for v in col[:3]] + [f"{v:.5f}" for v in col[3:]])
        print(table(["param", "unit", "dPx mm/u", "dPy mm/u", "dPz mm/u", "dRx rad/u", "dRy rad/u", "dRz rad/u"],
                    rows))


def cmd_sensitivity(args):
    model = load_model(args)
    limit = quantity(args.limit, "length" if args.rows == "position" else "angle", "--limit")
    prog = Progress("sensitivity", not args.quiet)
    prog(0, 1)
    sens = analysis.sensitivity(model, args.samples, args.seed, rows=args.rows, length_unit=args.length_unit)
    q, J = analysis.workspace_jacobian(model, args.samples, args.seed, rows=args.rows)
    R = analysis.correlation(J)
    pairs = analysis.correlated_pairs(R, model.param_names, args.correlation)
    ceil = analysis.ceilings(J, limit) if limit else None
    prog(1, 1)
    plots = []
    if args.plot:
        from .render import plots as P
        plots.append(str(P.salience_bars(sens, Path(args.plot) / "salience.png")))
    if args.json:
        out = sens.to_dict()
        out.update({"robot": model.name, "correlated_pairs": [{"parameters": [a, b], "rho": r} for a, b, r in pairs],
                    "correlation_threshold": args.correlation, "plots": plots})
        if ceil is not None:
            out["limit"] = limit
            out["ceilings"] = dict(zip(model.param_names, ceil))
        if args.correlation_matrix:
            out["correlation_matrix"] = R
        return out
    lu = args.length_unit
    scale = 1.0 / parse_quantity(f"1{lu}")
    print(f"robot {model.name}: sensitivity over {sens.samples} poses (seed {args.seed}), {args.rows} rows; "
          f"salience with lengths in {lu}")
    rows = []
    for j in np.argsort(-sens.salience, kind="stable"):
        u = model.param_units[j]
        shown = scale if args.rows == "position" and u == "rad" else 1.0
        per = "mm" if u == "m" else "rad"
        row = [model.param_names[j], (f"{lu}/{per}" if u == "rad" else "m/m") if args.rows == "position"
               else f"rad/{per}",
               fmt(sens.mu_mean[j] * shown), fmt(sens.mu_max[j] * shown), f"{sens.salience[j] * 100:.2f}"]
        if ceil is not None:
            c = ceil[j] / (parse_quantity(f"1{lu}") if u == "m" else 1.0)
            row.append(fmt(c) + (f" {lu}" if u == "m" else " rad"))
        rows.append(row)
    headers = ["param", "mu unit", "mu mean", "mu max", "D %"] + (["ceiling (eq.18)"] if ceil is not None else [])
    print(table(headers, rows))
    print(f"\ncorrelated column pairs (|rho| >= {args.correlation}):")
    print(table(["param i", "param j", "rho"], [[a, b, f"{r:+.3f}"] for a, b, r in pairs]) if pairs else "  none")
    for p in plots:
        print(f"plot: {p}")


def cmd_verify(args):
    model = load_model(args)
    budget = load_budget(args.tolerances, model)
    delta = budget.vector_for(model)
    limit = quantity(args.limit, "length", "--limit") if args.limit else budget.limit_position
    olimit = (quantity(args.orientation_limit, "angle", "--orientation-limit") if args.orientation_limit
              else budget.limit_orientation)
    signs = None
    if args.signs:
        signs = np.ones(model.n_params)
        for name in args.signs.split(","):
            name = name.strip()
            if name:
                signs[model.param_index([name.lstrip("-")])] = -1.0
    prog = Progress("verify", not args.quiet)
    ver = analysis.monte_carlo(model, delta, n=args.samples, distribution=args.errors, seed=args.seed,
                               limit_position=limit, limit_orientation=olimit, signs=signs, method=args.method,
                               chunk=max(1000, args.samples // 20), progress=prog)
    out = {"robot": model.name, "tolerances": str(args.tolerances), **ver.to_dict()}
    if args.bounds:
        J = model.error_jacobian(ver.q).position
        b = errors.bounds(J, delta)
        out["bounds_m"] = {k: analysis.summarize(v, limit) for k, v in b.items()}
    plots = []
    if args.plot:
        from .render import plots as P
        plots.append(str(P.error_histogram(ver.position, Path(args.plot) / "verify_error_histogram.png", limit,
                                           f"{model.name}: {args.errors} errors, {len(ver.position)} poses")))
    out["plots"] = plots
    for what, key, scale, unit in (("position", "position", 1e3, "mm"), ("orientation", "orientation", 1e3, "mrad")):
        summ = ver.summary[key]
        if summ.get("failures"):
            missed(args, f"{summ['failures']} of {summ['n']} poses exceed the {what} limit {summ['limit'] * scale:g} {unit} "
                         f"(largest error {summ['max'] * scale:.4f} {unit}, '{args.errors}' errors)")
    if args.json:
        return out
    s = ver.summary["position"]
    print(f"robot {model.name}, tolerances {args.tolerances}: {s['n']} poses (seed {args.seed}), "
          f"errors '{args.errors}', {args.method} model")
    rows = [["max", fmt(s["max"] * 1e3)], ["mean", fmt(s["mean"] * 1e3)], ["std", fmt(s["std"] * 1e3)]]
    rows += [[k, fmt(v * 1e3)] for k, v in s["percentiles"].items()]
    if limit is not None:
        rows.append([f"pass rate (<= {limit * 1e3:g} mm)", f"{s['pass_rate'] * 100:.2f} %"])
    print(table(["position error |dP|", "mm"], rows))
    o = ver.summary["orientation"]
    print(f"orientation error: max {o['max']:.3g} rad, mean {o['mean']:.3g} rad")
    if args.bounds:
        print("\nbounds over the same poses (max / mean, mm):")
        print(table(["criterion", "max", "mean"] + (["pass rate"] if limit else []),
                    [[k, fmt(v["max"] * 1e3), fmt(v["mean"] * 1e3)] + ([f"{v['pass_rate'] * 100:.2f} %"] if limit else [])
                     for k, v in out["bounds_m"].items()]))
    for p in plots:
        print(f"plot: {p}")


def _floors(args, model):
    floors = {"length": quantity(args.floor_length, "length", "--floor-length"),
              "angle": quantity(args.floor_angle, "angle", "--floor-angle")}
    for item in args.floor or []:
        if "=" not in item:
            raise CLIError(f"--floor: expected NAME=VALUE (e.g. theta1=0.2mrad), got {item!r}")
        name, value = item.split("=", 1)
        j = model.param_index([name.strip()])[0]
        floors[name.strip()] = quantity(value, model.param_kinds[j], f"--floor {name.strip()}")
    return floors


def cmd_allocate(args):
    from .core import synthesis
    from .core.errors import k_for_confidence
    model = load_model(args)
    limit = quantity(args.limit, "length", "--limit")
    olimit = quantity(args.orientation_limit, "angle", "--orientation-limit")
    k_sigma = k_for_confidence(args.confidence) if args.confidence is not None else 3.0
    prog = Progress(f"allocate ({args.solver})", not args.quiet)
    ga = {"tol_runs": args.ga_tol, "max_rounds": args.ga_rounds}
    res = synthesis.allocate(model, limit, args.model, args.solver, args.criterion, olimit, _floors(args, model),
                             k_sigma, seed=args.seed, n_mc=args.mc_poses, progress=prog,
                             solver_options=ga if args.solver == "ga" else None)
    doc = res.to_dict()
    doc["robot"] = model.name
    if args.out and args.out != "-":
        kinds = dict(zip(model.param_names, model.param_kinds))
        units = {"length": "mm", "angle": "rad"} if str(args.out).endswith((".yaml", ".yml")) else None
        doc["budget_file"] = str(res.budget().save(args.out, units=units, kinds=kinds))
    plots = []
    if args.plot:
        from .render import plots as P
        plots.append(str(_convergence_plot(P, res, Path(args.plot) / "allocate_convergence.png")))
        plots.append(str(P.error_histogram(res.mc_position, Path(args.plot) / "allocate_error_histogram.png", limit,
                                           f"{model.name}: {args.model} / {args.solver}, "
                                           f"{res.verification['monte_carlo']['distribution']} errors")))
    doc["plots"] = plots
    for what in res.shortfalls():
        missed(args, f"allocation does not meet its limit: {what}")
    if args.json:
        return doc
    print_allocation(doc)


def _convergence_plot(P, res, path):
    h = res.history
    if res.solver == "active-set":
        x = [r["iteration"] for r in h]
        final = max(abs(h[-1]["objective"]), 1e-300)
        objective = "cost index" if res.model_type == "min-cost" else "weighted sum of tolerances"
        return P.panels_plot(x, [(f"{objective} / its final value [-]",
                                  {"objective": np.abs([r["objective"] for r in h]) / final}),
                                 ("largest error in the check sample / limit [-]",
                                  {"check sample": [r["check_max_ratio"] for r in h]}),
                                 ("constraints (poses) [-]", {"constraints": [r["constraints"] for r in h]})],
                             path, "iteration", "active-set convergence")
    if h and "generation" in h[0]:
        return P.line_plot([r["generation"] for r in h], {"best fitness": [r["best_fitness"] for r in h]}, path,
                           "generation", "fitness: cost index + penalty [-]", "GA P1 convergence", logy=True)
    return P.line_plot([r["round"] for r in h], {"GA max error": [r["ga_max_error"] * 1e3 for r in h]}, path,
                       "round k", "largest error found by the GA [mm]", "GA section 4.3 rounds")


def print_allocation(doc):
    prob = doc["problem"]
    lim = prob["limit_position_m"]
    print(f"robot {doc['robot']}: {doc['model']} model, solver {doc['solver']}, criterion {prob['criterion']}, "
          f"limit {lim * 1e3:g} mm" + (f", orientation {prob['limit_orientation_rad']:g} rad"
                                       if prob["limit_orientation_rad"] else "") + f", seed {doc['seed']}")
    print(f"status: {doc['status']} ({doc['message']}); solved in {doc['time_s']:.2f} s\n")
    rows = []
    for r in doc["parameters"]:
        sc = 1e3 if r["unit"] == "m" else 1.0
        u = "mm" if r["unit"] == "m" else "rad"
        if r["free"]:
            rows.append([r["name"], u, "-", "-", "free (no effect)", "-", ""])
            continue
        flags = "floor" if r["at_floor"] else ("ceiling" if r["at_ceiling"] else "")
        grade = f"IT{r['iso_grade']} @ {r['nominal_size_mm']:g} mm" if r["iso_grade"] else "-"
        rows.append([r["name"], u, f"{r['floor'] * sc:.4f}", f"{r['ceiling'] * sc:.4f}", f"{r['tolerance'] * sc:.5f}",
                     grade, flags])
    print(table(["param", "unit", "floor", "ceiling Delta_j", "tolerance delta_j", "ISO 286", "at"], rows))
    print(f"\ncost index (eq. 17, mm and rad): {doc['cost_index']:.1f}    index I (eq. 21): {doc['index_I_m'] * 1e3:.4f} mm")
    ver = doc["verification"]
    print("\nsearched supremum over the joint space (position, mm):")
    print(table(["criterion", "supremum", "limit", "within"],
                [[c, f"{v['position']['value'] * 1e3:.4f}", f"{lim * 1e3:g}", "yes" if v["position"]["pass"] else "NO"]
                 for c, v in ver["supremum"].items()]))
    mc = ver["monte_carlo"]
    s = mc["position_m"]
    print(f"\nMonte Carlo, {mc['poses']} poses, '{mc['distribution']}' errors: pass {s['pass_rate'] * 100:.2f} %, "
          f"max {s['max'] * 1e3:.4f}, mean {s['mean'] * 1e3:.4f}, std {s['std'] * 1e3:.4f} mm")
    sc = ver["sign_control"]
    t = sc["position_m"]
    print(f"with the paper's sign control ({len(sc['pairs'])} correlated pairs, -delta on "
          f"{', '.join(sc['negative']) or 'none'}): max {t['max'] * 1e3:.4f}, mean {t['mean'] * 1e3:.4f}, "
          f"std {t['std'] * 1e3:.4f} mm")
    for w in doc["warnings"]:
        print(f"WARNING: {w}")
    print(f"budget saved: {doc['budget_file']}" if doc.get("budget_file")
          else "budget not saved (give --out FILE.yaml to save it)")
    for p in doc.get("plots", []):
        print(f"plot: {p}")


SKIPPED_SHOWN = 10  # skipped rows and records listed by `report` (--json lists them all)


def cmd_report(args):
    from .core.accuracy.evaluation import evaluate_file
    from .core.accuracy.io import read_measurements
    from .core.campaign import load_campaign
    from .render.accuracy_report import write_report
    model = load_model(args)
    budget = load_budget(args.budget, model) if args.budget else None
    campaign = load_campaign(args.campaign, model) if args.campaign else None
    if args.stream:
        from .core.accuracy.evaluation import stream_file
        if args.skip_bad:
            raise CLIError("--skip-bad: not available with --stream, which stops at the first bad row")
        if args.registration == "base+tool":
            raise CLIError("--stream: the tool offset needs all measurements at once; use --registration base")
        res = stream_file(model, args.measurements, budget, campaign, registration=args.registration)
        _over_limit(args, res["summary"])
        if args.json:
            return res
        s = res["summary"]
        print(f"robot {model.name}: {res['measurements']} measurements streamed from {res['source']}; "
              f"{describe(s['verdicts'], s['exceeded'])}; position error mean "
              f"{s['position_error_m']['mean'] * 1e3:.4f} mm, max {s['position_error_m']['max'] * 1e3:.4f} mm")
        return None
    meas = read_measurements(args.measurements, joint_names=model.joint_names, skip_bad=args.skip_bad)
    res = evaluate_file(model, meas, budget, campaign, registration=args.registration)
    _over_limit(args, res["summary"])
    files = write_report(res, args.out, model, budget) if args.out else {}
    body = {k: v for k, v in res.items() if k != "rows"}
    body["files"] = files
    if args.json:
        return body
    s = res["summary"]
    pe = s["position_error_m"]
    print(f"robot {model.name}: {res['measurements']} measurements from {res['source']}"
          + (f"; {len(meas.skipped)} skipped:" if meas.skipped else ""))
    for skip in meas.skipped[:SKIPPED_SHOWN]:
        print("  " + ", ".join(f"{k} {v}" for k, v in skip.items() if k != "reason") + f": {skip['reason']}")
    if len(meas.skipped) > SKIPPED_SHOWN:
        print(f"  ... and {len(meas.skipped) - SKIPPED_SHOWN} more (all of them in skipped_rows of --json)")
    print(f"registration {res['registration']['method']}: residual RMS {res['registration']['residual_rms_m'] * 1e3:.4f}"
          f" mm; position error mean {pe['mean'] * 1e3:.4f}, max {pe['max'] * 1e3:.4f} mm")
    if budget is not None:
        print(f"budget ({budget.criterion} bound): {describe(s['verdicts'], s['exceeded'])}")
    if res.get("per_pose"):
        rows = [[n, v["n"]] + ([f"{v[k] * 1e3:.4f}" for k in ("AP_p", "AP_a", "AP_b", "AP_c", "RP_l", "RP_a")]
                               if "AP_p" in v else ["-"] * 6) for n, v in res["per_pose"].items()]
        print(table(["pose", "n", "AP_p mm", "AP_a mrad", "AP_b mrad", "AP_c mrad", "RP_l mm", "RP_a mrad"], rows))
    ident = res.get("identification")
    if ident:
        oot = ident.get("out_of_tolerance", [])
        print(f"identification: {len(oot)} parameter(s) out of tolerance"
              + (": " + ", ".join(f"{o['name']} ({o['ratio']:.2f}x)" for o in oot) if oot else "")
              + (f"; not separable: {', '.join(ident['unidentifiable'])}" if ident.get("unidentifiable") else ""))
    for k, v in files.items():
        for f in (v if isinstance(v, list) else [v]):
            print(f"wrote {f}")


def _over_limit(args, summary):
    n = summary["verdicts"].get("over limit", 0)
    if n:
        what = ", ".join(f"{k} {v}" for k, v in summary["exceeded"].items() if "limit" in k and v)
        missed(args, f"{n} of {summary['measurements']} measurements over the design limit ({what})")


def _relative(path, start) -> str:
    """``path`` relative to the directory ``start`` when it lies at most two levels up from it (files that
    move together), else absolute."""
    target = Path(path).resolve()
    try:
        rel = os.path.relpath(target, Path(start).resolve())
    except ValueError:  # another drive
        return str(target)
    return rel if Path(rel).parts[:3] != (os.pardir,) * 3 else str(target)


def cmd_calibrate(args):
    from .core.accuracy.io import read_measurements
    from .core.calibration.calibrate import calibrate_measurements
    from .core.calibration.writers import save_calibration, write_calibrated_robot
    from .core.campaign import load_campaign
    from .render.calibration_report import parameter_rows, summary_rows, write_calibration_report
    model = load_model(args)
    noise = quantity(args.noise, "length", "--noise")
    onoise = quantity(args.orientation_noise, "angle", "--orientation-noise")
    if args.folds < 2:
        raise CLIError("--folds: must be >= 2")
    campaign = load_campaign(args.campaign, model) if args.campaign else None
    meas = read_measurements(args.measurements, joint_names=model.joint_names, skip_bad=args.skip_bad)
    prog = Progress("calibrate", not args.quiet)
    prog(0, 1)
    cal = calibrate_measurements(model, meas, campaign, args.registration, noise, onoise, args.folds, args.seed)
    prog(1, 1)
    out = Path(args.out)
    files = write_calibrated_robot(model, cal, out)
    source = getattr(model, "config_path", None) or getattr(model, "source", None)
    cal.sources.update({"robot": _relative(source, out) if source else model.name,
                        "measurements": _relative(args.measurements, out),
                        "campaign": (_relative(args.campaign, out) if campaign is not None
                                     and Path(args.campaign).is_file() else args.campaign),
                        "calibrated_robot": Path(files["robot"]).name})
    if hasattr(model, "tip_link"):  # a URDF chain: the links that choose it, to load the same chain again
        cal.sources.update(tip_link=model.tip_link, base_link=model.base_link)
    files["calibration"] = str(save_calibration(cal, out / "calibration.yaml"))
    written = write_calibration_report(cal, out, files)
    files.update(report=written["report"], json=written["json"], plots=written["plots"])
    v = cal.validation
    if v["after"]["position_rms_m"] >= v["before"]["position_rms_m"]:
        missed(args, f"hold-out validation: the calibrated model does not reduce the position error RMS "
                     f"({v['before']['position_rms_m'] * 1e3:.4f} mm before, {v['after']['position_rms_m'] * 1e3:.4f} "
                     f"mm after)")
    if args.json:
        doc = cal.to_dict()
        doc["files"] = files
        return doc
    print(f"robot {model.name}: {cal.measurements} measurements at {cal.poses} test poses from {meas.source}; "
          f"registration '{cal.registration}'")
    print(f"identified {cal.unknowns - 6} parameter errors and the base correction from {cal.rows} equations; "
          f"condition number {cal.fit_condition:.1f} (scaled); residual noise {cal.sigma * 1e6:.2f} um")
    print("held at nominal (not identifiable from these poses): " + (", ".join(cal.held) or "none"))
    print(table(["param", "unit", "error", "std", "|error|/std", "absorbs (first order)"], parameter_rows(cal)))
    print(f"\nvalidation: {v['method']}")
    print(table(["held-out poses", "before", "after"], summary_rows(v)))
    print(f"position error RMS reduced by {v['improvement'] * 100:.1f} %")
    for f in dict.fromkeys(files[k] for k in ("robot", "urdf", "calibration", "report", "json") if k in files):
        print(f"wrote {f}")
    for f in files["plots"]:
        print(f"plot: {f}")


def cmd_compensate(args):
    from .core.calibration.compensate import compensate
    from .core.calibration.writers import load_calibration
    from .core.campaign import load_campaign
    model = load_model(args)
    cal = load_calibration(args.calibration, model)
    calibrated = cal.mechanism(model)
    targets = load_campaign(args.targets, model)
    by_joints = [i for i, tp in enumerate(targets.poses) if tp.joints is not None]
    by_pose = [i for i, tp in enumerate(targets.poses) if tp.joints is None]
    results = [None] * len(targets.poses)
    for idx, kind in ((by_joints, "joints"), (by_pose, "pose")):
        if not idx:
            continue
        if kind == "joints":
            q = np.array([targets.poses[i].joints for i in idx])
            comp = compensate(calibrated, model, joints=model.check_joints(q, "targets"), match=args.match)
        else:
            comp = compensate(calibrated, model, poses=np.array([targets.poses[i].pose for i in idx]), match=args.match,
                              rng=args.seed)
        d = comp.to_dict()
        for k, i in enumerate(idx):
            results[i] = {"name": targets.poses[i].name, "target": kind, "nominal_joints": d["nominal_joints"][k],
                          "joints": d["joints"][k], "correction": d["correction"][k],
                          "residual_position_m": float(comp.residual_position[k]),
                          "residual_orientation_rad": float(comp.residual_orientation[k]),
                          "reached": bool(comp.reached[k]), "near_singularity": bool(comp.near_singularity[k]),
                          "out_of_limits": bool(comp.out_of_limits[k])}
    unreached = [r["name"] for r in results if not r["reached"]]
    if unreached:
        missed(args, f"{len(unreached)} target(s) out of reach of the calibrated robot: {', '.join(unreached)}")
    out_path = None
    if args.out:
        from .core.calibration.planning import campaign_dict
        doc = campaign_dict(model, np.array([r["joints"] for r in results]), f"{targets.name}_compensated",
                            targets.cycles, targets.dwell_s,
                            f"{targets.name} compensated with {Path(args.calibration).name} (tolerance-ros compensate)")
        for entry, r in zip(doc["poses"], results):
            entry["name"] = r["name"]
        out_path = Path(args.out)
        out_path.parent.mkdir(parents=True, exist_ok=True)
        import yaml
        out_path.write_text(yaml.safe_dump(doc, sort_keys=False, default_flow_style=None, width=120))
    if args.json:
        return {"robot": model.name, "calibration": str(args.calibration), "match": args.match,
                "joint_names": list(model.joint_names), "targets": results,
                "out_of_reach": unreached, "out": str(out_path) if out_path else None}
    rev = [t != "prismatic" for t in model.joint_types]

    def shown(v, per_rad, per_m):
        return ", ".join(f"{x * (per_rad if r else per_m):.4f}" for x, r in zip(v, rev))

    print(f"robot {model.name}, calibration {args.calibration}: {len(results)} targets ({args.match}); joints in deg "
          f"(prismatic mm), corrections in mdeg (prismatic um)")
    print(table(["target", "given", "compensated joints", "correction", "residual um", "flags"],
                [[r["name"], r["target"], shown(r["joints"], 180 / np.pi, 1e3),
                  shown(r["correction"], 18e4 / np.pi, 1e6), f"{r['residual_position_m'] * 1e6:.3g}",
                  ", ".join(f for f, on in (("out of reach", not r["reached"]),
                                            ("near singularity", r["near_singularity"]),
                                            ("out of limits", r["out_of_limits"])) if on)]
                 for r in results]))
    if out_path:
        print(f"wrote {out_path}")


def cmd_plan_campaign(args):
    from .core.calibration.planning import CRITERIA, REFERENCES, campaign_dict, plan
    from .core.campaign import load_campaign
    model = load_model(args)
    for name in ("candidates", "cycles"):
        if getattr(args, name) < 1:
            raise CLIError(f"--{name}: must be >= 1")
    noise = quantity(args.noise, "length", "--noise")
    onoise = quantity(args.orientation_noise, "angle", "--orientation-noise")
    delta = load_budget(args.budget, model).vector_for(model) if args.budget else None
    iso = load_campaign(args.compare, model).joints_for(model) if args.compare else None
    prog = Progress("plan-campaign", not args.quiet)
    prog(0, 1)
    pl = plan(model, args.n, args.criterion, args.candidates, args.seed, delta,
              noise / onoise if onoise else None, iso)
    prog(1, 1)
    out_path = Path(args.out or f"{model.name}_planned.yaml")
    idx = CRITERIA[args.criterion]
    desc = (f"{args.n} poses chosen by tolerance-ros plan-campaign: {idx} ({REFERENCES[idx]}) maximised by a DETMAX "
            f"exchange over {args.candidates} candidates within the joint limits (seed {args.seed})")
    import yaml
    out_path.parent.mkdir(parents=True, exist_ok=True)
    out_path.write_text(f"# {desc}\n" + yaml.safe_dump(campaign_dict(model, pl.q, f"{model.name}_planned", args.cycles,
                                                                        description=desc),
                                                         sort_keys=False, default_flow_style=None, width=120))
    plots = []
    if args.plot:
        from .render import plots as P
        plots.append(str(P.singular_values(pl.spectra, Path(args.plot) / "singular_values.png",
                                           f"{model.name}: scaled identification Jacobian")))
    if args.json:
        doc = pl.to_dict()
        doc.update(robot=model.name, campaign_file=str(out_path), plots=plots)
        return doc
    print(f"robot {model.name}: {args.n} poses maximising {idx} ({REFERENCES[idx]}) over {args.candidates} "
          f"candidates (seed {args.seed}, {pl.exchanges} exchanges); {len(pl.columns)} unknowns "
          f"({len(pl.columns) - 6} parameters + base), held: {', '.join(pl.held) or 'none'}")
    rows = []
    for label, d in (("planned", pl.chosen), (f"random (median of {pl.random['draws']})", pl.random),
                     ("ISO 9283 cube", pl.iso_cube)):
        if d is None:
            rows.append([label, "-", "-", "-", "-", "-", "-", "-"])
            continue
        rows.append([label, d.get("poses", args.n), f"{d['rank']}/{len(pl.columns)}", f"{d['O1'] * 1e3:.4g}",
                     f"{d['O2']:.4g}", f"{d['O3'] * 1e3:.4g}", f"{d['O4'] * 1e3:.4g}", f"{d['condition']:.4g}"])
    print(table(["pose set", "poses", "rank", "O1 mm", "O2", "O3 mm", "O4 mm", "condition"], rows))
    print(pl.iso_cube_note)
    print(f"wrote {out_path}")
    for f in plots:
        print(f"plot: {f}")


# ---------------------------------------------------------------- parser


def cmd_paper(args):
    from .papers import gao2023, rong2018
    if args.name == "gao2023":
        paper = gao2023
        res = gao2023.run(args.poses, args.seed, args.plot, not args.no_synthesis, args.ga_tol, args.quiet)
    elif args.name == "rong2018":
        paper = rong2018
        res = rong2018.run(args.seed, args.plot, not args.no_synthesis, args.quiet)
    else:
        raise CLIError(f"paper: unknown paper {args.name!r}; known: gao2023, rong2018")
    if args.json:
        return res
    paper.print_report(res)


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(prog="tolerance-ros", description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    def common(p, robot=True):
        if robot:
            p.add_argument("--robot", required=True, help="shipped robot name or YAML/URDF path")
            p.add_argument("--tip-link", help="URDF robots: the link the chain ends in (the tool)")
            p.add_argument("--base-link", help="URDF robots: the link the chain starts from (fixed to the root)")
        p.add_argument("--json", action="store_true", help="print one JSON document (SI units) on stdout")
        p.add_argument("--quiet", action="store_true", help="no progress on stderr")
        return p

    p = common(sub.add_parser("robots", help="list the shipped robot configs"), robot=False)
    p.set_defaults(func=cmd_robots)

    p = common(sub.add_parser("jacobian", help="nominal pose and parameter-error Jacobian at configurations"))
    p.add_argument("--joints", action="append", metavar="Q1,Q2,...",
                   help="a joint configuration (rad, m); repeat for several")
    p.add_argument("--deg", action="store_true", help="revolute joints in --joints are in degrees")
    p.add_argument("--random", type=int, default=1, metavar="N", help="N random configurations if no --joints")
    p.add_argument("--seed", type=int, default=0)
    p.set_defaults(func=cmd_jacobian)

    p = common(sub.add_parser("sensitivity", help="sensitivity, salience, ceilings and correlation"))
    p.add_argument("--samples", type=int, default=1000, help="joint-space samples (default 1000, as the paper)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--rows", choices=["position", "orientation"], default="position")
    p.add_argument("--length-unit", default="mm", help="length unit for salience and the table (default mm)")
    p.add_argument("--limit", help="design limit for the eq. 18 ceilings, e.g. 1.4mm")
    p.add_argument("--correlation", type=float, default=0.8, help="|rho| threshold for correlated pairs")
    p.add_argument("--correlation-matrix", action="store_true", help="include the full matrix in --json")
    p.add_argument("--plot", metavar="DIR", help="write salience.png into DIR")
    p.set_defaults(func=cmd_sensitivity)

    p = common(sub.add_parser("verify", help="Monte Carlo verification of a tolerance set"))
    p.add_argument("--tolerances", required=True, help="budget file (YAML/JSON) or shipped budget name")
    p.add_argument("--limit", help="position limit, e.g. 1.4mm (default: the budget's)")
    p.add_argument("--orientation-limit", help="orientation limit, e.g. 1mrad (default: the budget's)")
    p.add_argument("--samples", type=int, default=10000)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--errors", choices=analysis.DISTRIBUTIONS, default="extreme",
                   help="fixed: all at +delta (the paper); extreme: +-delta random signs; uniform; "
                        "normal: sigma = delta/3")
    p.add_argument("--signs", help="with --errors fixed: comma-separated parameters assembled at -delta")
    p.add_argument("--method", choices=["linear", "nonlinear"], default="linear",
                   help="first-order |J dx| or the exact perturbed forward kinematics")
    p.add_argument("--bounds", action="store_true", help="also report paper/worst-case/per-axis/RSS bounds")
    p.add_argument("--plot", metavar="DIR", help="write verify_error_histogram.png into DIR")
    p.set_defaults(func=cmd_verify)

    p = common(sub.add_parser("allocate", help="allocate tolerances under a design limit (precision synthesis)"))
    p.add_argument("--limit", required=True, help="position limit, e.g. 1.4mm")
    p.add_argument("--orientation-limit", help="orientation limit, e.g. 1mrad (optional)")
    p.add_argument("--model", choices=["min-cost", "optimal-precision"], default="min-cost")
    p.add_argument("--solver", choices=["active-set", "ga"], default="active-set",
                   help="active-set: exact convex method with adversarial pose search; ga: the paper's GA")
    p.add_argument("--criterion", choices=errors.LIMIT_CRITERIA, default="paper",
                   help="paper: |J delta|; worst-case: over every error sign; rss: statistical")
    p.add_argument("--confidence", type=float, help="rss confidence (default 0.9973, i.e. 3 sigma)")
    p.add_argument("--floor-length", default="0.05mm", help="floor of length tolerances (default 0.05mm)")
    p.add_argument("--floor-angle", default="0.0003rad", help="floor of angle tolerances (default 0.0003rad)")
    p.add_argument("--floor", action="append", metavar="NAME=VALUE", help="floor of one parameter, e.g. d2=0.02mm")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--mc-poses", type=int, default=10000, help="Monte Carlo verification poses")
    p.add_argument("--ga-tol", type=int, default=1000, help="GA: Tol of section 4.3 (max solves per round)")
    p.add_argument("--ga-rounds", type=int, default=50, help="GA: max rounds of section 4.3")
    p.add_argument("--out", help="budget file to write (.yaml in mm and rad, or .json in SI); none without it")
    p.add_argument("--plot", metavar="DIR",
                   help="write allocate_convergence.png and allocate_error_histogram.png into DIR")
    p.set_defaults(func=cmd_allocate)

    p = common(sub.add_parser("report", help="accuracy report of measured poses (ISO 9283, budget, identification)"))
    p.add_argument("--measurements", required=True, help="CSV file, campaign log (.jsonl) or rosbag2 (dir, .db3, .mcap)")
    p.add_argument("--budget", help="tolerance budget to check against")
    p.add_argument("--campaign", help="campaign with the test poses (ISO 9283 statistics per pose)")
    p.add_argument("--registration", choices=["base", "base+tool", "none"], default="base",
                   help="estimate the base (and tool) transform, or take measurements as base-frame")
    p.add_argument("--skip-bad", action="store_true", help="skip malformed rows (they are listed), instead of failing")
    p.add_argument("--out", metavar="DIR", help="write report.md, plots, JSON and CSV into DIR")
    p.add_argument("--stream", action="store_true", help="constant memory for large CSV files (summary only)")
    p.set_defaults(func=cmd_report)

    p = common(sub.add_parser("calibrate", help="calibrated robot file from measured poses, validated on "
                                                "held-out poses"))
    p.add_argument("--measurements", required=True,
                   help="CSV file, campaign log (.jsonl) or rosbag2 (dir, .db3, .mcap)")
    p.add_argument("--campaign", help="campaign with the test poses (joints of rows labelled by pose)")
    p.add_argument("--registration", choices=["base", "base+tool"], default="base",
                   help="estimate the tracker-to-base transform (and the tool offset)")
    p.add_argument("--noise", default="10um", help="tracker position noise, weights the rows (default 10um); the "
                                                   "uncertainties use the residual noise")
    p.add_argument("--orientation-noise", help="tracker orientation noise, e.g. 10urad: also fit orientations")
    p.add_argument("--folds", type=int, default=5, help="k of the k-fold validation by test pose (default 5)")
    p.add_argument("--seed", type=int, default=0, help="seed of the split into folds")
    p.add_argument("--skip-bad", action="store_true", help="skip malformed rows (they are listed), instead of failing")
    p.add_argument("--out", required=True, metavar="DIR",
                   help="write the calibrated robot file, calibration.yaml, calibration.md/.json and plots into DIR")
    p.set_defaults(func=cmd_calibrate)

    p = common(sub.add_parser("compensate", help="joints that put the calibrated robot's tool at each target"))
    p.add_argument("--calibration", required=True, help="calibration.yaml written by calibrate")
    p.add_argument("--targets", required=True, help="campaign file: test poses as nominal joints or as tool poses")
    p.add_argument("--match", choices=["pose", "position"], default="pose", help="match the whole pose or the position")
    p.add_argument("--seed", type=int, default=0, help="seed of the starts for tool-pose targets")
    p.add_argument("--out", metavar="FILE", help="write the compensated joints as a campaign file")
    p.set_defaults(func=cmd_compensate)

    p = common(sub.add_parser("plan-campaign", help="test poses that make the identification best conditioned"))
    p.add_argument("--n", type=int, default=30, help="number of test poses (default 30)")
    p.add_argument("--criterion", choices=["observability", "condition", "min-singular", "noise-amplification"],
                   default="observability",
                   help="observability: O1 (Borm & Menq 1991); condition: O2; min-singular: O3; "
                        "noise-amplification: O4 (Nahvi & Hollerbach 1996)")
    p.add_argument("--candidates", type=int, default=2000,
                   help="candidate poses within the joint limits (default 2000)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--cycles", type=int, default=3, help="visits per test pose in the campaign file (default 3)")
    p.add_argument("--budget", help="scale each parameter by its tolerance (default 1 mm / 1 mrad)")
    p.add_argument("--noise", default="10um", help="tracker position noise (default 10um)")
    p.add_argument("--orientation-noise",
                   help="tracker orientation noise, e.g. 10urad: the tracker measures orientation")
    p.add_argument("--compare", metavar="CAMPAIGN",
                   help="ISO 9283 cube campaign to compare with (default: built by IK)")
    p.add_argument("--out", metavar="FILE", help="campaign file to write (default <robot>_planned.yaml)")
    p.add_argument("--plot", metavar="DIR", help="write singular_values.png into DIR")
    p.set_defaults(func=cmd_plan_campaign)

    p = common(sub.add_parser("paper", help="reproduce a source paper's figures"), robot=False)
    p.add_argument("name", help="gao2023 or rong2018")
    p.add_argument("--poses", type=int, default=10000)
    p.add_argument("--seed", type=int, default=2023)
    p.add_argument("--plot", metavar="DIR", help="write the figures into DIR")
    p.add_argument("--no-synthesis", action="store_true", help="only the analysis, no allocation")
    p.add_argument("--ga-tol", type=int, default=1000, help="GA: Tol of section 4.3")
    p.set_defaults(func=cmd_paper)
    return parser


# ---------------------------------------------------------------- entry point


_NEGATIVE = re.compile(r"^-(\d|\.\d)")


def _attach_negative_values(argv, parser):
    """``--limit -1.4mm`` -> ``--limit=-1.4mm``, so that a negative value reaches the option's own check
    instead of being taken for an option."""
    takes_value = set()
    parsers = [parser] + [p for a in parser._actions if isinstance(a, argparse._SubParsersAction)
                          for p in a.choices.values()]
    for p in parsers:
        for a in p._actions:
            if a.option_strings and a.nargs is None:
                takes_value.update(a.option_strings)
    out, i = [], 0
    while i < len(argv):
        if argv[i] in takes_value and i + 1 < len(argv) and _NEGATIVE.match(argv[i + 1]):
            out.append(f"{argv[i]}={argv[i + 1]}")
            i += 2
        else:
            out.append(argv[i])
            i += 1
    return out


def error_code(exc) -> str:
    """The stable code of an error, as the services use them (not a Python class name)."""
    if isinstance(exc, ConfigNotFound) and exc.kind == "robots":
        return "unknown_robot"
    if isinstance(exc, InfeasibleError):
        return "infeasible"
    if isinstance(exc, (CLIError, ValueError, OSError, NotImplementedError)):
        return "invalid_request"
    return "internal"


def _message(exc) -> str:
    return str(exc.args[0]) if isinstance(exc, KeyError) and exc.args else str(exc)


def _fail(prog, code, message, as_json) -> int:
    if as_json:
        print(dumps({"ok": False, "error": {"code": code, "message": message}}))
    print(f"{prog}: error: {message}", file=sys.stderr)
    return EXIT_INTERNAL if code == "internal" else EXIT_INPUT


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    as_json = "--json" in argv
    parser = build_parser()
    try:
        args = parser.parse_args(_attach_negative_values(argv, parser))
        for name in ("samples", "poses", "random", "mc_poses", "ga_tol", "ga_rounds", "n"):
            if getattr(args, name, 1) is not None and getattr(args, name, 1) < 1:
                raise UsageError(f"--{name.replace('_', '-')}: must be >= 1")
    except UsageError as exc:
        return _fail(parser.prog, "invalid_request", str(exc), as_json)
    prog = f"{parser.prog} {args.command}"
    args.missed = []
    try:
        with limited(1):
            out = args.func(args)
        if as_json and out is not None:
            doc = {"ok": not args.missed, **out} if isinstance(out, dict) else out
            if args.missed and isinstance(doc, dict):
                doc["failed"] = list(args.missed)
            print(dumps(doc, indent=1))
    except BrokenPipeError:  # the reader (e.g. `| head`) went away: not an error of ours
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_OK
    except Exception as exc:  # every error is one line (and a JSON document with --json)
        code = error_code(exc)
        message = _message(exc) if code != "internal" else f"internal error (a bug): {type(exc).__name__}: {exc}"
        return _fail(prog, code, message, as_json)
    for what in args.missed:
        print(f"{prog}: FAILED: {what}", file=sys.stderr)
    return EXIT_TARGET_MISSED if args.missed else EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
