"""Benchmark: calibration without a tracker, from contacts, on simulated campaigns with a known truth.

Three campaigns, each run as a user runs it (`tolerance-ros simulate --contact`, `calibrate`, `validate`):

- probe: the FANUC R-2000iC/165F (shared URDF) touching one fixed point with a probe tip from 20 postures, the
  robot exact: the tool point and the point (the classic tool-centre-point calibration); printed with the
  error from the truth in units of the reported standard uncertainty;
- planes: the FANUC built within 0.1 mm / 0.5 mrad, its tip on three planes (40 contacts each), then another
  session with the planes moved (20 each): the held-out contact RMS before and after, and the other session
  with its planes refitted; beside it scipy's least_squares (trust-region reflective, tolerances 1e-15; scipy 1.11's
  MINPACK Levenberg-Marquardt stops early on its step test there) on the same
  objective and unknowns, from the same start: its cost over ours and its time;
- whole body: TALOS (example-robot-data) from the left foot's sole through the leg, the torso and the arm to
  the gripper (15 joints, 105 parameters), three fingertips flush on a table (60 postures), two sessions (the
  shape of FIGAROH's real set).

Exits 1 when a calibration does not reduce the held-out contact RMS, or the other session is not predicted
better than by the nominal robot, or scipy finds a lower cost than ours by more than 1e-9 of it.

    python bench/bench_contact.py
"""
import os

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")

import contextlib  # noqa: E402
import io  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from machine import load_average, machine  # noqa: E402
from tolerance_ros.cli import main as cli  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
FANUC = ROOT / "test" / "data" / "fanuc_r2000ic" / "fanuc_r2000ic_165f.urdf"


def run(*argv):
    """(exit code, stdout) of one command, quietly."""
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(io.StringIO()):
        code = cli([str(a) for a in argv])
    return code, out.getvalue()


def contacts(robot, out, specs, targets, touches, session, chain=(), tolerances="uniform:0.1mm,0.5mrad", flush=False):
    argv = ["simulate", "--robot", robot, *chain, "--tolerances", tolerances, "--touches", touches,
            "--session", session, "--out", out, "--json", "--quiet"] + (["--flush"] if flush else [])
    for s in specs:
        argv += ["--contact", s]
    for t in targets:
        argv += ["--target-offset", t]
    code, text = run(*argv)
    assert code == 0, text
    return json.loads(text)


def calibrate(robot, csv, out, targets, chain=()):
    argv = ["calibrate", "--robot", robot, *chain, "--measurements", csv, "--out", out, "--json", "--quiet"]
    for t in targets:
        argv += ["--target", t]
    t0 = time.perf_counter()
    code, text = run(*argv)
    return json.loads(text), code, time.perf_counter() - t0


def validate(robot, cal, csv, chain=()):
    code, text = run("validate", "--robot", robot, *chain, "--calibration", cal, "--measurements", csv, "--json")
    return json.loads(text), code


def probe(tmp):
    """The tool point and the probed point from 20 postures of an exact robot."""
    from tolerance_ros.core.calibration.contact import ContactData, fit_contacts
    from tolerance_ros.core.accuracy.io.contact_csv import read_contacts
    from tolerance_ros.core.models.urdf import URDFChain
    contacts(FANUC, tmp / "probe.csv", ["point:tip=1.6m,0.2m,0.6m"], ["A=12mm,-6mm,110mm"], 20, "s1",
             tolerances="uniform:0.001um,0.001urad")
    model = URDFChain(FANUC)
    c = read_contacts(tmp / "probe.csv", model.joint_names)
    data = ContactData(c.joints, np.zeros(len(c), int), np.zeros(len(c), int), [("s1", "point", "tip")], ("A",))
    t0 = time.perf_counter()
    f = fit_contacts(model, data, [[0, 0, 0.1]], "rig", sigma=1e-5)
    seconds = time.perf_counter() - t0
    rig = f.rig
    z_tool = np.abs(rig.offsets[0] - [0.012, -0.006, 0.110]) / rig.offsets_std[0]
    z_point = np.abs(rig.points[0] - [1.6, 0.2, 0.6]) / rig.points_std[0]
    print(f"probe tip, one point, 20 postures, robot exact to 1 nm: tool point {np.round(rig.offsets[0] * 1e3, 4)} mm "
          f"+- {np.round(rig.offsets_std[0] * 1e3, 4)} (truth [12, -6, 110]; largest error {z_tool.max():.2f} sigma), "
          f"the point within {z_point.max():.2f} sigma; residual {f.rms() * 1e3:.4f} mm RMS; {seconds * 1e3:.0f} ms")
    return z_tool.max() <= 3 and z_point.max() <= 3


def against_scipy(tmp):
    """Our final fit of the planes campaign beside scipy's least_squares on the same objective."""
    from scipy.optimize import least_squares
    from tolerance_ros.core.accuracy.io.contact_csv import read_contacts
    from tolerance_ros.core.calibration.contact import _stack, fit_contacts
    from tolerance_ros.core.calibration.contact_campaign import contact_data
    from tolerance_ros.core.models.urdf import URDFChain
    model = URDFChain(FANUC)
    data, nominal, _ = contact_data(model, read_contacts(tmp / "planes1.csv", model.joint_names),
                                    {"A": [0.0, 0.0, 0.1]})
    t0 = time.perf_counter()
    f = fit_contacts(model, data, nominal, "full", sigma=1e-5, robust=False)
    ours_s = time.perf_counter() - t0
    names = f.layout.names(model, data)
    held = list(model.param_index(f.held)) + [names.index(f"target {k}") for k, w in f.targets_why.items()
                                              if not w["fitted"]]
    free = np.flatnonzero(~np.isin(np.arange(f.layout.n), held))

    def residuals(z):
        x = np.zeros(f.layout.n)
        x[free] = z
        return _stack(model, data, x, f.reference, f.layout)[1]
    t0 = time.perf_counter()
    ref = least_squares(residuals, np.zeros(len(free)), method="trf", xtol=1e-15, ftol=1e-15, gtol=1e-15, x_scale=1e-3)
    theirs_s = time.perf_counter() - t0
    ours, theirs = float(np.sum(residuals(f.x[free]) ** 2)), float(np.sum(ref.fun ** 2))
    print(f"the planes' final fit ({len(free)} unknowns, {len(data)} contacts): cost {ours:.6e} m^2 in {ours_s:.3f} s; "
          f"scipy least_squares (trf) {theirs:.6e} m^2 in {theirs_s:.3f} s: cost ratio scipy/ours "
          f"{theirs / ours:.12f}, time ratio {theirs_s / ours_s:.1f}x")
    return theirs >= ours * (1 - 1e-9)


def main():
    from tolerance_ros.testing.example_robots import example_urdf
    print(f"machine: {machine()}, {load_average()}\n")
    ok = []
    rows = []
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        ok.append(probe(tmp))
        planes = ["plane:floor=0,0,1@300mm", "plane:wall=1,0,0@1700mm", "plane:side=0,1,0@-900mm"]
        moved = ["plane:floor=0,0.1,1@250mm", "plane:wall=1,0.05,0@1650mm", "plane:side=0,1,0.02@-800mm"]
        talos = example_urdf("talos_reduced.urdf")
        chain = ("--base-link", "left_sole_link", "--tip-link", "gripper_left_base_link")
        fingers = ["F1=0mm,0mm,-100mm", "F2=30mm,0mm,-100mm", "F3=0mm,30mm,-100mm"]
        nominal = ["F1=0mm,0mm,-100mm", "F2=30mm,0mm,-100mm", "F3=0mm,30mm,-100mm"]
        for label, robot, specs, specs2, targets, given, touches, ch in (
                ("FANUC, tip on three planes", FANUC, planes, moved, ["A=12mm,-6mm,110mm"], ["A=0mm,0mm,100mm"], 40, ()),
                ("TALOS sole to gripper, 3 fingertips flush on a table", talos, ["plane:table=0,0,1@900mm"],
                 ["plane:table=0,0.02,1@850mm"], fingers, nominal, 60, chain)):
            stem = "planes" if robot == FANUC else "talos"
            flush = robot != FANUC
            contacts(robot, tmp / f"{stem}1.csv", specs, targets, touches, "s1", ch, flush=flush)
            contacts(robot, tmp / f"{stem}2.csv", specs2, targets, touches // 2, "s2", ch, flush=flush)
            doc, code, seconds = calibrate(robot, tmp / f"{stem}1.csv", tmp / f"{stem}_cal", given, ch)
            v = doc["validation"]
            other, vcode = validate(robot, tmp / f"{stem}_cal" / "calibration.yaml", tmp / f"{stem}2.csv", ch)
            rows.append([label, doc["fit"]["measurements"], doc["model"]["label"], v["before"]["contact_rms_m"],
                         v["after"]["contact_rms_m"], other["before"]["contact_rms_m"],
                         other["after"]["contact_rms_m"], seconds])
            ok.append(code == 0 and vcode == 0 and v["after"]["contact_rms_m"] < v["before"]["contact_rms_m"]
                      and other["after"]["contact_rms_m"] < other["before"]["contact_rms_m"])
        ok.append(against_scipy(tmp))
    print()
    head = ["campaign", "contacts", "identified", "before mm", "held out mm", "other session: nominal mm",
            "calibrated mm", "calibrate s"]
    print(" | ".join(head))
    for r in rows:
        print(" | ".join([r[0], str(r[1]), r[2]] + [f"{x * 1e3:.4f}" for x in r[3:7]] + [f"{r[7]:.1f}"]))
    print("\n(contact RMS: distances to the planes; 'before' the nominal robot with its rig fitted on every row, "
          "'held out' 10-fold by pose; the other session with its planes refitted; simulated contact noise 10 um)")
    return 0 if all(ok) else 1


if __name__ == "__main__":
    sys.exit(main())
