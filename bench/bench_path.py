"""Benchmark of the path report at scale: a 10-minute run of the paper's arm (as built within gao2023_delta2)
driving the ISO 9283 rectangle at 0.2 m/s, seen by a 1 kHz tracker 8 ms late (about 600,000 points) against
500 Hz joint states (about 300,000), written as the two CSV files ``path-report`` reads.

- offline: the files read and the report computed (``read_points``, ``read_joint_states``, ``path_report``),
  wall time (target: under 10 s);
- on line: the same streams fed to the ROS-free monitor (``services.path_monitor.PathMonitor``) in batches of
  0.1 s of data as they would arrive, its CPU time against the 600 s they span (target: under it, so that it
  never falls behind for long), the slowest batch and the figures it reports when the last path ends, side by
  side with the offline ones.

Prints the machine and its load average and a verdict per target; exits 1 when a target is missed.

    python bench/bench_path.py [--minutes 10]
"""
import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))
from machine import load_average, machine, verdicts  # noqa: E402
from tolerance_ros.core.accuracy.io.joint_states import (read_joint_states, read_points,  # noqa: E402
                                                        write_joint_states, write_points)
from tolerance_ros.core.accuracy.iso_paths import plan_path  # noqa: E402
from tolerance_ros.core.accuracy.path_report import path_report  # noqa: E402
from tolerance_ros.core.accuracy.simulate import as_built_errors, path_streams  # noqa: E402
from tolerance_ros.core.budget import load_budget  # noqa: E402
from tolerance_ros.core.geometry import transform  # noqa: E402
from tolerance_ros.core.models import load_robot  # noqa: E402
from tolerance_ros.render.text import table  # noqa: E402
from tolerance_ros.services.path_monitor import PathMonitor  # noqa: E402

KEYS = (("latency_s", "latency ms", 1e3), ("AT_p_m", "AT_p mm", 1e3), ("RT_p_m", "RT_p mm", 1e3),
        ("CR_m", "CR mm", 1e3), ("CO_m", "CO mm", 1e3), ("AV", "AV %", 1e2), ("RV", "RV %", 1e2),
        ("FV_m_s", "FV mm/s", 1e3))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--minutes", type=float, default=10.0)
    args = ap.parse_args()
    model = load_robot("gao2023_7dof")
    model.fk(model.sample_joints(4, 0))
    budget = load_budget("gao2023_delta2", model)
    dx = as_built_errors(budget.vector_for(model), 3)
    one, _ = plan_path(model, "rectangle", speed=0.2, cycles=1, q_center=np.radians([0, 45, 0, 60, 0, 30, 0]))
    jp, _ = plan_path(model, "rectangle", speed=0.2, cycles=max(1, int(args.minutes * 60 / one.period)),
                      q_center=np.radians([0, 45, 0, 60, 0, 30, 0]))
    st = path_streams(model, jp, dx, transform([1.5, -0.3, 0.2], [0.05, -0.02, 1.2]), latency=0.008, noise=10e-6,
                      seed=1, repeatability=1e-4)
    print(f"machine: {machine()}; {load_average()}")
    print(f"run: {jp.duration:.0f} s, {jp.cycles} cycles of the rectangle at 0.2 m/s; {len(st.stamps):,} tracker "
          f"points (1 kHz, 8 ms late, 10 um noise), {len(st.joint_stamps):,} joint states (500 Hz)")
    with tempfile.TemporaryDirectory() as d:
        pts, js = Path(d) / "path.csv", Path(d) / "path.joints.csv"
        write_points(pts, st.stamps, st.points)
        write_joint_states(js, st.joint_stamps, st.joints, model.joint_names)
        t0 = time.perf_counter()
        tm, pm, _ = read_points(pts)
        tj, qj = read_joint_states(js, model.joint_names)
        t1 = time.perf_counter()
        off = path_report(model, tm, pm, tj, qj, budget)
        t2 = time.perf_counter()
    print(f"offline: read {t1 - t0:.2f} s + report {t2 - t1:.2f} s = {t2 - t0:.2f} s")
    mon = PathMonitor(model, budget)
    batch, worst, busy = 0.1, 0.0, 0.0
    start = min(st.joint_stamps[0], st.stamps[0])
    ja = np.searchsorted(st.joint_stamps, start + np.arange(0, jp.duration + 2.0, batch))
    ma = np.searchsorted(st.stamps, start + np.arange(0, jp.duration + 2.0, batch))
    for k in range(len(ja) - 1):
        c0 = time.process_time()
        mon.add_joint_states(st.joint_stamps[ja[k]:ja[k + 1]], st.joints[ja[k]:ja[k + 1]])
        mon.add_points(st.stamps[ma[k]:ma[k + 1]], st.points[ma[k]:ma[k + 1]])
        dt = time.process_time() - c0
        busy += dt
        worst = max(worst, dt)
    mon.finish()
    on = mon.last
    print(f"on line: {busy:.2f} s of CPU for {jp.duration:.0f} s of streams ({busy / jp.duration:.2%} of real time) "
          f"in {len(ja) - 1} batches of {batch:g} s; slowest batch {worst * 1e3:.0f} ms (the latency's estimate)")
    rows = []
    for key, head, scale in KEYS:
        a = off[key] if key == "latency_s" else off["overall"][key]
        b = on[key] if key == "latency_s" else on["overall"][key]
        rows.append([head, f"{a * scale:.4f}", f"{b * scale:.4f}"])
    rows.append(["cycles", off["cycles"], on["cycles"]])
    print(table(["figure", "offline", "on line"], rows))
    return verdicts([
        (t2 - t0 < 10.0, f"offline {len(st.stamps):,} points read and reported in {t2 - t0:.2f} s (target < 10 s)"),
        (busy < jp.duration, f"on line {busy:.1f} s of CPU for {jp.duration:.0f} s of streams (target < real time)"),
        (abs(off["latency_s"] - 0.008) < 5e-4 and abs(on["latency_s"] - 0.008) < 5e-4,
         f"latency {off['latency_s'] * 1e3:.3f} ms offline, {on['latency_s'] * 1e3:.3f} ms on line (8 ms, target "
         f"within 0.5 ms)"),
    ])


if __name__ == "__main__":
    sys.exit(main())
