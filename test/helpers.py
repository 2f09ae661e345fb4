"""Reference computations shared by the tests: finite differences, random chains, example URDFs; and a
private ROS domain for each test process."""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from tolerance_ros.core.models import DHChain
from tolerance_ros.core.geometry import matrix_log_vec, transform
from tolerance_ros.testing import example_robots

example_urdf = example_robots.example_urdf  # the tests import it from here


def pose_difference(Tp, Tm):
    """(n, 6) [dp; dphi] taking poses Tm to Tp (dphi in the base frame)."""
    dp = Tp[:, :3, 3] - Tm[:, :3, 3]
    dphi = matrix_log_vec(np.einsum("nij,nkj->nik", Tp[:, :3, :3], Tm[:, :3, :3]))
    return np.concatenate([dp, dphi], axis=1)


def fd_jacobian(fk, p0, h=1e-6):
    """(n, 6, p) central finite differences of ``fk(params) -> (n, 4, 4)`` around ``p0``."""
    cols = []
    for j in range(len(p0)):
        e = np.zeros(len(p0))
        e[j] = h
        cols.append(pose_difference(fk(p0 + e), fk(p0 - e)) / (2 * h))
    return np.stack(cols, axis=2)


def run_cli(capsys, *argv):
    """(exit code, stdout, stderr) of ``tolerance-ros argv`` in this process (each argument as text)."""
    from tolerance_ros.cli import main
    code = main([str(a) for a in argv])
    out = capsys.readouterr()
    return code, out.out, out.err


SHARED_DATA = Path(os.environ.get("TOLERANCE_ROS_SHARED_DATA") or
                   Path(__file__).resolve().parents[1].parent / "shared" / "data")
"""The public measurement sets: ``../shared/data`` from the repository root (where CI lays them), or the folder
that ``TOLERANCE_ROS_SHARED_DATA`` names (a checkout elsewhere, e.g. a git worktree)."""


def shared_data(name: str) -> Path:
    """The folder of the public data set ``name`` in ``SHARED_DATA``; the test skips, saying where it looked,
    where it is absent."""
    import pytest
    folder = SHARED_DATA / name
    if not folder.is_dir():
        pytest.skip(f"public data set {name!r} not found at {folder} (tolerance-ros data fetch {name}, or set "
                    f"TOLERANCE_ROS_SHARED_DATA)")
    return folder


XARM7_URDF = Path(__file__).parent / "data" / "xarm7" / "xarm7.urdf"  # vendored: example-robot-data < 4.4 lacks it


def random_dh(rng, dof=None, convention=None):
    """A random D-H chain with nonzero a and alpha, some prismatic joints, base and tool."""
    dof = dof or int(rng.integers(1, 8))
    types = ["prismatic" if rng.random() < 0.3 else "revolute" for _ in range(dof)]
    limits = [[-np.pi, np.pi] if t == "revolute" else [-0.2, 0.3] for t in types]
    return DHChain("random", a=rng.uniform(-0.5, 0.5, dof), alpha=rng.uniform(-np.pi, np.pi, dof),
                   d=rng.uniform(-0.5, 0.5, dof), theta=rng.uniform(-np.pi, np.pi, dof), joint_types=types,
                   joint_limits=limits, convention=convention or ("standard" if rng.random() < 0.5 else "modified"),
                   base=transform(rng.uniform(-1, 1, 3), rng.uniform(-np.pi, np.pi, 3)),
                   tool=transform(rng.uniform(-0.2, 0.2, 3), rng.uniform(-np.pi, np.pi, 3)))


def pin_fk(text, tip, chain, q):
    """(n, 4, 4) pose of ``tip`` by pinocchio from the URDF text, at chain configurations q (n, dof)."""
    import pinocchio as pin
    model = pin.buildModelFromXML(text)
    data = model.createData()
    fid = model.getFrameId(tip)
    out = []
    for qk in q:
        cfg = pin.neutral(model)
        for k, name in enumerate(chain.joint_names):
            jid = model.getJointId(name)
            iq = model.idx_qs[jid]
            if model.joints[jid].nq == 2:
                cfg[iq:iq + 2] = (np.cos(qk[k]), np.sin(qk[k]))
            else:
                cfg[iq] = qk[k]
        pin.framesForwardKinematics(model, data, cfg)
        out.append(data.oMf[fid].homogeneous.copy())
    return np.array(out)


def private_domain_id(first: int, span: int) -> int:
    """A ROS_DOMAIN_ID in [first, first + span) for this test process: the pytest-xdist workers of one run
    never share one (the worker index is the residue), other runs are told apart by the process id."""
    worker = os.environ.get("PYTEST_XDIST_WORKER", "gw0")[2:]
    index = int(worker) if worker.isdigit() else 0
    workers = max(1, int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1")))
    return first + (os.getpid() % max(1, span // workers)) * workers + index % workers
