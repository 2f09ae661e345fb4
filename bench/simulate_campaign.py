"""Simulated tracker measurements of a campaign, for trying the calibration loop without hardware.

An as-built robot is drawn within a tolerance budget (uniform, seeded: the simulated tracker node's
model, ``services.tracker.SimulatedTracker``), every test pose of the campaign is visited for its
cycles, and the tracker reads the tool pose in its own frame (``T_tracker_base``: 1.5 m, -0.3 m,
0.2 m; rpy 0.05, -0.02, 1.2 rad) with Gaussian noise. The CSV (measurement format of
``core/accuracy/io.py``) is what ``tolerance-ros report`` and ``calibrate`` read.

    python bench/simulate_campaign.py --robot gao2023_7dof --tolerances gao2023_delta2 \\
        --campaign out/planned.yaml --out out/measurements.csv [--noise 10um] [--orientation-noise 10urad] [--seed 0]

``--tolerances uniform:0.1mm,0.5mrad`` draws every length within 0.1 mm and every angle within 0.5 mrad
(for robots without a budget file, e.g. a URDF).
"""
import os

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")

import argparse  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout without installing
from tolerance_ros.core.accuracy.io import Measurements, write_csv  # noqa: E402
from tolerance_ros.core.accuracy.simulate import measure  # noqa: E402
from tolerance_ros.core.budget import load_budget  # noqa: E402
from tolerance_ros.core.campaign import load_campaign  # noqa: E402
from tolerance_ros.core.geometry import transform  # noqa: E402
from tolerance_ros.core.models import load_robot  # noqa: E402
from tolerance_ros.core.units import parse_quantity  # noqa: E402
from tolerance_ros.services.tracker import SimulatedTracker  # noqa: E402

T_TRACKER_BASE = transform([1.5, -0.3, 0.2], [0.05, -0.02, 1.2])


def tolerance_vector(model, spec):
    """(p,) SI tolerances from a budget (file or shipped name) or 'uniform:<length>,<angle>'."""
    if spec.startswith("uniform:"):
        length, angle = spec[len("uniform:"):].split(",")
        lv, av = parse_quantity(length, "length", "--tolerances"), parse_quantity(angle, "angle", "--tolerances")
        return np.array([lv if k == "length" else av for k in model.param_kinds])
    return load_budget(spec, model).vector_for(model)


def simulate(model, delta, campaign, noise, orientation_noise, seed):
    """(Measurements, as-built errors dx) of the campaign's sequence of visits."""
    tracker = SimulatedTracker(model, delta, seed, noise, orientation_noise, T_TRACKER_BASE)
    qk = campaign.joints_for(model)
    seq = campaign.sequence()
    q = np.array([qk[i] for i, _ in seq])
    T = measure(model, q, tracker.dx, noise, orientation_noise, T_TRACKER_BASE, seed=seed + 1)
    labels = np.array([campaign.names[i] for i, _ in seq], dtype=object)
    stamps = np.arange(len(q)) * campaign.dwell_s
    return Measurements(stamps, T, q, model.joint_names, labels, np.array([c for _, c in seq])), tracker.dx


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--robot", required=True)
    ap.add_argument("--tolerances", required=True, help="budget file or name, or uniform:<length>,<angle>")
    ap.add_argument("--campaign", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--noise", default="10um")
    ap.add_argument("--orientation-noise", default="10urad")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    model = load_robot(args.robot)
    meas, dx = simulate(model, tolerance_vector(model, args.tolerances), load_campaign(args.campaign, model),
                        parse_quantity(args.noise, "length", "--noise"),
                        parse_quantity(args.orientation_noise, "angle", "--orientation-noise"), args.seed)
    comment = (f"simulated: {model.name} as built within {args.tolerances} (seed {args.seed}), tracker noise "
               f"{args.noise} / {args.orientation_noise}; python bench/simulate_campaign.py")
    path = write_csv(args.out, meas, comments=[comment])
    print(f"wrote {path}: {len(meas)} measurements of {args.campaign}")


if __name__ == "__main__":
    main()
