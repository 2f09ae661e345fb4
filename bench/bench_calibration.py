"""Benchmark: the calibration loop on the 7-DOF D-H arm and the UR5 URDF.

For each robot: plan 30 poses (O1, 2000 candidates), draw an as-built robot within its tolerances
(gao2023_7dof: gao2023_delta2; UR5: 0.1 mm / 0.5 mrad per origin component), measure every pose
3 times with the simulated tracker (10 um, 10 urad; position rows fitted), calibrate with 10-fold
validation by test pose. Printed per robot over ``--draws`` as-built robots: the held-out position
RMS before and after and its reduction, the largest |identified - true| / std over the identified
parameters (true: in the identified parametrisation), the spread of those normalised errors over
all draws (1 when the stated uncertainties are right), and the times of planning and calibration
(one core).

    python bench/bench_calibration.py [--draws 10]
"""
import os

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")

import argparse  # noqa: E402
import importlib.metadata  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout without installing
from machine import load_average, machine, verdicts  # noqa: E402
from tolerance_ros.core.accuracy.simulate import measure  # noqa: E402
from tolerance_ros.core.budget import load_budget  # noqa: E402
from tolerance_ros.core.calibration.calibrate import calibrate  # noqa: E402
from tolerance_ros.core.calibration.planning import plan  # noqa: E402
from tolerance_ros.core.geometry import transform  # noqa: E402
from tolerance_ros.core.models import URDFChain, load_robot  # noqa: E402
from tolerance_ros.services.tracker import SimulatedTracker  # noqa: E402

T_TRACKER_BASE = transform([1.5, -0.3, 0.2], [0.05, -0.02, 1.2])


def ur5_urdf():
    for f in importlib.metadata.files("example-robot-data") or []:
        if str(f).endswith("/ur5_robot.urdf"):
            return Path(f.locate())
    raise SystemExit("the UR5 needs the PyPI package example-robot-data")


def effective_truth(model, dx, cal):
    eff = dx.copy()
    eff[model.param_index(cal.held)] = 0.0
    for name, absorbed in cal.aliases.items():
        if name in model.param_names:
            eff[model.param_index([name])[0]] += sum(c * dx[model.param_index([h])[0]] for h, c in absorbed.items())
    return eff


def run(model, delta, draws):
    t0 = time.perf_counter()
    pl = plan(model, 30, "observability", candidates=2000, seed=0)
    t_plan = time.perf_counter() - t0
    q = np.tile(pl.q, (3, 1))
    labels = np.tile([f"C{i + 1}" for i in range(30)], 3)
    rows, t_cal, zs = [], [], []
    for seed in range(draws):
        tracker = SimulatedTracker(model, delta, seed, 1e-5, 1e-5, T_TRACKER_BASE)
        T = measure(model, q, tracker.dx, 1e-5, 1e-5, T_TRACKER_BASE, seed=seed + 1)
        t0 = time.perf_counter()
        cal = calibrate(model, q, T, labels, sigma_position=1e-5)
        t_cal.append(time.perf_counter() - t0)
        est = np.setdiff1d(np.arange(model.n_params), model.param_index(cal.held))
        z = np.abs(cal.dx - effective_truth(model, tracker.dx, cal))[est] / cal.std[est]
        zs.append((cal.dx - effective_truth(model, tracker.dx, cal))[est] / cal.std[est])
        v = cal.validation
        rows.append((seed, v["before"]["position_rms_m"], v["after"]["position_rms_m"], v["improvement"], z.max(),
                     len(est)))
    print(f"\n{model.name}: planned in {t_plan:.1f} s (O1 {pl.chosen['O1'] * 1e3:.3f} mm, random "
          f"{pl.random['O1'] * 1e3:.3f} mm; condition {pl.chosen['condition']:.1f}, random "
          f"{pl.random['condition']:.1f}); calibration with validation {np.median(t_cal):.2f} s (median)")
    print("draw  before RMS mm  after RMS mm  reduction  max |err|/std  identified")
    for seed, b, a, imp, z, n in rows:
        print(f"{seed:4d}  {b * 1e3:13.4f}  {a * 1e3:12.4f}  {imp * 100:8.1f} %  {z:13.2f}  {n:10d}")
    imp = np.array([r[3] for r in rows])
    z = np.array([r[4] for r in rows])
    print(f"reduction min {imp.min() * 100:.1f} %, median {np.median(imp) * 100:.1f} %; max |err|/std <= 3 in "
          f"{np.sum(z <= 3)} of {len(z)} draws")
    Z = np.array(zs)
    print(f"(identified - true) / std over all draws: standard deviation {Z.std():.3f} (per parameter "
          f"{Z.std(axis=0).min():.2f}-{Z.std(axis=0).max():.2f}), {np.mean(np.abs(Z) > 3) * 100:.2f} % beyond 3 "
          f"(0.27 % for a normal variable)")
    band = 3 / np.sqrt(2 * Z.size)  # standard error of a normal sample's standard deviation: 1 / sqrt(2 N)
    return [(imp.min() >= 0.9, f"{model.name}: held-out position RMS reduced by {imp.min() * 100:.1f} % or more "
                               f"in every draw (target >= 90 %)"),
            (abs(Z.std() - 1) <= band, f"{model.name}: (identified - true) / std spreads with standard deviation "
                                       f"{Z.std():.3f} (target 1 +- {band:.2f}, three standard errors of a "
                                       f"sample of {Z.size}: the stated uncertainties are the real ones)")]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--draws", type=int, default=10)
    args = ap.parse_args()
    print(f"machine: {machine()}; {load_average()} (before); one core")
    gao = load_robot("gao2023_7dof")
    checks = run(gao, load_budget("gao2023_delta2", gao).vector_for(gao), args.draws)
    ur5 = URDFChain(ur5_urdf(), tip_link="tool0", name="ur5")
    checks += run(ur5, np.array([1e-4 if k == "length" else 5e-4 for k in ur5.param_kinds]), args.draws)
    print(f"\n{load_average()} (after)")
    return verdicts(checks)


if __name__ == "__main__":
    sys.exit(main())
