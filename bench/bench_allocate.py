"""Benchmark: ``tolerance-ros allocate`` on a 38-parameter industrial arm, this checkout against an earlier
revision, in one run.

The robot is the ABB IRB 4600-60/2.05 written from its published dimensions
(``test/data/abb_irb4600/``: 42 parameters, 38 of them move the flange centre); the command is the
default allocation (min-cost, the exact worst case over every error sign) under each ``--limits``. The
earlier revision (``--before``, default the commit this benchmark's change started from) is unpacked from
git into a temporary folder; each side gets a kernel cache of its own, filled before the runs (a second
run, not a first after an install: ``bench_first_run.py`` measures that). The runs alternate, before then
after, ``--repeat`` times per limit, each a fresh process (``python -m tolerance_ros.cli allocate ...
--json``), and the table gives the median wall-clock and CPU seconds of each side, their ratio, and whether
the answers are the same: the largest relative difference of the tolerances and the cost index of both.
Target: the allocation in under 5 s (median wall-clock) on 2 cores; exits 1 when it is missed or when an
answer differs.

    python bench/bench_allocate.py [--limits 6mm,8mm,12mm] [--repeat 3] [--before REV] [--model min-cost]
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from machine import load_average, machine, verdicts  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
ROBOT = ROOT / "test" / "data" / "abb_irb4600" / "abb_irb4600_60_205.urdf"
BEFORE = "7d78c25"  # the commit before the pruned exact worst case of the active-set solver
WITHIN_S = 5.0


class Side:
    """One version of the package: its source folder and its own filled kernel cache."""

    def __init__(self, name, tree, cache):
        self.name, self.tree, self.cache = name, Path(tree), Path(cache)

    def env(self):
        return dict(os.environ, NUMBA_CACHE_DIR=str(self.cache), PYTHONPATH=str(self.tree))

    def fill(self):
        """Compile every kernel into this side's cache (the background child's work, in the foreground)."""
        subprocess.run([sys.executable, "-m", "tolerance_ros.core.models.warmup"], cwd=self.tree, env=self.env(),
                       stdout=subprocess.DEVNULL, check=True)

    def run(self, argv):
        """(wall s, CPU s, JSON document) of one command in a fresh process."""
        before = os.times()
        t0 = time.perf_counter()
        out = subprocess.run([sys.executable, "-m", "tolerance_ros.cli", *argv, "--json", "--quiet"], cwd=self.tree,
                             env=self.env(), capture_output=True, text=True)
        wall = time.perf_counter() - t0
        after = os.times()
        if out.returncode not in (0, 3):
            raise SystemExit(f"{self.name}: {' '.join(argv)} exited {out.returncode}: {out.stderr.strip()[-400:]}")
        cpu = (after.children_user - before.children_user) + (after.children_system - before.children_system)
        return wall, cpu, json.loads(out.stdout)


def tolerances(doc):
    return np.array([r["tolerance"] if r["tolerance"] is not None else 0.0 for r in doc["parameters"]])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--limits", default="6mm,8mm,12mm", help="comma-separated --limit values")
    ap.add_argument("--repeat", type=int, default=3, help="runs of each side per limit (medians)")
    ap.add_argument("--before", default=BEFORE, help=f"the earlier revision (default {BEFORE})")
    ap.add_argument("--model", default="min-cost", choices=["min-cost", "optimal-precision"])
    args = ap.parse_args()
    if args.repeat < 1:
        ap.error("--repeat: expected 1 or more")
    print(f"machine: {machine()}, {load_average()}")
    print(f"robot: {ROBOT.relative_to(ROOT)}; {args.model}, worst case; before = {args.before}, after = this checkout",
          flush=True)
    rows, results = [], []
    with tempfile.TemporaryDirectory() as tmp:
        tree = Path(tmp) / "before"
        tree.mkdir()
        archive = subprocess.run(["git", "archive", args.before], cwd=ROOT, capture_output=True, check=True).stdout
        subprocess.run(["tar", "-x", "-C", str(tree)], input=archive, check=True)
        sides = [Side("before", tree, Path(tmp) / "cache-before"), Side("after", ROOT, Path(tmp) / "cache-after")]
        for side in sides:
            side.fill()
        for limit in args.limits.split(","):
            argv = ["allocate", "--robot", str(ROBOT), "--limit", limit, "--model", args.model]
            runs = {side.name: [] for side in sides}
            for k in range(args.repeat):
                for side in sides:
                    runs[side.name].append(side.run(argv))
                print(f"  {limit} run {k + 1}: " + ", ".join(f"{name} {r[-1][0]:.2f} s" for name, r in runs.items()),
                      flush=True)
            (wb, cb), (wa, ca) = ([float(np.median([r[i] for r in runs[name]])) for i in (0, 1)]
                                  for name in ("before", "after"))
            docs = [r[2] for r in runs["before"] + runs["after"]]
            ref = tolerances(docs[0])
            diff = max(float(np.max(np.abs(tolerances(d) - ref) / np.where(ref > 0, ref, 1.0))) for d in docs)
            costs = sorted({d["cost_index"] for d in docs})
            rows.append((limit, wb, cb, wa, ca, wb / wa, diff, costs, docs[-1]["status"]))
            results.append((wa <= WITHIN_S, f"allocate --limit {limit}: {wa:.2f} s (target <= {WITHIN_S:g} s)"))
            results.append((diff <= 1e-9, f"allocate --limit {limit}: the same tolerances before and after "
                                           f"(largest relative difference {diff:.1e})"))
    print(f"\nmedians of {args.repeat} run(s) each, {load_average()} after")
    print("| --limit | before s (CPU s) | after s (CPU s) | speed-up | tolerances, largest relative difference | "
          "cost index | status |")
    print("|---|---|---|---|---|---|---|")
    for limit, wb, cb, wa, ca, ratio, diff, costs, status in rows:
        print(f"| {limit} | {wb:.2f} ({cb:.2f}) | {wa:.2f} ({ca:.2f}) | {ratio:.2f}x | {diff:.1e} | "
              f"{' / '.join(f'{c:.4f}' for c in costs)} | {status} |")
    return verdicts(results)


if __name__ == "__main__":
    sys.exit(main())
