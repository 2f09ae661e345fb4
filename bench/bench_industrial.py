"""Benchmark: `calibrate` on a campaign of the industrial shape, side by side with an independent fit.

The campaign (``industrial.py``): the FANUC R-2000iC/165F URDF as built with a 3 mrad non-perpendicularity of
axes 1 and 2, small origin errors, joint offsets and a 0.2 mrad/kN m joint compliance loaded by a 120 kg
point mass at the flange; 24 configurations (21 at one joint-1 angle), 10 visits each, three reflectors,
40 um tracker noise per axis. `tolerance-ros calibrate --registration base+tool` runs as a user runs it (the
default, and with --parameters full, full+elastic and --no-robust), beside scipy's Levenberg-Marquardt
(tolerances 1e-15) on pinocchio's forward kinematics of an edited model, geometric and with the compliance of
joints 2-5, both scored by 10-fold cross-validation by configuration with seed 0, every point scored.
Printed: in-sample and held-out 3-D position RMS / max (mm), the rows rejected, the time of each command,
and the noise floor (the simulated noise's 3-D RMS). Exits 1 when the default `calibrate` rejects a
measurement, misses 1.2x the noise floor on held-out poses, or stops without converging.

    python bench/bench_industrial.py [--repeats 10] [--no-independent]
"""
import os

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")

import argparse  # noqa: E402
import contextlib  # noqa: E402
import io  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import industrial  # noqa: E402
from machine import load_average, machine  # noqa: E402
from tolerance_ros.cli import main as cli  # noqa: E402


def run_calibrate(csv, out, *extra):
    """(calibration.json document, seconds) of one `tolerance-ros calibrate` run."""
    t0 = time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        code = cli(["calibrate", "--robot", str(industrial.URDF), "--measurements", str(csv), "--registration",
                    "base+tool", "--out", str(out), "--quiet", *extra])
    seconds = time.perf_counter() - t0
    doc = json.loads((Path(out) / "calibration.json").read_text())
    doc["exit_code"] = code
    return doc, seconds


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=10)
    ap.add_argument("--no-independent", action="store_true", help="skip scipy's fits (the slow part)")
    args = ap.parse_args()
    print(f"machine: {machine()}, {load_average()}")
    c = industrial.campaign(repeats=args.repeats)
    floor = np.sqrt(3) * c.noise
    print(f"{len(c.q)} measurements at {len(set(c.labels))} configurations x {args.repeats} visits x 3 reflectors; "
          f"noise floor (3-D RMS of the simulated noise) {floor * 1e3:.4f} mm\n")
    rows = []
    if not args.no_independent:
        for label, joints in (("independent fit, geometric (scipy LM)", ()),
                              ("independent fit, + compliance of joints 2-5", ("joint_2", "joint_3", "joint_4",
                                                                              "joint_5"))):
            t0 = time.perf_counter()
            f = industrial.independent_figures(c, joints)
            rows.append([label, f["in_rms"], f["in_max"], f["cv_rms"], f["cv_max"], "none",
                         time.perf_counter() - t0, "-"])
    verdict = []
    with tempfile.TemporaryDirectory() as tmp:
        csv = c.write_csv(Path(tmp) / "campaign.csv")
        for label, extra in (("calibrate (default)", ()), ("calibrate --parameters full", ("--parameters", "full")),
                             ("calibrate --parameters full+elastic", ("--parameters", "full+elastic")),
                             ("calibrate --no-robust", ("--no-robust",))):
            doc, seconds = run_calibrate(csv, Path(tmp) / label.replace(" ", "_"), *extra)
            fit, v = doc["fit"], doc["validation"]
            conv = fit["convergence"]
            rows.append([f"{label}: {doc['model']['label']}", fit["position_rms_m"], fit["position_max_m"],
                         v["after"]["position_rms_m"], v["after"]["position_max_m"],
                         str(len(doc["rejected"])) if doc["rejected"] else "none", seconds,
                         f"{conv['iterations']} it., {conv['stop']}"])
            if label == "calibrate (default)":
                if doc["rejected"]:
                    verdict.append(f"the default calibrate rejected {len(doc['rejected'])} measurement(s)")
                if v["after"]["position_rms_m"] > 1.2 * floor:
                    verdict.append(f"held-out RMS {v['after']['position_rms_m'] * 1e3:.4f} mm is above 1.2x the noise "
                                   f"floor ({1.2 * floor * 1e3:.4f} mm)")
                if not conv["converged"]:
                    verdict.append("the default fit did not converge")
    print("| fit | in-sample RMS mm | in-sample max mm | held-out RMS mm | held-out max mm | rejected | time s | "
          "loop |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r[0]} | {r[1] * 1e3:.4f} | {r[2] * 1e3:.4f} | {r[3] * 1e3:.4f} | {r[4] * 1e3:.4f} | {r[5]} | "
              f"{r[6]:.1f} | {r[7]} |")
    print(f"\nafter: {load_average()}")
    for v in verdict:
        print(f"FAILED: {v}")
    print("verdict: " + ("FAILED" if verdict else "ok"))
    return 1 if verdict else 0


if __name__ == "__main__":
    sys.exit(main())
