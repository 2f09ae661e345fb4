"""ISO 9283 pose characteristics and the ISO test cube.

For one test pose visited ``n`` times (30 by default in a campaign), with commanded pose ``c`` and
attained poses ``j = 1..n`` (positions in m, orientations as REP 103 roll-pitch-yaw a, b, c in rad,
``R = Rz(c) Ry(b) Rx(a)``, the same convention as the 3-PUPS paper's alpha, beta, gamma):

- pose accuracy:      ``AP_x = x_bar - x_c`` (and y, z), ``AP_p = sqrt(AP_x^2 + AP_y^2 + AP_z^2)``;
- orientation accuracy: ``AP_a = a_bar - a_c`` (and b, c), angle differences wrapped to (-pi, pi];
- pose repeatability: ``RP_l = l_bar + 3 S_l``, ``l_j = |p_j - p_bar|``,
  ``S_l = sqrt(sum (l_j - l_bar)^2 / (n - 1))``;
- orientation repeatability: ``RP_a = 3 S_a`` with ``S_a = sqrt(sum (a_j - a_bar)^2 / (n - 1))`` (b, c).
Means of angles are taken of their deviations from the commanded angle, so wrapping cannot bias them.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from ..geometry import rpy_from_matrix


def wrap(angle):
    """Angles wrapped to (-pi, pi]."""
    a = np.asarray(angle, dtype=float)
    return np.pi - np.mod(np.pi - a, 2.0 * np.pi)


@dataclass
class PoseCharacteristics:
    """ISO 9283 figures of one test pose (m, rad; the orientation figures are None for measured points)."""

    n: int
    AP_p: float
    AP_x: float
    AP_y: float
    AP_z: float
    AP_a: float
    AP_b: float
    AP_c: float
    RP_l: float
    RP_a: float
    RP_b: float
    RP_c: float
    l_bar: float
    S_l: float

    def to_dict(self) -> dict:
        return asdict(self)


def pose_characteristics(commanded, attained, orientation: bool = True) -> PoseCharacteristics:
    """ISO 9283 AP and RP of one test pose.

    commanded : 4x4 commanded (nominal) pose.  attained : (n, 4, 4) measured poses, n >= 2.
    orientation : False for measured points: the orientation figures are None (nothing measured them).
    """
    T = np.asarray(attained, dtype=float)
    C = np.asarray(commanded, dtype=float)
    if T.ndim != 3 or T.shape[1:] != (4, 4) or len(T) < 2:
        raise ValueError(f"attained: expected (n >= 2, 4, 4) poses, got shape {T.shape}")
    if C.shape != (4, 4):
        raise ValueError(f"commanded: expected a 4x4 pose, got shape {C.shape}")
    if not (np.all(np.isfinite(T)) and np.all(np.isfinite(C))):
        raise ValueError("poses must be finite")
    n = len(T)
    p = T[:, :3, 3]
    pbar = p.mean(axis=0)
    ap = pbar - C[:3, 3]
    l = np.linalg.norm(p - pbar, axis=1)
    lbar = l.mean()
    S_l = np.sqrt(np.sum((l - lbar) ** 2) / (n - 1))
    if not orientation:
        return PoseCharacteristics(n, float(np.linalg.norm(ap)), *map(float, ap), None, None, None,
                                   float(lbar + 3 * S_l), None, None, None, float(lbar), float(S_l))
    dang = wrap(rpy_from_matrix(T[:, :3, :3]) - rpy_from_matrix(C[None, :3, :3]))
    abar = dang.mean(axis=0)
    S_ang = np.sqrt(np.sum((dang - abar) ** 2, axis=0) / (n - 1))
    return PoseCharacteristics(n, float(np.linalg.norm(ap)), *map(float, ap), *map(float, abar),
                               float(lbar + 3 * S_l), *map(float, 3 * S_ang), float(lbar), float(S_l))


def iso_cube_points(center, side, fraction: float = 0.1) -> np.ndarray:
    """(5, 3) positions P1..P5 (m) of the ISO 9283 test poses in a cube of edge ``side`` at ``center``.

    P1 is the cube centre; P2..P5 lie on the diagonals of the diagonal plane through the corners
    (-,-,-), (+,+,-), (+,+,+), (-,-,+) (the plane C1-C2-C7-C8 of the standard), at ``fraction`` (10 %)
    of the diagonal length from those corners.
    """
    c = np.asarray(center, dtype=float)
    if c.shape != (3,) or not np.all(np.isfinite(c)):
        raise ValueError("center: expected three finite numbers (m)")
    if not (np.isfinite(side) and side > 0):
        raise ValueError("side: expected a positive length (m)")
    h = side / 2.0
    corners = c + h * np.array([[-1, -1, -1], [1, 1, -1], [1, 1, 1], [-1, -1, 1]], dtype=float)
    opposite = corners[[2, 3, 0, 1]]
    pts = corners + fraction * (opposite - corners)
    return np.vstack([c, pts[[2, 0, 1, 3]]])
