"""A calibrated Universal Robots arm for its ROS 2 driver: the ``kinematics_params`` file of Universal Robots'
description (``ur_description``), the format its calibration tool (``ur_calibration``) writes.

The description builds the arm as ``base_link`` -> ``base_link_inertia`` (a turn of pi about z: the controller's
base frame) -> one joint per link, each turning about the z axis of its origin ``x, y, z, roll, pitch, yaw``
(``shoulder``, ``upper_arm``, ``forearm``, ``wrist_1``, ``wrist_2``, ``wrist_3``) -> ``wrist_3_link``, which is
``tool0``. Any frame on a joint's axis, z along it, serves as that link's frame; the export takes, for each link,
the nominal frame of UR's Denavit-Hartenberg convention moved the least onto the calibrated axis (its origin the
point of the axis nearest the nominal one, its x axis the nominal one made square to the axis), and ``wrist_3``
the calibrated ``tool0``. The six origins then reproduce the calibrated robot exactly (the joints turn about the
calibrated axes, from the calibrated zeros), with the calibration's base correction in ``shoulder``; with no
calibration they are UR's default kinematics of the arm. The nominal convention is fitted to the robot model given
(d1, a2, a3, d4, d5, d6 by least squares over postures, and where the model's base frame lies in the controller's):
a model that is not a UR arm in UR's joint conventions, to 1 um and 1 urad, is refused.

Angles are written in the URDF's own convention, ``R = Rz(yaw) Ry(pitch) Rx(roll)``, which the description applies
(``ur_calibration`` writes Eigen's ``eulerAngles(0, 1, 2)``, ``R = Rx Ry Rz``; both agree on UR's default values).
``hash`` names the calibration: it is not the controller's, so the driver reports that the description's
kinematics differ from the controller's own calibration, which is true. SI: m, rad.
"""
from __future__ import annotations

import numpy as np

from ..geometry import rpy_from_matrix, transform
from ..models.base import Mechanism, ModelError
from ..models.ik import joint_jacobian

LINKS = ("shoulder", "upper_arm", "forearm", "wrist_1", "wrist_2", "wrist_3")
ALPHA = (np.pi / 2, 0.0, 0.0, np.pi / 2, -np.pi / 2, 0.0)
FIT_TOL = 1e-6        # m and rad: a model within this of UR's convention is a UR arm
EXACT_TOL = 1e-9      # m and rad: the file reproduces the calibrated robot this closely (checked before writing)
ZERO = 1e-11          # m and rad: a value below this is written 0 (the rounding of the frames' construction)


def _rx(a):
    return transform([0, 0, 0], [a, 0, 0])


def _dh(q, lengths):
    """(n, 4, 4) UR's DH forward kinematics; ``lengths`` (d1, a2, a3, d4, d5, d6)."""
    d1, a2, a3, d4, d5, d6 = lengths
    a = (0.0, a2, a3, 0.0, 0.0, 0.0)
    d = (d1, 0.0, 0.0, d4, d5, d6)
    q = np.atleast_2d(q)
    T = np.tile(np.eye(4), (len(q), 1, 1))
    for i in range(6):
        c, s = np.cos(q[:, i]), np.sin(q[:, i])
        ca, sa = np.cos(ALPHA[i]), np.sin(ALPHA[i])
        A = np.zeros((len(q), 4, 4))
        A[:, 0] = np.stack([c, -s * ca, s * sa, a[i] * c], axis=1)
        A[:, 1] = np.stack([s, c * ca, -c * sa, a[i] * s], axis=1)
        A[:, 2, 1], A[:, 2, 2], A[:, 2, 3], A[:, 3, 3] = sa, ca, d[i], 1.0
        T = T @ A
    return T


def fit_convention(model: Mechanism, samples: int = 24, seed: int = 0):
    """(lengths (6,), C 4x4: the controller's base frame in the model's base frame) of UR's DH convention fitted to
    ``model``; ModelError when the model is not a UR arm in UR's joint conventions."""
    if model.dof != 6 or any(t == "prismatic" for t in model.joint_types):
        raise ModelError(f"robot {model.name!r} is not a 6-joint revolute arm: not a UR arm")
    q = np.vstack([np.zeros(6), np.random.default_rng(seed).uniform(-np.pi, np.pi, (samples, 6))])
    T = model.fk(q)
    R0 = _dh(q, np.ones(6))[:, :3, :3]
    Rc = T[:, :3, :3] @ np.swapaxes(R0, 1, 2)
    spread = np.abs(Rc - Rc[0]).max()
    if spread > FIT_TOL:
        raise ModelError(f"robot {model.name!r}: its joints do not turn as a UR arm's do (zeros, signs or axes differ "
                         f"from UR's convention by {spread:.2g}); give the chain from base_link to tool0 of a UR arm")
    # position per length (n, 3, 6); the base frame's origin is taken on the model's base plane (a shift along joint
    # 1's axis is d1's): its x and y in the controller's base frame are fitted with the lengths
    G = np.stack([_dh(q, np.eye(6)[k])[:, :3, 3] for k in range(6)], axis=2)
    A = np.concatenate([np.einsum("ij,njk->nik", Rc[0], G), np.tile(Rc[0][:, :2], (len(q), 1, 1))], axis=2)
    sol, *_ = np.linalg.lstsq(A.reshape(-1, 8), T[:, :3, 3].reshape(-1), rcond=None)
    resid = np.abs(A.reshape(-1, 8) @ sol - T[:, :3, 3].reshape(-1)).max()
    if resid > FIT_TOL:
        raise ModelError(f"robot {model.name!r}: its geometry is not UR's (d1, a2, a3, d4, d5, d6): the best fit "
                         f"leaves {resid * 1e3:.3g} mm; give the chain from base_link to tool0 of a UR arm")
    C = np.eye(4)
    C[:3, :3], C[:3, 3] = Rc[0], Rc[0][:, :2] @ sol[6:]
    return sol[:6], C


def nominal_frames(lengths) -> np.ndarray:
    """(6, 4, 4) UR's link frames at zero joints in the controller's base frame (DH: Rz(theta) Tz(d), then Tx(a)
    Rx(alpha) to the next)."""
    d1, a2, a3, d4, d5, d6 = lengths
    L = [transform([0, 0, d1])]
    L.append(L[0] @ _rx(np.pi / 2))
    L.append(L[1] @ transform([a2, 0, 0]))
    L.append(L[2] @ transform([a3, 0, 0]) @ transform([0, 0, d4]))
    L.append(L[3] @ _rx(np.pi / 2) @ transform([0, 0, d5]))
    L.append(L[4] @ _rx(-np.pi / 2) @ transform([0, 0, d6]))
    return np.array(L)


def calibrated_frames(model: Mechanism, calibrated: Mechanism):
    """((6, 4, 4) link frames of the calibrated arm at zero joints in the controller's base frame, lengths, C)."""
    lengths, C = fit_convention(model)
    nominal = nominal_frames(lengths)
    Ci = np.linalg.inv(C)
    T0, J0 = joint_jacobian(calibrated, np.zeros((1, 6)))
    T0 = Ci @ T0[0]
    w = Ci[:3, :3] @ J0[0, 3:]
    v = Ci[:3, :3] @ J0[0, :3]
    p = T0[:3, 3]
    frames = np.empty((6, 4, 4))
    for k in range(5):
        d = w[:, k] / np.linalg.norm(w[:, k])
        point = p + np.cross(d, v[:, k])
        o = nominal[k, :3, 3]
        origin = point + ((o - point) @ d) * d
        x = nominal[k, :3, 0] - (nominal[k, :3, 0] @ d) * d
        x /= np.linalg.norm(x)
        frames[k] = np.eye(4)
        frames[k, :3, :3] = np.stack([x, np.cross(d, x), d], axis=1)
        frames[k, :3, 3] = origin
    frames[5] = T0
    d6 = w[:, 5] / np.linalg.norm(w[:, 5])
    if np.linalg.norm(np.cross(T0[:3, 2], d6)) > FIT_TOL:
        raise ModelError(f"robot {model.name!r}: its tool frame's z axis is not joint 6's axis: give the chain to "
                         f"tool0")
    return frames, lengths, C


def kinematics(model: Mechanism, calibrated: Mechanism, hash_text: str) -> dict:
    """The ``kinematics`` document: {link: {x, y, z, roll, pitch, yaw}, hash}; checked against the calibrated robot
    (ModelError, a bug, when the file would not reproduce it)."""
    frames, lengths, C = calibrated_frames(model, calibrated)
    doc, prev = {}, np.eye(4)
    for name, L in zip(LINKS, frames):
        P = np.linalg.inv(prev) @ L
        rpy = rpy_from_matrix(P[None, :3, :3])[0]
        values = np.where(np.abs(np.r_[P[:3, 3], rpy]) < ZERO, 0.0, np.r_[P[:3, 3], rpy]) + 0.0
        doc[name] = dict(zip(("x", "y", "z", "roll", "pitch", "yaw"), map(float, values)))
        P = transform(values[:3], values[3:])
        prev = L
    q = np.random.default_rng(1).uniform(-np.pi, np.pi, (16, 6))
    ours = np.linalg.inv(C) @ calibrated.fk(q)
    theirs = description_fk(doc, q)
    err = max(np.abs(ours[:, :3, 3] - theirs[:, :3, 3]).max(), np.abs(ours[:, :3, :3] - theirs[:, :3, :3]).max())
    if err > EXACT_TOL:
        raise ModelError(f"kinematics: the file would put tool0 {err:.3g} m or rad from the calibrated robot (a bug)")
    doc["hash"] = hash_text
    return {"kinematics": doc, "lengths": lengths, "base": C, "error": float(err)}


def description_fk(doc: dict, q) -> np.ndarray:
    """(n, 4, 4) tool0 in the controller's base frame (base_link_inertia) as the description builds it from
    ``doc`` (each joint about the z axis of its origin, origin rpy applied as the URDF does)."""
    q = np.atleast_2d(q)
    T = np.tile(np.eye(4), (len(q), 1, 1))
    for k, name in enumerate(LINKS):
        e = doc[name]
        O = transform([e["x"], e["y"], e["z"]], [e["roll"], e["pitch"], e["yaw"]])
        c, s = np.cos(q[:, k]), np.sin(q[:, k])
        Rz = np.tile(np.eye(4), (len(q), 1, 1))
        Rz[:, 0, 0], Rz[:, 0, 1], Rz[:, 1, 0], Rz[:, 1, 1] = c, -s, s, c
        T = T @ O @ Rz
    return T


def text(result: dict, header: list) -> str:
    """The kinematics file's YAML (UR's layout: one key a line, full precision)."""
    lines = [f"# {h}" for h in header] + ["kinematics:"]
    for name in LINKS:
        lines.append(f"  {name}:")
        for key in ("x", "y", "z", "roll", "pitch", "yaw"):
            lines.append(f"    {key}: {result['kinematics'][name][key]!r}")
    lines.append(f"  hash: {result['kinematics']['hash']}")
    return "\n".join(lines) + "\n"
