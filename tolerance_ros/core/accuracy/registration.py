"""Registration: the rigid transform from the robot base frame to the tracker frame (and optionally
the tool/TCP offset), estimated by least squares from paired nominal and measured poses."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation


@dataclass
class Registration:
    """``T_tracker_base`` maps base-frame poses into the tracker frame; ``tool_offset`` (m, tool frame) is
    added to the nominal tool point when estimated. Residuals are position residuals (m)."""

    T_tracker_base: np.ndarray
    tool_offset: np.ndarray | None
    residuals: np.ndarray
    n: int

    @property
    def rms(self) -> float:
        return float(np.sqrt(np.mean(self.residuals ** 2)))

    @property
    def max(self) -> float:
        return float(self.residuals.max())

    def to_base(self, T_tracker) -> np.ndarray:
        """(n, 4, 4) tracker-frame poses expressed in the base frame (tool offset removed)."""
        return to_base_frame(T_tracker, np.linalg.inv(self.T_tracker_base), self.tool_offset)

    def to_dict(self) -> dict:
        return {"T_tracker_base": self.T_tracker_base, "tool_offset_m": self.tool_offset, "n": self.n,
                "residual_rms_m": self.rms, "residual_max_m": self.max}


def to_base_frame(T_tracker, T_base_tracker, tool_offset=None) -> np.ndarray:
    """(n, 4, 4) tracker-frame poses in the base frame (``T_base_tracker`` @ T), with the tool offset
    (m, tool frame) removed from the measured point."""
    T = np.asarray(T_base_tracker, dtype=float) @ np.asarray(T_tracker, dtype=float).reshape(-1, 4, 4)
    if tool_offset is not None:
        T[:, :3, 3] -= np.einsum("nij,j->ni", T[:, :3, :3], tool_offset)
    return T


def kabsch(P, M):
    """Rotation R and translation t minimising sum |R P_i + t - M_i|^2 (P, M: (n, 3))."""
    P, M = np.asarray(P, float), np.asarray(M, float)
    cp, cm = P.mean(axis=0), M.mean(axis=0)
    H = (P - cp).T @ (M - cm)
    U, S, Vt = np.linalg.svd(H)
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T)) or 1.0])
    R = Vt.T @ D @ U.T
    return R, cm - R @ cp, S


def register(T_nominal, T_measured, tool: bool = False) -> Registration:
    """Estimate the base-to-tracker transform from (n, 4, 4) nominal base-frame poses and their tracker
    readings; with ``tool`` also the tool-point offset in the tool frame (needs varied orientations)."""
    Tn, Tm = np.asarray(T_nominal, float), np.asarray(T_measured, float)
    if Tn.shape != Tm.shape or Tn.ndim != 3 or Tn.shape[1:] != (4, 4):
        raise ValueError(f"registration: nominal and measured poses must both be (n, 4, 4), got {Tn.shape}, {Tm.shape}")
    n = len(Tn)
    P, M = Tn[:, :3, 3], Tm[:, :3, 3]
    if n < 3:
        raise ValueError(f"registration: needs at least 3 poses, got {n}")
    R, t, S = kabsch(P, M)
    if S[1] < 1e-9 * max(S[0], 1e-300):
        raise ValueError("registration: the measured points are collinear; the rotation is not determined")
    offset = None
    if tool:
        def resid(x):
            Rx = Rotation.from_rotvec(x[:3]).as_matrix()
            pts = P + np.einsum("nij,j->ni", Tn[:, :3, :3], x[6:9])
            return ((pts @ Rx.T + x[3:6]) - M).ravel()

        x0 = np.concatenate([Rotation.from_matrix(R).as_rotvec(), t, np.zeros(3)])
        sol = least_squares(resid, x0, method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15)
        Jm = sol.jac
        if np.linalg.matrix_rank(Jm, tol=1e-9 * np.abs(Jm).max()) < 9:
            raise ValueError("registration: the tool offset is not determined (orientations too similar)")
        R, t, offset = Rotation.from_rotvec(sol.x[:3]).as_matrix(), sol.x[3:6], sol.x[6:9]
        P = P + np.einsum("nij,j->ni", Tn[:, :3, :3], offset)
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    res = np.linalg.norm(P @ R.T + t - M, axis=1)
    return Registration(T, offset, res, n)


class KabschAccumulator:
    """Position-only registration from streamed pairs in constant memory (sums of the Kabsch problem)."""

    def __init__(self):
        self.n, self.sp, self.sm, self.spm = 0, np.zeros(3), np.zeros(3), np.zeros((3, 3))

    def add(self, P, M):
        P, M = np.asarray(P, float).reshape(-1, 3), np.asarray(M, float).reshape(-1, 3)
        self.n += len(P)
        self.sp += P.sum(axis=0)
        self.sm += M.sum(axis=0)
        self.spm += P.T @ M

    def result(self) -> np.ndarray:
        """4x4 base -> tracker transform."""
        if self.n < 3:
            raise ValueError(f"registration: needs at least 3 poses, got {self.n}")
        cp, cm = self.sp / self.n, self.sm / self.n
        H = self.spm - self.n * np.outer(cp, cm)
        U, S, Vt = np.linalg.svd(H)
        if S[1] < 1e-9 * max(S[0], 1e-300):
            raise ValueError("registration: the measured points are collinear; the rotation is not determined")
        D = np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T)) or 1.0])
        R = Vt.T @ D @ U.T
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = R, cm - R @ cp
        return T
