"""The orientations programs write, to and from rotation matrices, and the written values nearest a new rotation.

- ``quat``: ABB's quaternion [q1, q2, q3, q4] = [w, x, y, z] (normalised on reading, as the controller does);
- ``zyx``: KUKA's A, B, C (deg): ``R = Rz(A) Ry(B) Rx(C)``;
- ``wpr``: FANUC's W, P, R (deg), turns about the fixed x, y, z axes: ``R = Rz(R) Ry(P) Rx(W)``;
- ``rotvec``: Universal Robots' rotation vector [rx, ry, rz] (rad), the axis times the angle.

``nearest`` writes a new rotation in the values nearest the old ones (Gauss-Newton from them, the smallest change
where the values are not unique: Euler angles at +-90 deg, a rotation vector at pi, a quaternion's sign): an
unchanged rotation keeps its values to the last bit, and a small correction changes them by a small amount, never
by a branch or a turn.
"""
from __future__ import annotations

import numpy as np

from ..geometry import exp_so3, quat_to_matrices, rotation_error, rpy_to_matrices

KINDS = ("quat", "zyx", "wpr", "rotvec")


def to_matrix(kind: str, values) -> np.ndarray:
    """(n, 3, 3) rotations of (n, k) written values (angles in degrees for zyx and wpr)."""
    v = np.atleast_2d(np.asarray(values, float))
    if kind == "quat":
        return quat_to_matrices(v[:, [1, 2, 3, 0]])
    if kind == "zyx":
        return rpy_to_matrices(np.radians(v[:, [2, 1, 0]]))
    if kind == "wpr":
        return rpy_to_matrices(np.radians(v))
    if kind == "rotvec":
        return exp_so3(v)
    raise ValueError(f"orientation: unknown kind {kind!r}")


GIMBAL = 1e-7   # cos(pitch) below which only the sum or the difference of the other two angles is defined


def _wrap_near(x, ref):
    return x + 2 * np.pi * np.round((ref - x) / (2 * np.pi))


def _nearest_rpy(old, R):
    """(n, 3) roll, pitch, yaw (rad) of ``R`` nearest ``old``: both branches of the pitch, each angle the turn
    nearest its old value; at +-90 deg of pitch, the pair of roll and yaw nearest the old pair."""
    r0, p0, y0 = old.T
    cp = np.hypot(R[:, 0, 0], R[:, 1, 0])
    p = np.arctan2(-R[:, 2, 0], cp)
    y = np.arctan2(R[:, 1, 0], R[:, 0, 0])
    r = np.arctan2(R[:, 2, 1], R[:, 2, 2])
    cands = []
    for rr, pp, yy in ((r, p, y), (r + np.pi, np.pi - p, y + np.pi)):
        c = np.stack([_wrap_near(rr, r0), _wrap_near(pp, p0), _wrap_near(yy, y0)], axis=1)
        cands.append(c)
    cands = np.stack(cands, axis=1)
    best = cands[np.arange(len(old)), np.argmin(np.linalg.norm(cands - old[:, None], axis=2), axis=1)]
    lock = cp < GIMBAL
    if lock.any():
        i = np.flatnonzero(lock)
        up = R[i, 2, 0] < 0                                  # pitch +90: roll - yaw is defined; -90: roll + yaw
        d = np.where(up, np.arctan2(R[i, 0, 1], R[i, 1, 1]), np.arctan2(-R[i, 0, 1], R[i, 1, 1]))
        a, b = r0[i], y0[i]
        d = _wrap_near(d, np.where(up, a - b, a + b))
        roll = np.where(up, (a + b + d) / 2, (a - b + d) / 2)
        yaw = np.where(up, (a + b - d) / 2, (b - a + d) / 2)
        best[i] = np.stack([roll, _wrap_near(np.where(up, np.pi / 2, -np.pi / 2), p0[i]), yaw], axis=1)
    return best


def nearest(kind: str, old, R_new, iterations: int = 6) -> np.ndarray:
    """(n, k) values of ``kind`` that give the rotations ``R_new`` (n, 3, 3), nearest the ``old`` values (n, k)."""
    x = np.array(np.atleast_2d(np.asarray(old, float)))
    R_new = np.asarray(R_new, float).reshape(-1, 3, 3)
    if kind == "wpr":
        return np.degrees(_nearest_rpy(np.radians(x), R_new))
    if kind == "zyx":
        return np.degrees(_nearest_rpy(np.radians(x[:, ::-1]), R_new))[:, ::-1]
    h = 1e-6
    for _ in range(iterations):
        e = rotation_error(R_new, to_matrix(kind, x))
        if np.all(np.abs(e) < 1e-15):
            break
        J = np.empty((len(x), 3, x.shape[1]))
        for k in range(x.shape[1]):
            dx = np.zeros(x.shape[1])
            dx[k] = h
            J[:, :, k] = (rotation_error(to_matrix(kind, x + dx), to_matrix(kind, x - dx))) / (2 * h)
        step = np.einsum("nij,nj->ni", np.linalg.pinv(J, rcond=1e-10), e)
        x = x + step
    return x
