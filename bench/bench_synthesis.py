"""Benchmark: tolerance allocation on the paper's 7-DOF arm ([Delta] = 1.4 mm, the paper's floors, cost
model and criterion): the active-set solver against the paper's GA with Table 2 settings, and the
published sets, all verified the same way. The same study, with the same settings, as the synthesis
part of ``tolerance-ros paper gao2023`` (so the figures are the same); this script adds the machine,
the load and the targets, and exits 1 if a target is missed.

``--markdown`` also prints the study as the README's table (the README's figures come from it).

    python bench/bench_synthesis.py [--seed 2023] [--ga-tol 1000] [--markdown]
"""
from tolerance_ros.core.threads import cap_environment

cap_environment()

import argparse  # noqa: E402
import sys  # noqa: E402

from machine import load_average, machine, verdicts  # noqa: E402
from tolerance_ros.core.threads import limited  # noqa: E402
from tolerance_ros.papers import gao2023  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed", type=int, default=2023)
    ap.add_argument("--ga-tol", type=int, default=1000)
    ap.add_argument("--markdown", action="store_true", help="also print the README's synthesis table")
    args = ap.parse_args()
    print(f"machine: {machine()}; {load_average()} (before); BLAS threads: 1")
    with limited(1):
        syn = gao2023.synthesis_study(seed=args.seed, ga_options={"tol_runs": args.ga_tol})
    gao2023.print_synthesis(syn)
    best = syn["sets"]["active-set min-cost"]
    if args.markdown:
        print("\n" + gao2023.synthesis_markdown(syn))
    sup = best["verification"]["supremum"]["paper"]["position"]["value"]
    pass_rate = best["verification"]["monte_carlo"]["position_m"]["pass_rate"]
    print(f"\n{load_average()} (after)")
    return verdicts([
        (best["cost"] < 34459, f"active-set min-cost: cost {best['cost']:.0f} below the published delta_1's 34459"),
        (pass_rate == 1.0, f"active-set min-cost: Monte Carlo pass {pass_rate * 100:.2f} % (target 100 %)"),
        (sup <= 1.4e-3, f"active-set min-cost: searched supremum {sup * 1e3:.4f} mm <= 1.4 mm"),
        (best["time_s"] <= 30, f"active-set min-cost: solved in {best['time_s']:.1f} s <= 30 s")])


if __name__ == "__main__":
    sys.exit(main())
