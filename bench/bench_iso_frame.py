"""Benchmark: where the ISO report's base frame comes from, against the as-built truth, run as a user runs it.

For each seeded as-built robot: `plan-campaign --iso9283` (the cube's five poses, 30 cycles) and a separate
30-pose calibration campaign, both measured by `simulate` on the same robot and tracker set-up (10 um, 10 urad);
`calibrate` on the calibration campaign; then `iso9283` on the cube in each frame:

- `test poses`: the default, fitted on the test poses themselves (AP a lower bound, said in the report);
- `calibration`: `--registration-from` the calibration;
- `poses`: `--registration-poses` the calibration campaign's measurements (a rigid fit on other poses).

Two truths, from the noise-free measurements of the same runs: AP in the mounting frame (the simulated tracker
placement), and AP in the kinematic base frame as built (the mounting frame moved by the errors of the
parameters every registration absorbs: joint 1's origin of a URDF chain, d1 and theta1 of a D-H one), the frame
any measurement of the robot's own poses can find. Prints AP_p per pose, and the largest deviation of each frame
from each truth as a share of it; the target of issue 47: the calibration's frame within 10 % + 10 um of the
as-built truth in the kinematic base frame.

    python bench/bench_iso_frame.py [--robot test/data/fanuc_r2000ic/fanuc_r2000ic_165f.urdf] [--seeds 3]
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
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout without installing
from machine import load_average, machine, verdicts  # noqa: E402
from tolerance_ros.cli.main import main  # noqa: E402
from tolerance_ros.core.accuracy.io import read_measurements  # noqa: E402
from tolerance_ros.core.accuracy.iso9283 import pose_characteristics  # noqa: E402
from tolerance_ros.core.accuracy.registration import kabsch  # noqa: E402
from tolerance_ros.core.calibration.calibration_file import load_calibration  # noqa: E402
from tolerance_ros.core.campaign import load_campaign  # noqa: E402
from tolerance_ros.core.models import load_robot  # noqa: E402


def cli(*argv) -> dict:
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(io.StringIO()):
        code = main([str(a) for a in argv] + ["--json", "--quiet"])
    doc = json.loads(out.getvalue())
    if code not in (0, 3):
        raise SystemExit(f"tolerance-ros {' '.join(map(str, argv))}: {doc}")
    return doc


def truth_ap(model, truth, exact, campaign, absorbed) -> tuple:
    """{pose: AP_p} of the noise-free measurements in the mounting frame and in the kinematic base frame as built."""
    dx = truth.dx.copy()
    q = model.sample_joints(200, 0)
    keep = dx.copy()
    keep[model.param_index(absorbed)] = 0.0
    R, t, _ = kabsch(model.fk(q, keep)[:, :3, 3], model.fk(q, dx)[:, :3, 3])   # exact: a transform on the left
    E = np.eye(4)
    E[:3, :3], E[:3, 3] = R, t
    T_cmd = dict(zip(campaign.names, model.fk(campaign.joints_for(model))))
    out = []
    for T_tb in (truth.T_tracker_base, truth.T_tracker_base @ E):
        T = np.linalg.inv(T_tb) @ exact.T
        out.append({p: pose_characteristics(T_cmd[p], T[exact.pose == p], True).AP_p for p in campaign.names})
    return tuple(out)


def main_():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robot", default="test/data/fanuc_r2000ic/fanuc_r2000ic_165f.urdf")
    ap.add_argument("--tolerances", default="uniform:0.1mm,0.5mrad")
    ap.add_argument("--seeds", type=int, default=3)
    a = ap.parse_args()
    model = load_robot(a.robot)
    print(f"machine: {machine()}; {load_average()}")
    print(f"{a.robot} built within {a.tolerances}; ISO cube 5 poses x 30 cycles, calibration 30 poses x 3 cycles")
    checks, worst = [], {}
    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        cli("plan-campaign", "--robot", a.robot, "--iso9283", "--out", d / "cube.yaml")
        cli("plan-campaign", "--robot", a.robot, "--n", "30", "--out", d / "cal.yaml")
        cube = load_campaign(d / "cube.yaml", model)
        for s in range(a.seeds):
            sim = ("simulate", "--robot", a.robot, "--tolerances", a.tolerances, "--seed", s)
            cli(*sim, "--campaign", d / "cube.yaml", "--out", d / f"iso{s}.csv")
            cli(*sim, "--campaign", d / "cube.yaml", "--noise", "0um", "--orientation-noise", "0rad",
                "--out", d / f"exact{s}.csv")
            cli(*sim, "--campaign", d / "cal.yaml", "--out", d / f"cal{s}.csv")
            cli("calibrate", "--robot", a.robot, "--measurements", d / f"cal{s}.csv", "--campaign", d / "cal.yaml",
                "--out", d / f"c{s}")
            iso = ("iso9283", "--robot", a.robot, "--campaign", d / "cube.yaml", "--measurements", d / f"iso{s}.csv")
            frames = {"test poses": cli(*iso),
                      "calibration": cli(*iso, "--registration-from", d / f"c{s}" / "calibration.yaml"),
                      "poses": cli(*iso, "--registration-poses", d / f"cal{s}.csv")}
            absorbed = _absorbed(a.robot, model, d, s)
            mount, joint1 = truth_ap(model, load_calibration(d / f"iso{s}.truth.yaml", model),
                                     read_measurements(d / f"exact{s}.csv", joint_names=model.joint_names), cube,
                                     absorbed)
            print(f"\nseed {s}: absorbed by any registration: {', '.join(absorbed)}")
            print(f"{'AP_p mm':28}" + "".join(f"{p:>9}" for p in cube.names))
            print(f"{'truth, mounting frame':28}" + "".join(f"{mount[p] * 1e3:9.4f}" for p in cube.names))
            print(f"{'truth, kinematic base':28}" + "".join(f"{joint1[p] * 1e3:9.4f}" for p in cube.names))
            for name, doc in frames.items():
                got = {p: doc["pose"][p]["AP_p"] for p in cube.names}
                print(f"{name + ' (' + doc['frame']['source'] + ')':28}" + "".join(f"{got[p] * 1e3:9.4f}"
                                                                             for p in cube.names))
                for tname, tr in (("mounting", mount), ("kinematic base", joint1)):
                    excess = max(abs(got[p] - tr[p]) - (0.1 * tr[p] + 1e-5) for p in cube.names)
                    share = max(abs(got[p] - tr[p]) / tr[p] for p in cube.names)
                    worst.setdefault((name, tname), []).append((excess, share))
    print("\nlargest |AP_p - truth| / truth over the poses and seeds, and whether within 10 % + 10 um everywhere:")
    for (name, tname), v in worst.items():
        ok = max(e for e, _ in v) <= 0
        print(f"  {name:12} against the truth in the {tname} frame: {max(s for _, s in v) * 100:6.1f} %  "
              f"{'within' if ok else 'NOT within'}")
        if name == "calibration" and tname == "kinematic base":
            checks.append((ok, "--registration-from the calibration: AP_p within 10 % + 10 um of the as-built truth "
                               "(the kinematic base frame)"))
        if name == "test poses" and tname == "kinematic base":
            checks.append((not ok, "fitted on the test poses: AP_p flattered beyond 10 % (a lower bound, as said)"))
    return verdicts(checks)


def _absorbed(robot, model, d, s) -> list:
    """The parameters the registration absorbs (report's groups against a uniform budget)."""
    import yaml
    tol = {n: (1e-4 if k == "length" else 1e-3) for n, k in zip(model.param_names, model.param_kinds)}
    (d / "budget.yaml").write_text(yaml.safe_dump({"robot": model.name, "units": {"length": "m", "angle": "rad"},
                                                   "limit": {"position": 0.01}, "criterion": "worst-case",
                                                   "tolerances": tol}))
    rep = cli("report", "--robot", robot, "--measurements", d / f"cal{s}.csv", "--campaign", d / "cal.yaml",
              "--budget", d / "budget.yaml")
    return rep["identification"]["groups"]["absorbed_by_registration"]


if __name__ == "__main__":
    sys.exit(main_())
