"""Benchmark: tolerance allocation on the paper's 7-DOF arm ([Delta] = 1.4 mm, the paper's floors, cost
model and criterion): the active-set solver against the paper's GA with Table 2 settings, and the
published sets, all verified the same way. The same study, with the same settings, as the synthesis
part of ``tolerance-ros paper gao2023`` (so the figures are the same); this script adds the machine,
the load and the targets, and exits 1 if a target is missed.

    python bench/bench_synthesis.py [--seed 2023] [--ga-tol 1000]
"""
from tolerance_ros.core.threads import cap_environment

cap_environment()

import argparse  # noqa: E402
import os  # noqa: E402
import platform  # noqa: E402
import sys  # noqa: E402

from tolerance_ros.core.threads import limited  # noqa: E402
from tolerance_ros.papers import gao2023  # noqa: E402


def machine() -> str:
    cpu = next((line.split(":", 1)[1].strip() for line in open("/proc/cpuinfo") if line.startswith("model name")),
               platform.processor())
    return f"{cpu}, {os.cpu_count()} cores, load average {' '.join(f'{x:.2f}' for x in os.getloadavg())}"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed", type=int, default=2023)
    ap.add_argument("--ga-tol", type=int, default=1000)
    args = ap.parse_args()
    print(f"machine: {machine()} (before); BLAS threads: 1")
    with limited(1):
        syn = gao2023.synthesis_study(seed=args.seed, ga_options={"tol_runs": args.ga_tol})
    gao2023.print_synthesis(syn)
    best = syn["sets"]["active-set min-cost"]
    checks = [("cost below the published delta_1's 34459", best["cost"] < 34459),
              ("100 % Monte Carlo pass", best["verification"]["monte_carlo"]["position_m"]["pass_rate"] == 1.0),
              ("searched supremum <= 1.4 mm", best["verification"]["supremum"]["paper"]["position"]["value"] <= 1.4e-3),
              ("solved in <= 30 s", best["time_s"] <= 30)]
    print(f"\nmachine: {machine()} (after)")
    print("targets (active-set min-cost): " + "; ".join(f"{name} {'met' if ok else 'NOT met'}" for name, ok in checks))
    return 0 if all(ok for _, ok in checks) else 1


if __name__ == "__main__":
    sys.exit(main())
