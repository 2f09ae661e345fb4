"""Benchmark: FK plus the 6x28 parameter-error Jacobian of the paper's 7-DOF arm for 10,000 poses.

Three ways, in one run, on one core (threads pinned to 1 before numpy loads):
  batched    tolerance_ros's vectorised analytic model (one call for all poses);
  per-pose   the textbook loop: 4x4 link matrices and the same analytic columns, pose by pose;
  pinocchio  central finite differences of pinocchio's FK over the 28 D-H parameters, pose by pose.
Prints ms total, us per pose and the ratios, and checks that the three agree.

    python bench/bench_jacobian.py [--poses 10000] [--fd-poses 10000] [--repeat 7]
"""
import os

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout without installing
from tolerance_ros.core.models import load_robot  # noqa: E402


def per_pose_loop(model, q):
    """Textbook per-pose implementation (standard D-H), same column definitions as the batched one."""
    n, dof = q.shape
    out_T = np.empty((n, 4, 4))
    out_J = np.empty((n, 6, 4 * dof))
    for k in range(n):
        T = model.base.copy()
        frames = [T.copy()]
        for i in range(dof):
            th = q[k, i] + model.theta[i]
            ct, st = np.cos(th), np.sin(th)
            ca, sa = np.cos(model.alpha[i]), np.sin(model.alpha[i])
            A = np.array([[ct, -st * ca, st * sa, model.a[i] * ct], [st, ct * ca, -ct * sa, model.a[i] * st],
                          [0.0, sa, ca, model.d[i]], [0.0, 0.0, 0.0, 1.0]])
            T = T @ A
            frames.append(T.copy())
        T = T @ model.tool
        p = T[:3, 3]
        for i in range(dof):
            z, o = frames[i][:3, 2], frames[i][:3, 3]
            x, oi = frames[i + 1][:3, 0], frames[i + 1][:3, 3]
            out_J[k, :, i] = np.r_[x, 0.0, 0.0, 0.0]
            out_J[k, :, dof + i] = np.r_[z, 0.0, 0.0, 0.0]
            out_J[k, :, 2 * dof + i] = np.r_[np.cross(x, p - oi), x]
            out_J[k, :, 3 * dof + i] = np.r_[np.cross(z, p - o), z]
        out_T[k] = T
    return out_T, out_J


def pinocchio_fd(model, q, h=1e-7):
    """FK from pinocchio at every pose, and central differences over the 28 parameters."""
    import pinocchio as pin

    def fk_all(pm, fid):
        data = pm.createData()
        out = np.empty((len(q), 4, 4))
        for k in range(len(q)):
            pin.framesForwardKinematics(pm, data, q[k])
            out[k] = data.oMf[fid].homogeneous
        return out

    T = fk_all(*model.to_pinocchio())
    J = np.empty((len(q), 6, model.n_params))
    for j in range(model.n_params):
        e = np.zeros(model.n_params)
        e[j] = h
        Tp, Tm = fk_all(*model.to_pinocchio(e)), fk_all(*model.to_pinocchio(-e))
        J[:, :3, j] = (Tp[:, :3, 3] - Tm[:, :3, 3]) / (2 * h)
        dR = np.einsum("nij,nkj->nik", Tp[:, :3, :3], Tm[:, :3, :3])
        J[:, 3:, j] = np.stack([dR[:, 2, 1] - dR[:, 1, 2], dR[:, 0, 2] - dR[:, 2, 0], dR[:, 1, 0] - dR[:, 0, 1]],
                               axis=1) / (4 * h)
    return T, J


def best_of(fn, repeat):
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--poses", type=int, default=10000)
    ap.add_argument("--fd-poses", type=int, default=10000, help="poses for the pinocchio finite differences")
    ap.add_argument("--repeat", type=int, default=7)
    args = ap.parse_args()
    model = load_robot("gao2023_7dof")
    q = model.sample_joints(args.poses, 0)
    n = args.poses

    t_batch, (T_b, EJ) = best_of(lambda: model.fk_and_jacobian(q), args.repeat)
    t_loop, (T_l, J_l) = best_of(lambda: per_pose_loop(model, q), 1)
    nfd = min(args.fd_poses, n)
    t_fd, (T_p, J_p) = best_of(lambda: pinocchio_fd(model, q[:nfd]), 1)

    err_loop = np.abs(EJ.J - J_l).max()
    err_fd = np.abs(EJ.J[:nfd] - J_p).max()
    err_fk = max(np.abs(T_b - T_l).max(), np.abs(T_b[:nfd] - T_p).max())
    print(f"FK + 6x{model.n_params} parameter-error Jacobian, {model.name}, one core")
    print(f"{'method':<34}{'poses':>8}{'total ms':>12}{'us/pose':>10}{'vs batched':>12}")
    rows = [("batched analytic (tolerance_ros)", n, t_batch), ("per-pose loop (numpy 4x4)", n, t_loop),
            ("pinocchio FK, central differences", nfd, t_fd)]
    per_pose_batch = t_batch / n
    for name, count, t in rows:
        print(f"{name:<34}{count:>8}{t * 1e3:>12.2f}{t / count * 1e6:>10.2f}{(t / count) / per_pose_batch:>11.1f}x")
    print(f"max |difference|: FK {err_fk:.1e} m, Jacobian vs loop {err_loop:.1e}, vs pinocchio FD {err_fd:.1e}")
    print(f"target: batched <= 10 ms for 10,000 poses -> {'met' if t_batch * 1e4 / n <= 0.010 else 'NOT met'}; "
          f">= 20x faster than the loop -> {'met' if t_loop / t_batch >= 20 else 'NOT met'}")


if __name__ == "__main__":
    main()
