"""Benchmark: accuracy reports on the paper's 7-DOF arm.

1. A campaign of 5 test poses x 30 cycles: read the CSV, register, evaluate, identify, write the
   Markdown/PNG/JSON/CSV report.
2. 100,000 streamed measurements at random configurations: two constant-memory passes over the CSV
   (registration sums, then evaluation with the budget check and the linearised identification), on
   one core; the peak traced memory of the evaluation (a separate tracemalloc run, which slows Python
   down and is therefore not timed) is printed for 10,000 and 100,000 rows to show it stays flat.

    python bench/bench_report.py [--rows 100000]
"""
import os

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")

import argparse  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
import tracemalloc  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout without installing
from machine import load_average, machine, verdicts  # noqa: E402
from tolerance_ros.core.accuracy.io import Measurements, read_csv, write_csv  # noqa: E402
from tolerance_ros.core.accuracy.evaluation import evaluate_file, stream_file  # noqa: E402
from tolerance_ros.core.accuracy.simulate import as_built_errors, measure  # noqa: E402
from tolerance_ros.core.budget import load_budget  # noqa: E402
from tolerance_ros.core.campaign import Campaign, TestPose  # noqa: E402
from tolerance_ros.core.models import load_robot  # noqa: E402
from tolerance_ros.core.geometry import transform  # noqa: E402
from tolerance_ros.render.accuracy_report import write_report  # noqa: E402


def synth(model, q, delta, path, labels=None):
    T = measure(model, q, as_built_errors(delta, 1), 1e-5, 1e-5, transform([1.5, 0.2, 0.1], [0, 0, 0.7]), seed=2)
    n = len(q)
    m = Measurements(np.arange(n) * 0.01, T, q, model.joint_names,
                     np.array(labels if labels is not None else [""] * n, dtype=object), np.full(n, -1))
    return write_csv(path, m)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rows", type=int, default=100000)
    args = ap.parse_args()
    print(f"machine: {machine()}; {load_average()} (before); one core")
    model = load_robot("gao2023_7dof")
    budget = load_budget("gao2023_delta2", model)
    delta = budget.vector_for(model)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        qk = model.sample_joints(5, 3)
        camp = Campaign("bench", [TestPose(f"P{i + 1}", joints=qk[i]) for i in range(5)], cycles=30)
        path = synth(model, np.tile(qk, (30, 1)), delta, tmp / "campaign.csv", [f"P{i % 5 + 1}" for i in range(150)])
        t0 = time.perf_counter()
        res = evaluate_file(model, read_csv(path), budget, camp)
        t1 = time.perf_counter()
        write_report(res, tmp / "report", model, budget)
        t2 = time.perf_counter()
        print(f"5 poses x 30 cycles: evaluate {1e3 * (t1 - t0):.1f} ms, write report with plots "
              f"{1e3 * (t2 - t1):.1f} ms, total {1e3 * (t2 - t0):.1f} ms")
        for rows in sorted({10000, args.rows}):
            p = synth(model, model.sample_joints(rows, 4), delta, tmp / f"stream{rows}.csv")
            t0 = time.perf_counter()
            out = stream_file(model, p, budget)
            dt = time.perf_counter() - t0
            tracemalloc.start()
            stream_file(model, p, budget)
            peak = tracemalloc.get_traced_memory()[1]
            tracemalloc.stop()
            v = out["summary"]["verdicts"]
            print(f"{rows} streamed measurements: {dt:.2f} s ({rows / dt:.0f} per s), peak traced memory "
                  f"{peak / 2**20:.1f} MiB; verdicts {v}")
    print(f"{load_average()} (after)")
    return verdicts([(dt <= 10 * rows / 100000,
                      f"{rows} streamed measurements in {dt:.2f} s (target: 100,000 in <= 10 s)")])


if __name__ == "__main__":
    sys.exit(main())
