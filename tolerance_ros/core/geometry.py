"""Rotations and rigid transforms, batched: one implementation of each formula (SI: m, rad).

Conventions (REP 103, URDF): roll-pitch-yaw are fixed-axis angles, ``R = Rz(yaw) Ry(pitch) Rx(roll)``;
quaternions are ``(x, y, z, w)``; a rotation vector ``w`` is the axis times the angle; a small rotation
error ``dphi`` is expressed in the base frame, ``R_actual = exp([dphi]x) R_nominal``.

Layouts: ``*_matrices`` functions take the angle or vector in the last axis and return ``(..., 3, 3)``;
``rpy_matrix`` and ``axis_angle_matrix`` return the ``(3, 3, ...)`` layout that serial chains use when
they are batched over a trailing axis of poses.
"""
from __future__ import annotations

import math

import numpy as np


# The vee map of a skew-symmetric part reads R[_VEE_I, _VEE_J] - R[_VEE_J, _VEE_I].
_VEE_I, _VEE_J = np.array([2, 0, 1]), np.array([1, 2, 0])


def rpy_matrix(roll, pitch, yaw) -> np.ndarray:
    """(3, 3, ...) rotations ``Rz(yaw) Ry(pitch) Rx(roll)`` of broadcastable angle arrays (rad)."""
    cr, sr, cp, sp, cy, sy = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch), np.cos(yaw), np.sin(yaw)
    cr, sr, cp, sp, cy, sy = np.broadcast_arrays(cr, sr, cp, sp, cy, sy)
    return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]])


def rpy_to_matrices(rpy) -> np.ndarray:
    """(..., 3, 3) rotations of (..., 3) roll-pitch-yaw angles (rad)."""
    rpy = np.asarray(rpy, dtype=float)
    return np.moveaxis(rpy_matrix(rpy[..., 0], rpy[..., 1], rpy[..., 2]), (0, 1), (-2, -1))


def rpy_to_matrix(rpy) -> np.ndarray:
    """3x3 rotation of one roll-pitch-yaw triple (rad)."""
    return rpy_to_matrices(np.asarray(rpy, dtype=float).reshape(3))


def rpy_from_matrix(R) -> np.ndarray:
    """(n, 3) roll, pitch, yaw (rad) of (n, 3, 3) rotations (pitch in [-pi/2, pi/2]).

    Pitch from atan2 (arcsin loses half the digits near +-pi/2) and roll from the rotation left after
    yaw, so the angles rebuild the matrix to rounding error also at and near gimbal lock.
    """
    R = np.asarray(R, dtype=float).reshape(-1, 3, 3)
    pitch = np.arctan2(-R[:, 2, 0], np.hypot(R[:, 0, 0], R[:, 1, 0]))
    yaw = np.arctan2(R[:, 1, 0], R[:, 0, 0])
    cy, sy = np.cos(yaw), np.sin(yaw)
    roll = np.arctan2(sy * R[:, 0, 2] - cy * R[:, 1, 2], cy * R[:, 1, 1] - sy * R[:, 0, 1])
    return np.stack([roll, pitch, yaw], axis=1)


def axis_angle_matrix(axis, angle) -> np.ndarray:
    """(3, 3, ...) rotations by ``angle`` (rad, any shape) about the unit ``axis`` (3,) (Rodrigues)."""
    angle = np.asarray(angle, dtype=float)
    c, s = np.cos(angle), np.sin(angle)
    v = 2.0 * np.sin(angle / 2.0) ** 2  # 1 - cos, without cancellation at small angles
    x, y, z = (float(a) for a in axis)
    return np.array([[c + x * x * v, x * y * v - z * s, x * z * v + y * s],
                     [y * x * v + z * s, c + y * y * v, y * z * v - x * s],
                     [z * x * v - y * s, z * y * v + x * s, c + z * z * v]])


def axis_rotations(axis: int, angle) -> np.ndarray:
    """(..., 3, 3) rotations by ``angle`` (rad, any shape) about base axis 0 (x), 1 (y) or 2 (z)."""
    return np.moveaxis(axis_angle_matrix(np.eye(3)[axis], angle), (0, 1), (-2, -1))


def exp_so3(w) -> np.ndarray:
    """(n, 3, 3) rotation matrices ``exp([w]x)`` of (n, 3) rotation vectors (rad)."""
    w = np.asarray(w, dtype=float).reshape(-1, 3)
    th = np.linalg.norm(w, axis=1)
    u = w / np.where(th > 0, th, 1.0)[:, None]
    c, s = np.cos(th), np.sin(th)
    v = 2.0 * np.sin(th / 2.0) ** 2
    x, y, z = u.T
    return np.stack([np.stack([c + x * x * v, x * y * v - z * s, x * z * v + y * s], -1),
                     np.stack([y * x * v + z * s, c + y * y * v, y * z * v - x * s], -1),
                     np.stack([z * x * v - y * s, z * y * v + x * s, c + z * z * v], -1)], 1)


def matrix_log_vec(R) -> np.ndarray:
    """(n, 3) rotation vectors of (n, 3, 3) rotation matrices (robust near 0 and pi)."""
    R = np.asarray(R, dtype=float).reshape(-1, 3, 3)
    cos = (np.einsum("nii->n", R) - 1.0) / 2.0
    w = R[:, _VEE_I, _VEE_J] - R[:, _VEE_J, _VEE_I]
    sin2 = np.sqrt(np.einsum("ni,ni->n", w, w))  # 2 sin(angle)
    angle = np.arctan2(sin2 / 2.0, cos)  # accurate at every angle, unlike arccos near 0 and pi
    small = angle < 1e-6
    scale = np.where(small, 0.5 + angle ** 2 / 12.0, angle / np.where(small, 1.0, sin2))
    out = w * scale[:, None]
    near = angle > np.pi - 1e-4
    if near.any():
        near_pi = np.flatnonzero(near)
        # The symmetric part is cos I + (1 - cos) u u^T: the axis up to its sign, which w gives.
        S = (R[near_pi] + R[near_pi].transpose(0, 2, 1)) / 2.0
        c = cos[near_pi, None, None]
        U = (S - c * np.eye(3)) / (1.0 - c)
        k = np.argmax(np.diagonal(U, axis1=1, axis2=2), axis=1)
        rows = np.arange(near_pi.size)
        axis = U[rows, :, k] / np.sqrt(np.maximum(U[rows, k, k], 1e-300))[:, None]
        axis /= np.linalg.norm(axis, axis=1, keepdims=True)
        flip = np.einsum("ni,ni->n", axis, w[near_pi]) < 0
        axis[flip] *= -1.0
        out[near_pi] = axis * angle[near_pi, None]
    return out


def rotation_error(R_actual, R_nominal) -> np.ndarray:
    """(n, 3) rotation vector dphi (base frame, rad) with ``R_actual = exp([dphi]x) R_nominal``."""
    return matrix_log_vec(np.matmul(np.asarray(R_actual, float), np.swapaxes(np.asarray(R_nominal, float), -1, -2)))


def quat_to_matrices(q) -> np.ndarray:
    """(n, 3, 3) rotations of (n, 4) quaternions (x, y, z, w), normalised; a zero quaternion raises ValueError."""
    q = np.asarray(q, dtype=float).reshape(-1, 4)
    if len(q) == 1:  # one pose (a message): plain floats, a tenth of the array arithmetic's overhead
        return _quat_to_matrix(*q[0].tolist())[None]
    m = np.abs(q).max(axis=1)
    if not (np.all(m >= 1e-9) and np.all(m < np.inf)):  # 1 <= |q| / max|q_i| <= 2
        raise ValueError("quaternion with zero (or non-finite) norm")
    q = q / m[:, None]  # scaled first, so that huge finite components do not overflow
    x, y, z, w = q.T
    s = 2.0 / (x * x + y * y + z * z + w * w)
    xs, ys, zs = x * s, y * s, z * s
    wx, wy, wz, xx, xy, xz, yy, yz, zz = w * xs, w * ys, w * zs, x * xs, x * ys, x * zs, y * ys, y * zs, z * zs
    R = np.empty((len(q), 3, 3))
    R[:, 0, 0], R[:, 0, 1], R[:, 0, 2] = 1.0 - (yy + zz), xy - wz, xz + wy
    R[:, 1, 0], R[:, 1, 1], R[:, 1, 2] = xy + wz, 1.0 - (xx + zz), yz - wx
    R[:, 2, 0], R[:, 2, 1], R[:, 2, 2] = xz - wy, yz + wx, 1.0 - (xx + yy)
    return R


def _quat_to_matrix(x, y, z, w) -> np.ndarray:
    """(3, 3) rotation of one quaternion (x, y, z, w), normalised (see ``quat_to_matrices``)."""
    m = max(abs(x), abs(y), abs(z), abs(w))
    if not (1e-9 <= m and math.isfinite(x + y + z + w)):
        raise ValueError("quaternion with zero (or non-finite) norm")
    x, y, z, w = x / m, y / m, z / m, w / m
    s = 2.0 / (x * x + y * y + z * z + w * w)
    xs, ys, zs = x * s, y * s, z * s
    wx, wy, wz, xx, xy, xz, yy, yz, zz = w * xs, w * ys, w * zs, x * xs, x * ys, x * zs, y * ys, y * zs, z * zs
    return np.array([[1.0 - (yy + zz), xy - wz, xz + wy], [xy + wz, 1.0 - (xx + zz), yz - wx],
                     [xz - wy, yz + wx, 1.0 - (xx + yy)]])


def matrices_to_quat(R) -> np.ndarray:
    """(n, 4) unit quaternions (x, y, z, w), w >= 0, of (n, 3, 3) rotations (Shepperd's method)."""
    R = np.asarray(R, dtype=float).reshape(-1, 3, 3)
    d0, d1, d2 = R[:, 0, 0], R[:, 1, 1], R[:, 2, 2]
    # Four candidate formulas; each row takes the one with the largest (best conditioned) root.
    roots = np.stack([1 + d0 + d1 + d2, 1 + d0 - d1 - d2, 1 - d0 + d1 - d2, 1 - d0 - d1 + d2], axis=1)
    k = np.argmax(roots, axis=1)
    s = 2.0 * np.sqrt(np.maximum(roots[np.arange(len(R)), k], 1e-300))
    a, b = R[:, 2, 1] - R[:, 1, 2], R[:, 0, 2] - R[:, 2, 0]
    c, d = R[:, 1, 0] - R[:, 0, 1], R[:, 0, 1] + R[:, 1, 0]
    e, f = R[:, 0, 2] + R[:, 2, 0], R[:, 1, 2] + R[:, 2, 1]
    cand = np.stack([np.stack([a / s, b / s, c / s, s / 4], -1),
                     np.stack([s / 4, d / s, e / s, a / s], -1),
                     np.stack([d / s, s / 4, f / s, b / s], -1),
                     np.stack([e / s, f / s, s / 4, c / s], -1)], axis=1)
    q = cand[np.arange(len(R)), k]
    q[q[:, 3] < 0] *= -1.0
    return q


def transform(xyz=(0.0, 0.0, 0.0), rpy=(0.0, 0.0, 0.0)) -> np.ndarray:
    """4x4 homogeneous transform from a translation (m) and roll-pitch-yaw (rad)."""
    T = np.eye(4)
    T[:3, :3] = rpy_to_matrix(rpy)
    T[:3, 3] = np.asarray(xyz, dtype=float)
    return T


def pose_matrices(p, R) -> np.ndarray:
    """(n, 4, 4) transforms from positions (n, 3), m, and rotations (n, 3, 3)."""
    p = np.asarray(p, dtype=float).reshape(-1, 3)
    T = np.zeros((len(p), 4, 4))
    T[:, :3, :3] = R
    T[:, :3, 3] = p
    T[:, 3, 3] = 1.0
    return T


def cross3(a, b):
    """Cross product of (3, ...) column stacks (the vector in the first axis)."""
    return np.stack((a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]))
