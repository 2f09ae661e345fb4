"""`tolerance-ros allocate`: precision synthesis, tolerances under a design limit, verified independently."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..core import errors
from ..render.text import Progress, table
from .common import CLIError, limit_option, load_model, missed, quantity

NAME = "allocate"
HELP = "allocate tolerances under a design limit (precision synthesis)"
ROBOT = True


def add_arguments(p):
    p.add_argument("--limit", required=True, help="position limit, e.g. 1.4mm")
    p.add_argument("--orientation-limit", help="orientation limit, e.g. 1mrad (optional)")
    p.add_argument("--model", choices=["min-cost", "optimal-precision"], default="min-cost",
                   help="min-cost (the cheapest parts, default) or optimal-precision (the largest weighted tolerances)")
    p.add_argument("--solver", choices=["active-set", "ga"], default="active-set",
                   help="active-set: exact convex method with adversarial pose search; ga: the paper's GA")
    p.add_argument("--criterion", choices=errors.LIMIT_CRITERIA, default=errors.DEFAULT_LIMIT_CRITERION,
                   help="worst-case (default): over every error sign, guarantees the limit; paper: |J delta| "
                        "(Gao et al. 2023), lets errors of opposite effect cancel; rss: statistical")
    p.add_argument("--confidence", type=float, help="rss confidence (default 0.9973, i.e. 3 sigma)")
    p.add_argument("--floor-length", default="0.05mm", help="floor of length tolerances (default 0.05mm)")
    p.add_argument("--floor-angle", default="0.0003rad", help="floor of angle tolerances (default 0.0003rad)")
    p.add_argument("--floor", action="append", metavar="NAME=VALUE", help="floor of one parameter, e.g. d2=0.02mm")
    p.add_argument("--seed", type=int, default=0, help="seed of the joint-space samples and of the GA (default 0)")
    p.add_argument("--mc-poses", type=int, default=10000, help="Monte Carlo verification poses")
    p.add_argument("--ga-tol", type=int, default=1000, help="GA: Tol of section 4.3 (max solves per round)")
    p.add_argument("--ga-rounds", type=int, default=50, help="GA: max rounds of section 4.3")
    p.add_argument("--out", help="budget file to write (.yaml in mm and rad, or .json in SI); none without it")
    p.add_argument("--plot", metavar="DIR",
                   help="write allocate_convergence.png and allocate_error_histogram.png into DIR")


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


def run(args):
    from ..core import synthesis
    from ..core.errors import k_for_confidence
    model = load_model(args)
    limit = limit_option(model, args.limit, "length", "--limit")
    olimit = limit_option(model, args.orientation_limit, "angle", "--orientation-limit")
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
        from ..render import plots as P
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
    print(f"status: {doc['status']} ({doc['message']}); solved in {doc['time_s']:.2f} s")
    chk = doc["limit_check"]
    print(f"against the limit {lim * 1e3:g} mm: worst case {chk['worst_case_m'] * 1e3:.4f} mm "
          f"({'within' if chk['worst_case_within'] else 'EXCEEDS THE LIMIT'}), RSS {chk['rss_m'] * 1e3:.4f} mm, "
          f"Monte Carlo pass {chk['monte_carlo_pass_rate'] * 100:.2f} % of {chk['monte_carlo_poses']} poses "
          f"('{chk['monte_carlo_distribution']}' errors)")
    print()
    rows = []
    for r in doc["parameters"]:
        sc, u = 1e3, ("mm" if r["unit"] == "m" else "mrad")  # 0.05 mrad, not 0.0001 rad
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
          f"max {s['max'] * 1e3:.4f}, mean {s['mean'] * 1e3:.4f}, std {s['std'] * 1e3:.4f} mm (the same as "
          f"verify --samples {mc['poses']} --seed {mc['seed']} --errors {mc['distribution']} on these tolerances)")
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
