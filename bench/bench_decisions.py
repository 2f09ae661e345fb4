"""Benchmark: are `report --budget`'s decisions right? Simulated arms with a known truth, judged as a user does.

The README's first hour, repeated over seeded arms: `plan-campaign` (30 poses), `simulate` (3 cycles, tracker
noise 10 um and 10 urad, the as-built truth written beside), `report --budget` (the groups' decisions, by the
default rule guarded:2 and by `simple`). Two kinds of arm: built within every tolerance (errors uniform within
the budget) and built well beyond it (uniform within 3x the budget). Each group's truth is the combination its
estimate measures (its coefficients times the true errors). Counted per rule:

- wrong blame: a part decided out whose truth is within its tolerance;
- wrong acceptance: a part decided within whose truth is out by more than 3 std;
- caught: the parts out by more than 3 std that are decided out.

    python bench/bench_decisions.py [--robot gao2023_7dof] [--budget gao2023_delta2] [--within 10] [--beyond 10]
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
import yaml  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout without installing
from machine import load_average, machine, verdicts  # noqa: E402
from tolerance_ros.cli.main import main  # noqa: E402
from tolerance_ros.core.budget import load_budget  # noqa: E402
from tolerance_ros.core.calibration.calibration_file import load_calibration  # noqa: E402
from tolerance_ros.core.models import load_robot  # noqa: E402


def run(*argv):
    """The command's exit code and JSON answer (it runs in this process, quiet)."""
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(io.StringIO()):
        code = main([*argv, "--json", "--quiet"])
    return code, json.loads(out.getvalue())


def scaled_budget(path, factor, out):
    """A copy of the budget file ``path`` with every tolerance times ``factor`` (to build arms beyond it)."""
    doc = yaml.safe_load(Path(path).read_text())
    doc["tolerances"] = {k: v * factor for k, v in doc["tolerances"].items()}
    Path(out).write_text(yaml.safe_dump(doc))
    return out


def uniform_budget(model, spec, out):
    """A budget file of ``uniform:LENGTH_MM,ANGLE_MRAD`` (numbers in mm and mrad) for every parameter of ``model``."""
    length, angle = (float(v) for v in spec[len("uniform:"):].split(","))
    tol = {n: (length if k == "length" else angle * 1e-3) for n, k in zip(model.param_names, model.param_kinds)}
    Path(out).write_text(yaml.safe_dump({"robot": model.name, "units": {"length": "mm", "angle": "rad"},
                                         "limit": {"position": 1.0}, "criterion": "worst-case", "tolerances": tol}))
    return str(out)


def judge(model, tmp, budget, build_budget, seed, rules, extra=()):
    """[(rule, truth (g,), tolerance, std, decision)] of one simulated arm."""
    meas, truth_file = tmp / f"m{seed}.csv", tmp / f"m{seed}.truth.yaml"
    robot = getattr(model, "config_path", None) or getattr(model, "source", None) or model.name
    code, ans = run("simulate", "--robot", robot, "--tolerances", build_budget, "--campaign", str(tmp / "planned.yaml"),
        "--out", str(meas), "--seed", str(seed), *extra)
    if code:
        raise SystemExit(f"simulate: {ans}")
    dx = dict(zip(model.param_names, load_calibration(truth_file, model).dx))
    rows = []
    for rule in rules:
        code, rep = run("report", "--robot", robot, "--measurements", str(meas), "--campaign",
                     str(tmp / "planned.yaml"), "--budget", budget, "--decision-rule", rule)
        if code not in (0, 3):
            raise SystemExit(f"report: {rep}")
        for g in rep["identification"]["groups"]["groups"]:
            t = sum(c * dx[n] for n, c in g["coefficients"].items())
            rows.append((rule, t, g["tolerance"], g["std"], g["decision"], g["error"]))
    return rows


def main_():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robot", default="gao2023_7dof")
    ap.add_argument("--budget", default="gao2023_delta2",
                    help="a budget (file or shipped name), or uniform:LENGTH_MM,ANGLE_MRAD for every parameter")
    ap.add_argument("--simulate", default="", help="more options of `simulate`, e.g. '--backlash 0.05mrad'")
    ap.add_argument("--within", type=int, default=10, help="arms built within every tolerance")
    ap.add_argument("--beyond", type=int, default=10, help="arms built within 3x the budget")
    a = ap.parse_args()
    model = load_robot(a.robot)
    print(f"machine: {machine()}; {load_average()}")
    rules = ("guarded:2", "simple")
    results = {}
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        budget = uniform_budget(model, a.budget, tmp / "budget.yaml") if a.budget.startswith("uniform:") else a.budget
        budget_path = load_budget(budget, model).path
        robot = getattr(model, "config_path", None) or getattr(model, "source", None) or model.name
        code, ans = run("plan-campaign", "--robot", robot, "--n", "30", "--out", str(tmp / "planned.yaml"))
        if code:
            raise SystemExit(f"plan-campaign: {ans}")
        beyond = scaled_budget(budget_path, 3.0, tmp / "beyond.yaml")
        for kind, n, build in (("within", a.within, budget), ("beyond", a.beyond, str(beyond))):
            rows = []
            for s in range(n):
                rows += judge(model, tmp, budget, build, s, rules, a.simulate.split())
            results[kind] = rows
    print(f"{a.robot} against {a.budget}: {a.within} arms built within every tolerance, {a.beyond} within 3x the "
          f"budget; 30 poses x 3 cycles, tracker noise 10 um, 10 urad" + (f"; simulate {a.simulate}" if a.simulate else ""))
    print(f"{'arms':8} {'rule':10} {'parts':>6} {'out':>5} {'undec.':>7} {'within':>7} {'wrong out':>10} "
          f"{'in, >3u out':>12} {'caught':>10}")
    checks = []
    for kind, rows in results.items():
        for rule in rules:
            r = [x for x in rows if x[0] == rule and np.isfinite(x[2])]
            t, tol, u = (np.array([x[k] for x in r], float) for k in (1, 2, 3))
            dec = np.array([x[4] for x in r])
            out, und, win = dec == "out", dec == "undecided", dec == "within"
            wrong = out & (np.abs(t) <= tol)
            far = np.abs(t) > tol + 3 * u
            accepted_far = win & far
            caught = (out & far).sum()
            print(f"{kind:8} {rule:10} {len(r):6d} {out.sum():5d} {und.sum():7d} {win.sum():7d} {wrong.sum():10d} "
                  f"{accepted_far.sum():12d} {caught:5d} of {far.sum():3d}")
            if rule == "guarded:2":
                z = (np.array([x[5] for x in r]) - t) / u
                print(f"{'':8} {'':10} (estimate - truth) / u over the parts: mean {z.mean():+.2f}, std {z.std():.2f}, "
                      f"|z| > 2 for {100 * np.mean(np.abs(z) > 2):.1f} %")
                if kind == "within":
                    checks.append((wrong.sum() <= max(1, a.within // 10),
                                   f"arms within tolerance: {wrong.sum()} part(s) wrongly blamed over {a.within} arms "
                                   f"(at most 1 per 10)"))
                checks.append((accepted_far.sum() == 0,
                               f"arms {kind}: {accepted_far.sum()} part(s) decided within while out by > 3 std"))
                if far.sum():
                    checks.append((caught >= far.sum() / 2,
                                   f"arms {kind}: {caught} of {far.sum()} parts out by > 3 std decided out (half)"))
    g = [x for rows in results.values() for x in rows if x[0] == "guarded:2" and np.isfinite(x[2])]
    outs = [x for x in g if x[4] == "out"]
    wrong_all = sum(abs(x[1]) <= x[2] for x in outs)
    checks.append((wrong_all <= 0.025 * max(len(outs), 1),
                   f"wrong blame {wrong_all} of {len(outs)} 'out' decisions (<= 2.5 %)"))
    return verdicts(checks)


if __name__ == "__main__":
    sys.exit(main_())
