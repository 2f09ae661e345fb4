"""`tolerance-ros sensitivity`: sensitivity and salience over the workspace, eq. 18 ceilings, correlated parameter pairs."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..core import analysis
from ..core.units import parse_quantity
from ..render.text import Progress, fmt, table
from .common import SENSITIVITY_SAMPLES, check_cap, limit_option, load_model

OWN_CAPS = ("samples",)  # its own, smaller cap than verify's (SENSITIVITY_SAMPLES)

NAME = "sensitivity"
HELP = "sensitivity, salience, ceilings and correlation"
ROBOT = True


def add_arguments(p):
    p.add_argument("--samples", type=int, default=1000,
                   help=f"joint-space samples (default 1000, as the paper; at most {SENSITIVITY_SAMPLES})")
    p.add_argument("--seed", type=int, default=0, help="seed of the joint-space samples (default 0)")
    p.add_argument("--rows", choices=["position", "orientation"], default="position",
                   help="the error rows judged: position (default) or orientation")
    p.add_argument("--length-unit", default="mm", help="length unit for salience and the table (default mm)")
    p.add_argument("--limit", help="design limit for the eq. 18 ceilings, e.g. 1.4mm")
    p.add_argument("--correlation", type=float, default=0.8, help="|rho| threshold for correlated pairs")
    p.add_argument("--correlation-matrix", action="store_true", help="include the full matrix in --json")
    p.add_argument("--plot", metavar="DIR", help="write salience.png into DIR")


def run(args):
    check_cap(args.samples, "samples", SENSITIVITY_SAMPLES)
    model = load_model(args)
    limit = limit_option(model, args.limit, "length" if args.rows == "position" else "angle", "--limit")
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
        from ..render import plots as P
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
