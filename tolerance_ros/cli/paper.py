"""`tolerance-ros paper`: reproduce a source paper's figures."""
from __future__ import annotations

from .common import CLIError

NAME = "paper"
HELP = "reproduce a source paper's figures"
ROBOT = False


def add_arguments(p):
    p.add_argument("name", help="gao2023 or rong2018")
    p.add_argument("--poses", type=int, default=10000, help="joint-space poses of the analysis and of the Monte Carlo checks (default 10000)")
    p.add_argument("--seed", type=int, default=2023, help="seed of the samples and the GA (default 2023)")
    p.add_argument("--plot", metavar="DIR", help="write the figures into DIR")
    p.add_argument("--no-synthesis", action="store_true", help="only the analysis, no allocation")
    p.add_argument("--ga-tol", type=int, default=1000, help="GA: Tol of section 4.3")


def run(args):
    from ..papers import gao2023, rong2018
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
