"""`tolerance-ros verify`: Monte Carlo verification of a tolerance set, with the bounds of every criterion."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..core import analysis, errors
from ..core.budget import load_budget
from ..render.text import Progress, fmt, table
from .common import limit_option, load_model, missed

NAME = "verify"
HELP = "Monte Carlo verification of a tolerance set"
ROBOT = True


def add_arguments(p):
    p.add_argument("--tolerances", required=True, help="budget file (YAML/JSON) or shipped budget name")
    p.add_argument("--limit", help="position limit, e.g. 1.4mm (default: the budget's)")
    p.add_argument("--orientation-limit", help="orientation limit, e.g. 1mrad (default: the budget's)")
    p.add_argument("--samples", type=int, default=10000, help="Monte Carlo poses (default 10000)")
    p.add_argument("--seed", type=int, default=0, help="seed of the poses and the errors drawn (default 0)")
    p.add_argument("--errors", choices=analysis.DISTRIBUTIONS, default="extreme",
                   help="fixed: all at +delta (the paper); extreme: +-delta random signs; uniform; "
                        "normal: sigma = delta/3")
    p.add_argument("--signs", help="with --errors fixed: comma-separated parameters assembled at -delta")
    p.add_argument("--method", choices=["linear", "nonlinear"], default="linear",
                   help="first-order |J dx| or the exact perturbed forward kinematics")
    p.add_argument("--bounds", action="store_true", help="also report paper/worst-case/per-axis/RSS bounds")
    p.add_argument("--plot", metavar="DIR", help="write verify_error_histogram.png into DIR")


def run(args):
    model = load_model(args)
    budget = load_budget(args.tolerances, model)
    delta = budget.vector_for(model)
    limit = limit_option(model, args.limit, "length", "--limit") if args.limit else budget.limit_position
    olimit = (limit_option(model, args.orientation_limit, "angle", "--orientation-limit") if args.orientation_limit
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
        from ..render import plots as P
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
