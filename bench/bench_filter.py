"""Benchmark of `tolerance-ros filter`: a 10,000-target program in each format corrected through the calibration of a
simulated as-built arm (each length within 0.15 mm, each angle within 0.4 mrad, the base 0.3 mm and 0.3 mrad off).

The programs are written here from seeded joints of the FANUC R-2000iC/165F URDF (RAPID, KRL, FANUC) and of the UR5
(URScript), away from the singularities (5 cm and 0.1 rad): 9,000 Cartesian targets in their configurations (several
tools and frames) and 1,000 joint targets. For each format:

- the time of the whole command in this process (read, correct, write the file; kernels warm), and of the core
  alone (read, correct, texts), with the peer: the same correction one target at a time (200 targets), per target;
- where every target lands on the as-built robot when the controller runs the program before and after (each
  Cartesian target solved on the nominal robot in the configuration written): median, 99th percentile and largest
  error of position (um) and of orientation (urad).

Prints the machine and its load average, and a verdict per target (10,000 targets < 10 s; every target within
10 um after); exits 1 when one is missed.

    python bench/bench_filter.py [--targets 10000]
"""
import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import io  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from contextlib import redirect_stderr, redirect_stdout  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))
from machine import load_average, machine, verdicts  # noqa: E402
from tolerance_ros.cli import main  # noqa: E402
from tolerance_ros.core.calibration.calibration_file import save_calibration  # noqa: E402
from tolerance_ros.core.geometry import matrices_to_quat, matrix_log_vec, rpy_from_matrix, transform  # noqa: E402
from tolerance_ros.core.models import warmup  # noqa: E402
from tolerance_ros.core.programs import fanuc, rapid  # noqa: E402
from tolerance_ros.core.programs.configuration import ArmGeometry  # noqa: E402
from tolerance_ros.core.programs.correct import Requests, correct  # noqa: E402
from tolerance_ros.core.programs.filtering import dialect_for, filter_program, landing, resolve  # noqa: E402
from tolerance_ros.core.programs.text import to_bytes  # noqa: E402
from tolerance_ros.testing.programs import as_built, example_setup, robot, robot_args  # noqa: E402

ERRORS = (1.5e-4, 4e-4)
BASE = np.array([2e-4, -1e-4, 3e-4, 2e-4, -1e-4, 3e-4])
JOINT_SHARE = 0.1

# the frames the written programs use, as on the command line (the same as the example programs')
OPTIONS = {
    "rapid": [],
    "krl": ["--tool", "1=200mm,0mm,0mm,0deg,90deg,0deg", "--frame", "2=1800mm,-400mm,300mm,0deg,0deg,30deg"],
    "fanuc": ["--base", "0mm,0mm,670mm,0deg,0deg,0deg", "--flange", "0mm,0mm,0mm,180deg,-90deg,0deg",
              "--tool", "1=0mm,0mm,200mm,0deg,0deg,0deg", "--frame", "1=1800mm,-400mm,-370mm,0deg,0deg,-15deg"],
    "urscript": ["--base", "0m,0m,0m,0deg,0deg,180deg"],
}
TOOL = transform([0.2, 0, 0], [0, np.pi / 2, 0])                    # RAPID and KRL: 200 mm along the flange x
FRAME = transform([1.8, -0.4, 0.3], [0, 0, 0])                      # RAPID's wobjTable
KUKA_BASE = transform([1.8, -0.4, 0.3], [0, 0, np.radians(30)])
FANUC_WORLD = transform([0, 0, 0.670])
FANUC_TOOL = transform([0, 0, 0], [np.pi, -np.pi / 2, 0]) @ transform([0, 0, 0.2])
FANUC_UF1 = FANUC_WORLD @ transform([1.8, -0.4, -0.37], [0, 0, np.radians(-15)])
UR_BASE = transform([0, 0, 0], [0, 0, np.pi])
UR_TCP = transform([0, 0, 0.15])


def joints(model, n, seed):
    """(n, 6) seeded joints 5 cm and 0.1 rad away from the configuration changes, J5 away from 0 and +-180 deg."""
    g = ArmGeometry(model)
    rng = np.random.default_rng(seed)
    out = []
    while sum(len(o) for o in out) < n:
        q = model.sample_joints(4 * n, rng)
        q[:, 1:3] *= 0.6
        _, margin = g.flags(q)
        ok = (margin[:, 0] > 0.05) & (margin[:, 1] > 0.05) & (margin[:, 2] > 0.1) & (np.abs(np.abs(q[:, 4]) - np.pi) > 0.1)
        out.append(q[ok])
    return np.vstack(out)[:n], g


def _num(x, d):
    t = f"{x:.{d}f}"
    return "0" if float(t) == 0 else t


def write_rapid(model, q, path):
    g = ArmGeometry(model)
    signs, _ = g.flags(q)
    n_j = int(len(q) * JOINT_SHARE)
    in_frame = np.arange(len(q)) % 2 == 0
    T = model.fk(q) @ TOOL
    T[in_frame] = np.linalg.inv(FRAME) @ T[in_frame]
    quat = matrices_to_quat(T[:, :3, :3])[:, [3, 0, 1, 2]]
    decl, moves = [], []
    ext = "[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]"
    for k in range(len(q)):
        if k < n_j:
            decl.append(f"    CONST jointtarget j{k}:=[[{','.join(_num(v, 4) for v in np.degrees(q[k]))}],{ext}];")
            moves.append(f"        MoveAbsJ j{k}, v1000, z50, tGripper;")
            continue
        p, s = T[k, :3, 3] * 1e3, signs[k]
        cf = [rapid.quadrant(q[k, 0]), rapid.quadrant(q[k, 3]), rapid.quadrant(q[k, 5]),
              4 * (s[0] < 0) + 2 * (s[1] < 0) + (s[2] < 0)]
        decl.append(f"    CONST robtarget p{k}:=[[{','.join(_num(v, 3) for v in p)}],"
                    f"[{','.join(_num(v, 6) for v in quat[k])}],[{','.join(map(str, cf))}],{ext}];")
        moves.append(f"        MoveL p{k}, v1000, z10, tGripper" + ("\\WObj:=wobjTable;" if in_frame[k] else ";"))
    text = ("MODULE Bench\n    PERS tooldata tGripper:=[TRUE,[[200,0,0],[0.707106781,0,0.707106781,0]],"
            "[25,[100,0,0],[1,0,0,0],0,0,0]];\n    TASK PERS wobjdata wobjTable:=[FALSE,TRUE,\"\",[[1800,-400,300],"
            "[1,0,0,0]],[[0,0,0],[1,0,0,0]]];\n" + "\n".join(decl) + "\n    PROC main()\n" + "\n".join(moves)
            + "\n    ENDPROC\nENDMODULE\n")
    path.write_text(text)
    return [path]


def write_krl(model, q, path):
    g = ArmGeometry(model)
    signs, _ = g.flags(q)
    n_j = int(len(q) * JOINT_SHARE)
    in_base = np.arange(len(q)) % 2 == 0
    T = model.fk(q) @ TOOL
    T[in_base] = np.linalg.inv(KUKA_BASE) @ T[in_base]
    abc = np.degrees(rpy_from_matrix(T[:, :3, :3])[:, ::-1])
    decl = ["DECL FDAT FB2={TOOL_NO 1,BASE_NO 2,IPO_FRAME #BASE}", "DECL FDAT FB0={TOOL_NO 1,BASE_NO 0,IPO_FRAME #BASE}"]
    moves = []
    for k in range(len(q)):
        if k < n_j:
            a = np.degrees(q[k])
            decl.append(f"DECL E6AXIS XJ{k}={{" + ",".join(f"A{i + 1} {_num(a[i], 4)}" for i in range(6))
                        + ",E1 0.0,E2 0.0,E3 0.0,E4 0.0,E5 0.0,E6 0.0}")
            moves.append(f"PTP XJ{k}")
            continue
        p, s = T[k, :3, 3] * 1e3, signs[k]
        S = int((s[0] < 0) + 2 * (s[1] > 0) + 4 * (s[2] < 0))
        t = sum(1 << j for j in range(6) if q[k, j] < 0)
        decl.append(f"DECL E6POS XP{k}={{X {_num(p[0], 3)},Y {_num(p[1], 3)},Z {_num(p[2], 3)},A {_num(abc[k, 0], 4)},"
                    f"B {_num(abc[k, 1], 4)},C {_num(abc[k, 2], 4)},S {S},T {t},E1 0.0,E2 0.0,E3 0.0,E4 0.0,E5 0.0,"
                    f"E6 0.0}}")
        moves.append(f"FDAT_ACT={'FB2' if in_base[k] else 'FB0'}\nLIN XP{k} C_DIS")
    dat, src = path.with_suffix(".dat"), path.with_suffix(".src")
    dat.write_text("&ACCESS RVP\nDEFDAT BENCH\n" + "\n".join(decl) + "\nENDDAT\n")
    src.write_text("&ACCESS RVP\nDEF BENCH( )\nBAS(#TOOL,1)\nBAS(#BASE,0)\n" + "\n".join(moves) + "\nEND\n")
    return [src]


def write_fanuc(model, q, path):
    g = ArmGeometry(model)
    signs, _ = g.flags(q)
    n_j = int(len(q) * JOINT_SHARE)
    in_uf = np.arange(len(q)) % 2 == 0
    T = model.fk(q) @ FANUC_TOOL
    T[in_uf] = np.linalg.inv(FANUC_UF1) @ T[in_uf]
    T[~in_uf] = np.linalg.inv(FANUC_WORLD) @ T[~in_uf]
    wpr = np.degrees(rpy_from_matrix(T[:, :3, :3]))
    c = fanuc.coupling(model)
    mn, pos = [], []
    for k in range(len(q)):
        mn.append(f"{k + 1:>4}:J P[{k + 1}] 100% CNT50    ;")
        if k < n_j:
            J = np.degrees(q[k]).copy()
            J[2] += c * J[1]
            pos.append(f"P[{k + 1}]{{\n   GP1:\n\tUF : 0, UT : 1,\t\n" + "\t" + ",\t".join(
                f"J{i + 1}= {J[i]:9.3f} deg" for i in range(3)) + ",\n\t" + ",\t".join(
                f"J{i + 1}= {J[i]:9.3f} deg" for i in range(3, 6)) + "\n};")
            continue
        s = signs[k]
        turns = [fanuc.turn(q[k, j]) for j in (3, 4, 5)]
        cfg = (f"{'F' if s[2] > 0 else 'N'} {'U' if s[1] > 0 else 'D'} {'T' if s[0] > 0 else 'B'}, "
               f"{turns[0]}, {turns[1]}, {turns[2]}")
        p = T[k, :3, 3] * 1e3
        pos.append(f"P[{k + 1}]{{\n   GP1:\n\tUF : {1 if in_uf[k] else 0}, UT : 1,\t\tCONFIG : '{cfg}',\n"
                   f"\tX = {p[0]:9.3f}  mm,\tY = {p[1]:9.3f}  mm,\tZ = {p[2]:9.3f}  mm,\n"
                   f"\tW = {wpr[k, 0]:9.3f} deg,\tP = {wpr[k, 1]:9.3f} deg,\tR = {wpr[k, 2]:9.3f} deg\n}};")
    text = "/PROG  BENCH\n/ATTR\n/MN\n" + "\n".join(mn) + "\n/POS\n" + "\n".join(pos) + "\n/END\n"
    path.write_bytes(text.replace("\n", "\r\n").encode())
    return [path]


def write_urscript(model, q, path):
    n_j = int(len(q) * JOINT_SHARE)
    T = np.linalg.inv(UR_BASE) @ model.fk(q) @ UR_TCP
    r = matrix_log_vec(T[:, :3, :3])
    lines = ["def bench():", "  set_tcp(p[0, 0, 0.15, 0, 0, 0])"]
    every = max(len(q) // n_j, 1)
    for k in range(len(q)):
        if k % every == 0:      # a joint target now and then: the poses after it are solved near it
            lines.append("  movej([" + ", ".join(f"{v:.7f}" for v in q[k]) + "], a=1.4, v=1.05)")
        else:
            lines.append("  movel(p[" + ", ".join(f"{v:.7f}" for v in (*T[k, :3, 3], *r[k])) + "], a=1.2, v=0.25)")
    path.write_text("\n".join(lines) + "\nend\n")
    return [path]


def ur_sequence(model, n, seed):
    """Joints of a UR program: short hops of a random walk (the controller solves each pose near the last)."""
    g = ArmGeometry(model)
    rng = np.random.default_rng(seed)
    q = np.empty((n, 6))
    cur = np.array([0.3, -1.2, 1.5, -1.9, -1.5708, 0.2])
    for k in range(n):
        for _ in range(200):
            nxt = cur + rng.normal(0, 0.05, 6)
            _, m = g.flags(nxt[None])
            inside = np.all(np.abs(nxt) < np.minimum(model.joint_limits[:, 1], 2.6))
            if inside and np.all(m[0] > [0.1, 0.1, 0.3]) and abs(abs(nxt[4]) - np.pi) > 0.3:
                break
        cur = nxt
        q[k] = cur
    return q, g


CATEGORIES = (("out of reach", "reach"), ("near a singularity", "singularity"),
              ("a joint changed by more than max_joint_correction", "max_joint_correction"),
              ("moved by more than max_tool_correction", "max_tool_correction"),
              ("its configuration would change", "configuration"))
WRITERS = {"rapid": write_rapid, "krl": write_krl, "fanuc": write_fanuc, "urscript": write_urscript}


def one_at_a_time(program, setup, count):
    """Seconds per target of ``correct`` called on one target at a time (the first ``count`` targets)."""
    targets, req, why, _ = resolve(program, setup)
    idx = [i for i in range(len(targets)) if why[i] is None][:count]
    t0 = time.perf_counter()
    for i in idx:
        s = slice(i, i + 1)
        correct(setup.model, setup.calibrated, Requests(req.pose[s], req.T[s], req.tool[s], req.q[s], req.want[s],
                                                        req.windows[s], req.near[s]), setup.envelope, setup.geometry)
    return (time.perf_counter() - t0) / len(idx)


def main_(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--targets", type=int, default=10_000)
    args = ap.parse_args(argv)
    warmup.start(background=False)
    print(f"machine: {machine()}; {load_average()}")
    results, rows = [], []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for kind, writer in WRITERS.items():
            arm = "ur5" if kind == "urscript" else "fanuc"
            model = robot(arm)
            truth = as_built(model, *ERRORS, seed=11, base=BASE)
            cal_path = save_calibration(truth, tmp / f"{arm}.yaml")
            if kind == "urscript":
                q, _ = ur_sequence(model, args.targets, 3)
            else:
                q, _ = joints(model, args.targets, 3)
            ext = {"rapid": ".mod", "krl": ".src", "fanuc": ".ls", "urscript": ".script"}[kind]
            files = writer(model, q, tmp / f"bench{ext}")
            out = tmp / f"out_{kind}"
            argv_ = ["filter", *map(str, files), *robot_args(arm), "--calibration", str(cal_path), *OPTIONS[kind],
                     "--out", str(out), "--quiet"]
            sink = io.StringIO()
            t0 = time.perf_counter()
            with redirect_stdout(sink), redirect_stderr(sink):
                code = main(argv_)
            wall = time.perf_counter() - t0
            # the core alone, and the peer
            import tolerance_ros.testing.programs as tp
            tp.EXAMPLES.setdefault(f"bench_{kind}", {"options": OPTIONS[kind]})
            setup = example_setup(f"bench_{kind}", model, truth)
            dialect = dialect_for(files)
            t0 = time.perf_counter()
            before = dialect.read(files)
            outcome = filter_program(before, setup, ["tolerance-ros filter: corrected (bench)"])
            core = time.perf_counter() - t0
            per_one = one_at_a_time(before, setup, 200)
            for p, text in outcome.texts.items():
                (out / p.name).write_bytes(to_bytes(text))
            after = dialect.read([out / files[0].name])
            land = landing(before, after, setup, truth.calibrated_chain(model))
            n = len(outcome.rows)
            left = len(outcome.left)
            kept = {id(t) for t, _ in outcome.left}
            done = np.array([id(t) not in kept for t in land["target"]], bool)      # the targets corrected
            land = {k: (np.asarray(v)[done] if k.endswith(("_m", "_rad")) else v) for k, v in land.items()}
            b, a = land["before_m"] * 1e6, land["after_m"] * 1e6
            br, ar = land["before_rad"] * 1e6, land["after_rad"] * 1e6
            print(f"\n{kind}: {n} targets ({sum(t.kind == 'pose' for t in before.targets)} Cartesian), {left} left as "
                  f"written, exit {code}")
            reasons = {}
            for _, why in outcome.left:
                label = " + ".join(name for name, key in CATEGORIES if key in why) or why
                reasons[label] = reasons.get(label, 0) + 1
            for why, count in sorted(reasons.items(), key=lambda kv: -kv[1]):
                print(f"  left as written: {count} ({why})")
            print(f"  command {wall:.2f} s, core {core:.2f} s ({core / n * 1e3:.3f} ms a target); one target at a time "
                  f"{per_one * 1e3:.2f} ms a target: {per_one / (core / n):.0f}x the batch")
            print(f"  landing before: median {np.median(b):.0f} um, p99 {np.percentile(b, 99):.0f} um, max "
                  f"{b.max():.0f} um; {np.median(br):.0f} / {br.max():.0f} urad")
            print(f"  landing after:  median {np.median(a):.3f} um, p99 {np.percentile(a, 99):.3f} um, max "
                  f"{a.max():.3f} um; {np.median(ar):.3f} / {ar.max():.3f} urad")
            results.append((wall < 10.0, f"{kind}: {n} targets filtered in {wall:.2f} s (< 10 s)"))
            results.append((a.max() < 10.0, f"{kind}: every corrected target within 10 um after ({a.max():.3f} um over "
                                            f"{len(a)}; {left} left as written, with their reasons)"))
            rows.append((kind, n, wall, core, b.max(), a.max()))
    print(f"\nmachine: {machine()}; {load_average()}")
    return verdicts(results)


if __name__ == "__main__":
    sys.exit(main_())
