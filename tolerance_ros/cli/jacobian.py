"""`tolerance-ros jacobian`: nominal pose and parameter-error Jacobian at given or random configurations."""
from __future__ import annotations

import numpy as np

from ..render.text import table
from .common import CAPS, CLIError, check_cap, gigabytes, joints_option, load_model

NAME = "jacobian"
HELP = "nominal pose and parameter-error Jacobian at configurations"
ROBOT = True


def add_arguments(p):
    p.add_argument("--joints", action="append", metavar="Q1,Q2,...",
                   help="a joint configuration, each value with its unit (e.g. 0deg,10deg,... or 0rad,0.1rad,...; a "
                        "prismatic joint's 20mm); repeat for several")
    p.add_argument("--deg", action="store_true",
                   help="--joints as bare numbers: degrees for revolute joints, metres for prismatic ones")
    p.add_argument("--random", type=int, default=1, metavar="N",
                   help=f"N random configurations if no --joints (at most {CAPS['random'][0]})")
    p.add_argument("--seed", type=int, default=0, help="seed of the random joints (default 0)")


def _joints(args, model):
    """The configurations of ``--joints`` (each value with its unit; with ``--deg``, bare numbers in degrees for
    revolute joints and metres for prismatic ones), or ``--random`` ones."""
    if args.joints:
        rows = []
        for i, text in enumerate(args.joints):
            option = f"--joints[{i}]"
            if args.deg:
                try:
                    vals = [float(v) for v in text.split(",")]
                except ValueError:
                    raise CLIError(f"{option}: with --deg, expected {model.dof} numbers separated by commas, got "
                                   f"{text[:200]!r}") from None
                if len(vals) != model.dof:
                    raise CLIError(f"{option}: expected {model.dof} values per configuration "
                                   f"({', '.join(model.joint_names)}), got {len(vals)}")
                rows.append(np.where([t == "revolute" for t in model.joint_types], np.deg2rad(vals), vals))
            else:
                rows.append(joints_option(model, text, option))
        return model.check_joints(np.array(rows), "--joints", allow_out_of_limits=True)
    return model.sample_joints(args.random, args.seed)


BYTES_PER_FLOAT = 100  # a float of the JSON document in memory: the Python float, its list slot and its text


def run(args):
    model = load_model(args)
    if not args.joints:
        n = args.random
        check_cap(n, "random", need=f"the answer for {n} poses would take about "
                                    f"{gigabytes(n * (17 + model.dof + 6 * model.n_params) * BYTES_PER_FLOAT)} "
                                    f"in memory")
    q = _joints(args, model)
    T, EJ = model.fk_and_jacobian(q)
    outside = model.out_of_limits(q)
    if args.json:
        return {"robot": model.name, "joint_names": list(model.joint_names), "joints": q,
                "out_of_limits": outside.any(axis=1), "poses": T, "parameters": list(EJ.names),
                "units": list(EJ.units), "rows": ["dx", "dy", "dz", "drx", "dry", "drz"],
                "jacobian": EJ.J}
    for k in range(q.shape[0]):
        p = T[k, :3, 3] * 1e3
        flag = "  (outside joint limits)" if outside[k].any() else ""
        print(f"pose {k}: q = [{', '.join(f'{v:.4f}' for v in q[k])}]{flag}")
        print(f"  tool position [mm]: {p[0]:.3f} {p[1]:.3f} {p[2]:.3f}")
        rows = []
        for j, (n, u) in enumerate(zip(EJ.names, EJ.units)):
            col = EJ.J[k, :, j]
            rows.append([n, u] + [f"{v * 1e3:.5f}" for v in col[:3]] + [f"{v:.5f}" for v in col[3:]])
        print(table(["param", "unit", "dPx mm/u", "dPy mm/u", "dPz mm/u", "dRx rad/u", "dRy rad/u", "dRz rad/u"],
                    rows))
