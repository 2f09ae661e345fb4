"""A simulated humanoid standing on one sole and touching a table flush with three fingertips, its joints yielding
under its weight: the contact campaigns of the elastic tests and benchmarks (example-robot-data's
``talos_full_v2.urdf``, the chain from the left sole to the left gripper, the right leg and arm recorded beside it)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .example_robots import example_urdf

URDF = "talos_full_v2.urdf"
BASE, TIP = "left_sole_link", "gripper_left_base_link"
TIPS = np.array([[0.032, 0.05114, -0.12151], [-0.032, 0.05114, -0.12151], [0.0, -0.05114, -0.12151]])   # m
OTHERS = tuple(f"leg_right_{i}_joint" for i in range(1, 7)) + tuple(f"arm_right_{i}_joint" for i in range(1, 8))
RANGES = np.array([[-0.05, 0.21], [-1.00, 0.16], [0.16, 2.05], [-1.71, -0.12], [-0.49, 0.29], [-0.30, 0.31],
                   [-1.20, 0.11], [-0.13, 0.71], [-1.30, 0.35], [1.24, 2.80], [-1.97, 1.83], [-2.16, -0.06],
                   [-2.40, 2.26], [-1.30, 1.33], [-0.67, 0.68]])    # rad: the joints of FIGAROH's left session


def chain():
    """The chain from the left sole to the left gripper."""
    from ..core.models.urdf import URDFChain
    return URDFChain(example_urdf(URDF), tip_link=TIP, base_link=BASE)


def robot_args() -> list:
    """The command-line options of the robot and its chain."""
    return ["--robot", str(example_urdf(URDF)), "--base-link", BASE, "--tip-link", TIP]


def target_args() -> list:
    """``--target`` of the three fingertips at their places (mm)."""
    return [arg for k, t in enumerate(TIPS) for arg in
            ("--target", f"F{k + 1}=" + ",".join(f"{v * 1e3:g}mm" for v in t))]


def other_readings(model, n, rng) -> np.ndarray:
    """(n, len(OTHERS)) seeded readings (rad) of the right leg and arm, within +-0.6 rad and the URDF's limits."""
    pm = model.pin_model
    lo = np.array([pm.lowerPositionLimit[pm.idx_qs[pm.getJointId(j)]] for j in OTHERS])
    hi = np.array([pm.upperPositionLimit[pm.idx_qs[pm.getJointId(j)]] for j in OTHERS])
    return rng.uniform(np.maximum(lo, -0.6), np.minimum(hi, 0.6), (n, len(OTHERS)))


def campaign(model, dx, compliance, table, n, seed, load="standing", encoder=0.0):
    """(joints read (n, dof), other joints' names, their readings (n, m)) of ``n`` postures flush on ``table``
    ((unit normal, offset m) in the sole's frame) of the robot built with errors ``dx``, its joints yielding by
    ``compliance`` (dof,) rad/(N m) times their load at the postures they reach (``elastic.Load`` kind ``load``,
    the right leg and arm at seeded readings within +-0.6 rad), read with encoder noise of std ``encoder`` rad.
    (The calibration's model takes the load at the joints read: where the load grows with the deflection, as a
    standing robot's ankle's does, its compliance comes out as ``c / (1 - c dg/dq)``.)"""
    from ..core.accuracy.simulate import touch
    from ..core.calibration.elastic import Load
    rng = np.random.default_rng(seed)
    q = touch(model.with_joint_limits(RANGES), dx, TIPS, "plane", table, n, seed=[seed, 1])
    others = other_readings(model, len(q), rng)
    read = q - np.asarray(compliance, float) * Load(load).torques(model, q, (OTHERS, others))
    return read + rng.standard_normal(read.shape) * encoder, OTHERS, others


def write_campaign(path, q, other_names, others, session) -> Path:
    """The contact CSV of a ``campaign`` (every joint's column, the chain's and the others')."""
    from ..core.accuracy.io.contact_csv import write_contacts
    model_names = chain().joint_names
    n = len(q)
    rows = np.repeat(np.arange(n), len(TIPS))
    joints = np.c_[q, others][rows]
    return write_contacts(path, rows.astype(float), [f"P{i + 1:02d}" for i in rows], [session] * len(rows),
                          [f"F{k + 1}" for k in range(len(TIPS))] * n, ["plane:table"] * len(rows), joints,
                          tuple(model_names) + tuple(other_names))
