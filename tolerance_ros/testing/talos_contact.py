"""FIGAROH's TALOS table-contact sessions (``../shared/data/talos_table_contact``, Apache-2.0; not in the repository)
as contact campaigns, for tests and benchmarks: where the data live, the chain, the fingertips' nominal places, and
the files turned into the contact CSV (``core.accuracy.io.contact_csv``) that ``calibrate`` and ``validate`` read.

A data row of the FIGAROH file is ``gripper, talos/<side>_gripper, handle, table/contact_NN, joint_states`` and 32
joint values (rad) in ``JOINTS`` order; some header lines are shifted, so rows are read by position. Each posture
becomes three contact rows (the three fingertips flush on the table, ``plane:table``), its pose named by its row.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .example_robots import example_urdf



def shared_data(name) -> Path:
    """The public data set ``name`` of ``shared/data/`` beside the repository (``../shared/data`` from its root, or
    from a folder above it where the checkout is a worktree in a subfolder); the first place when none has it."""
    root = Path(__file__).resolve().parents[2]
    for up in (root, *root.parents):
        if (up.parent / "shared" / "data" / name).is_dir():
            return up.parent / "shared" / "data" / name
    return root.parent / "shared" / "data" / name


DATA = shared_data("talos_table_contact")
URDF = "talos_full_v2.urdf"
SESSIONS = {"left": "left_train.csv", "right": "right_train.csv"}
JOINTS = ([f"arm_left_{i}_joint" for i in range(1, 8)] + [f"arm_right_{i}_joint" for i in range(1, 8)]
          + ["gripper_left_joint", "gripper_right_joint", "head_1_joint", "head_2_joint"]
          + [f"leg_left_{i}_joint" for i in range(1, 7)] + [f"leg_right_{i}_joint" for i in range(1, 7)]
          + ["torso_1_joint", "torso_2_joint"])
FINGERTIPS = {"F1": (32.0, 51.14, -121.51), "F2": (-32.0, 51.14, -121.51), "F3": (0.0, -51.14, -121.51)}   # mm


def available() -> bool:
    """True when both training sessions are on this machine."""
    return all((DATA / f).is_file() for f in SESSIONS.values())


def chain(side) -> tuple:
    """(base link, tip link) of a side's chain: the sole on the floor to the gripper."""
    return f"{side}_sole_link", f"gripper_{side}_base_link"


def robot_args(side) -> list:
    """The command-line options of the robot and its chain for ``side``."""
    base, tip = chain(side)
    return ["--robot", str(example_urdf(URDF)), "--base-link", base, "--tip-link", tip]


def target_args() -> list:
    """``--target NAME=X,Y,Z`` of the three fingertips at their nominal places (mm, gripper frame)."""
    out = []
    for name, xyz in FINGERTIPS.items():
        out += ["--target", f"{name}=" + ",".join(f"{v:g}mm" for v in xyz)]
    return out


def postures(path) -> tuple:
    """((n, 32) joints rad in ``JOINTS`` order, (n,) the table spot of each) of a FIGAROH file's data rows."""
    q, spots = [], []
    for line in Path(path).read_text().splitlines():
        fields = line.split(",")
        if fields[0].strip() != "gripper":
            continue
        q.append([float(v) for v in fields[5:5 + len(JOINTS)]])
        spots.append(fields[3].strip())
    return np.array(q, float), spots


def write_campaign(side, out, session=None, q=None, source=None) -> Path:
    """The contact CSV at ``out`` of ``side``'s training session, or of another FIGAROH session file ``source`` of
    that side (another table set-up), every one of its 32 joints a column (the rest of the posture loads the
    chain's joints); ``q`` instead of the file's joints when given; the session named ``session`` (default: the
    file's stem)."""
    from ..core.accuracy.io.contact_csv import write_contacts
    src = Path(source) if source is not None else DATA / SESSIONS[side]
    q_file, spots = postures(src)
    q = q_file if q is None else np.asarray(q, float)
    names = list(FINGERTIPS)
    n = len(q)
    rows = np.repeat(np.arange(n), len(names))
    return write_contacts(out, rows.astype(float), [f"row{i + 1:02d}" for i in rows], [session or src.stem] * len(rows),
                          names * n, ["plane:table"] * len(rows), q[rows], JOINTS,
                          comments=[f"{src.name} of FIGAROH's TALOS table contact (Apache-2.0), {n} postures: the "
                                    f"three fingertips flush on the table"])


def independent_joint_offsets(side, folds=10, seed=0) -> np.ndarray:
    """(n, 3) held-out distances (m) of each posture's fingertips under an independent fit, the reference of the
    real-data tests and benchmark: pinocchio's forward kinematics of the whole ``talos_full_v2.urdf`` (the sole's
    and the gripper's frames), scipy's least_squares (trust-region reflective, tolerances 1e-12) on the 15 joint
    offsets of the chain and one plane per session, the fingertips at their nominal places; each fold's postures
    (``crossval.folds_of``, one posture a group, as ``calibrate`` splits them) scored against the plane its
    training postures fitted."""
    import pinocchio as pin
    from scipy.optimize import least_squares
    from ..core.accuracy.folds import folds_of
    model = pin.buildModelFromUrdf(str(example_urdf(URDF)))
    data = model.createData()
    tips = np.array(list(FINGERTIPS.values())) * 1e-3
    q32, _ = postures(DATA / SESSIONS[side])
    n = len(q32)
    Q = np.zeros((n, model.nq))
    Q[:, [model.joints[model.getJointId(j)].idx_q for j in JOINTS]] = q32
    chain_joints = ([f"leg_{side}_{i}_joint" for i in range(6, 0, -1)] + ["torso_1_joint", "torso_2_joint"]
                    + [f"arm_{side}_{i}_joint" for i in range(1, 8)])
    cols = [model.joints[model.getJointId(j)].idx_q for j in chain_joints]
    sole, gripper = model.getFrameId(f"{side}_sole_link"), model.getFrameId(f"gripper_{side}_base_link")

    def points(offsets):
        out = np.empty((n, len(tips), 3))
        for i in range(n):
            q = Q[i].copy()
            q[cols] += offsets
            pin.framesForwardKinematics(model, data, q)
            T = data.oMf[sole].inverse() * data.oMf[gripper]
            out[i] = tips @ T.rotation.T + T.translation
        return out

    def normal(a, b):
        v = np.array([a, b, 1.0])
        return v / np.linalg.norm(v)

    fold, k = folds_of(np.arange(n), folds, seed)
    nominal = points(np.zeros(len(cols)))
    dist = np.empty((n, len(tips)))
    for f in range(k):
        train, test = np.flatnonzero(fold != f), np.flatnonzero(fold == f)
        X = nominal[train].reshape(-1, 3)
        c = X.mean(axis=0)
        m = np.linalg.svd(X - c)[2][2]
        m = m / m[2]
        z0 = np.r_[np.zeros(len(cols)), m[0], m[1], normal(m[0], m[1]) @ c]
        sol = least_squares(lambda z: (points(z[:-3])[train] @ normal(z[-3], z[-2]) - z[-1]).ravel(), z0,
                            method="trf", x_scale=1e-2, xtol=1e-12, ftol=1e-12, gtol=1e-12)
        z = sol.x
        dist[test] = np.abs(points(z[:-3])[test] @ normal(z[-3], z[-2]) - z[-1])
    return dist
