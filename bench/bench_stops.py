"""Benchmark: the stops of a stream against their closed-form truth, on the usual speed profiles.

A command of moves of 100 mm out and back (0.5 m/s and 5 m/s^2, then 0.1 m/s and 1 m/s^2) by each profile (trapezoid, raised cosine,
minimum jerk), its joint states at 500 Hz; a robot ringing at 8 Hz (damping 0.2) follows it; a tracker reads
it at 1 kHz with 2 um of noise (seeded, several seeds). Printed per profile: the error of the instant the
command rests (found between the joint states' samples), against the first joint-state sample under 1 mm/s (a
speed threshold), and the error of the stabilisation time (band 0.1 mm) against the truth, in ms and in
tracker periods.

    python bench/bench_stops.py [--seeds 8]
"""
import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout without installing
from machine import load_average, machine, verdicts  # noqa: E402
from tolerance_ros.core.accuracy import path as P  # noqa: E402
from tolerance_ros.core.accuracy.iso_paths import PROFILES  # noqa: E402
from tolerance_ros.core.accuracy.settling import stops  # noqa: E402
from tolerance_ros.testing.stops import entered, profile_run  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=8)
    a = ap.parse_args()
    print(f"machine: {machine()}; {load_average()}")
    print(f"{'profile':22} {'stop instant ms':>15} {'threshold ms':>13} {'stabilisation ms':>17} {'periods':>8} "
          f"{'truth ms':>9}")
    checks = []
    for (speed, accel), profile in ((va, pr) for va in ((0.5, 5.0), (0.1, 1.0)) for pr in PROFILES):
        inst, thr, stab, truth_all = [], [], [], []
        for seed in range(a.seeds):
            tm, pm, tj, pc, ends, (fine, exact) = profile_run(profile, seed=seed, speed=speed, accel=accel)
            runs = P.motions(tj, pc)
            rep = stops(tm, pm, tj, pc, runs, 1e-4)
            for s, (i0, i1), t_end in zip(rep["stops"], runs, ends):
                truth = entered(fine, exact, t_end, 1e-4)
                inst.append(s["t_stop_s"] - t_end)
                thr.append(tj[i1] - t_end)
                stab.append(s["stabilisation_time_s"] - truth)
                truth_all.append(truth)
        inst, thr, stab = (np.array(x) * 1e3 for x in (inst, thr, stab))
        worst = np.abs(stab).max()
        print(f"{profile + f' {speed:g} m/s':22} {np.abs(inst).max():15.4f} {thr.mean():+13.1f} {worst:17.3f} {worst:8.2f} "
              f"{np.mean(truth_all) * 1e3:9.1f}")
        checks.append((worst <= 1.0, f"{profile} at {speed:g} m/s: the stabilisation time within one tracker period of the truth "
                                     f"({worst:.3f} ms at worst over {len(stab)} stops)"))
    print("(stop instant: the largest |error| of the instant found; threshold: the mean error of the first joint-state "
          "sample under 1 mm/s; stabilisation: the largest |error| against the closed-form truth)")
    return verdicts(checks)


if __name__ == "__main__":
    sys.exit(main())
