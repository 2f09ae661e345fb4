"""Registration: the rigid transform from the robot base frame to the tracker frame and, optionally, the
offsets of the measured targets on the tool, by least squares from nominal tool poses and the tracker's
readings.

Model: target ``k`` seen at joints ``q_i`` reads ``m_i = A T(q_i) X_k`` (``A`` = ``T_tracker_base``,
``T(q)`` the nominal tool frame, ``X_k`` the target's frame in the tool frame; positions always, the
orientation too when the targets are measured frames).

Without offsets to fit, the targets' points are known in the base frame and ``A`` is the closed-form
Kabsch solution. With offsets (``tool=True``) the problem is not convex, but for a fixed rotation ``R``
of ``A`` it is linear: ``R^T m_i - p_i = b + R_i t_k`` (``b = R^T a``, ``p_i, R_i`` the tool frame,
``t_k`` the target point). Eliminating ``(b, t)`` leaves a quadratic form in the nine entries of ``R``,
``f(R) = |P (G vec R^T - p)|^2`` with the fixed projector ``P``; it is evaluated on a dense seeded
cover of SO(3) (4,096 rotations, the 24 of the cube, and the projection of its unconstrained minimum),
so no starting guess is involved; the best distinct candidates are refined by Levenberg-Marquardt on
the full residual and the lowest wins. This finds the global solution for any tracker placement (any
rotation, upside down) and any offsets. Measured frames then get each target's rotation in closed form
(the rotation nearest the mean of ``R_i^T R^T R_m``). SI throughout.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..targets import Targets

COVER = 4096      # rotations of the seeded cover of SO(3) on which f(R) is evaluated
REFINE = 4        # distinct best candidates refined by Levenberg-Marquardt
DISTINCT = 0.2    # rad: candidates closer than this to a better one are not refined again


@dataclass
class Registration:
    """``T_tracker_base`` maps base-frame poses into the tracker frame; ``targets`` are the measured
    targets' frames in the tool frame (fitted when ``estimated``). Residuals are position residuals (m)."""

    T_tracker_base: np.ndarray
    targets: Targets
    residuals: np.ndarray
    n: int
    estimated: bool = False

    @property
    def rms(self) -> float:
        return float(np.sqrt(np.mean(self.residuals ** 2)))

    @property
    def max(self) -> float:
        return float(self.residuals.max())

    @property
    def tool_offset(self) -> np.ndarray | None:
        """(3,) m: the one target's fitted point in the tool frame (None when not fitted or several)."""
        return self.targets.offsets[0].copy() if self.estimated and len(self.targets) == 1 else None

    def to_base(self, T_tracker) -> np.ndarray:
        """(n, 4, 4) tracker-frame readings expressed in the base frame."""
        return np.linalg.inv(self.T_tracker_base) @ np.asarray(T_tracker, float).reshape(-1, 4, 4)

    def to_dict(self) -> dict:
        return {"T_tracker_base": self.T_tracker_base, "tool_offset_m": self.tool_offset,
                "targets_estimated": self.estimated, **self.targets.to_dict(), "n": self.n,
                "residual_rms_m": self.rms, "residual_max_m": self.max}


def to_base_frame(T_tracker, T_base_tracker) -> np.ndarray:
    """(n, 4, 4) tracker-frame readings in the base frame (``T_base_tracker @ T``)."""
    return np.asarray(T_base_tracker, dtype=float) @ np.asarray(T_tracker, dtype=float).reshape(-1, 4, 4)


def kabsch(P, M):
    """Rotation R and translation t minimising sum |R P_i + t - M_i|^2 (P, M: (n, 3))."""
    P, M = np.asarray(P, float), np.asarray(M, float)
    cp, cm = P.mean(axis=0), M.mean(axis=0)
    H = (P - cp).T @ (M - cm)
    U, S, Vt = np.linalg.svd(H)
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T)) or 1.0])
    R = Vt.T @ D @ U.T
    return R, cm - R @ cp, S


def spread_ratio(P, M) -> float:
    """RMS spread of measured points ``M`` about their centroid over that of the nominal points ``P``
    ((n, 3) each): about 1 when both are in the same length unit, 1e-3 for metres labelled millimetres."""
    P, M = np.asarray(P, float), np.asarray(M, float)
    sp = np.sqrt(np.mean(np.sum((P - P.mean(axis=0)) ** 2, axis=1)))
    sm = np.sqrt(np.mean(np.sum((M - M.mean(axis=0)) ** 2, axis=1)))
    return float(sm / sp) if sp > 0 else float("inf")


def register(T_nominal, T_measured, tool: bool = False, index=None, names=("",), frames: bool = False,
             targets: Targets | None = None) -> Registration:
    """Registration of tracker readings (n, 4, 4) to nominal tool frames (n, 4, 4) in the base frame.

    index : (n,) each row's target in ``names`` (None: one target).  tool : fit each target's offset
    (needs varied orientations).  frames : the readings are frames (their orientation is measured).
    targets : known target frames instead (only the tracker is fitted; ``tool`` must be False).
    """
    Tn, Tm = np.asarray(T_nominal, float), np.asarray(T_measured, float)
    if Tn.shape != Tm.shape or Tn.ndim != 3 or Tn.shape[1:] != (4, 4):
        raise ValueError(f"registration: nominal and measured poses must both be (n, 4, 4), got {Tn.shape}, {Tm.shape}")
    n = len(Tn)
    if n < 3:
        raise ValueError(f"registration: needs at least 3 poses, got {n}")
    names = tuple(targets.names) if targets is not None else tuple(names)
    K = len(names)
    idx = np.zeros(n, int) if index is None else np.asarray(index, int)
    if idx.shape != (n,) or (n and (idx.min() < 0 or idx.max() >= K)):
        raise ValueError(f"registration: index must give each of the {n} rows one of {K} targets")
    if tool and targets is not None:
        raise ValueError("registration: give known targets or fit them (tool), not both")
    if not tool:
        tg = targets if targets is not None else Targets.at_tool(names, frames)
        P = tg.poses(Tn, idx)[:, :3, 3]
        R, t, S = kabsch(P, Tm[:, :3, 3])
        if S[1] < 1e-9 * max(S[0], 1e-300):
            raise ValueError("registration: the measured points are collinear; the rotation is not determined")
        A = _matrix(R, t)
        return Registration(A, tg, np.linalg.norm(P @ R.T + t - Tm[:, :3, 3], axis=1), n, False)
    R, b, offsets = _global_points(Tn, Tm[:, :3, 3], idx, K, names)
    X = np.tile(np.eye(4), (K, 1, 1))
    X[:, :3, 3] = offsets
    if frames:
        for k in range(K):
            sel = idx == k
            Mk = np.einsum("nji,jk,nkl->il", Tn[sel, :3, :3], R.T, Tm[sel, :3, :3])
            X[k, :3, :3] = _nearest_rotation(Mk)
    A = _matrix(R, R @ b)
    tg = Targets(names, X, frames)
    P = tg.poses(Tn, idx)[:, :3, 3]
    return Registration(A, tg, np.linalg.norm(P @ R.T + R @ b - Tm[:, :3, 3], axis=1), n, True)


def _matrix(R, t) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    return T


def _nearest_rotation(M) -> np.ndarray:
    U, _, Vt = np.linalg.svd(M)
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt)) or 1.0])
    return U @ D @ Vt


def _design(Rt, idx, K) -> np.ndarray:
    """(3n, 3 + 3K) design of ``b + R_i t_k``: an identity block, then each row's tool rotation in its
    target's block."""
    n = len(Rt)
    D = np.zeros((n, 3, 3 + 3 * K))
    D[:, :, :3] = np.eye(3)
    for k in range(K):
        sel = idx == k
        D[sel, :, 3 + 3 * k:6 + 3 * k] = Rt[sel]
    return D.reshape(3 * n, 3 + 3 * K)


def _global_points(Tn, M, idx, K, names):
    """(R, b, offsets (K, 3)) minimising sum |R^T m_i - b - p_i - R_i t_k|^2 over every rotation."""
    n = len(Tn)
    Rt, p = Tn[:, :3, :3], Tn[:, :3, 3].reshape(-1)
    counts = np.bincount(idx, minlength=K)
    if counts.min() < 3:
        k = int(np.argmin(counts))
        raise ValueError(f"registration: the tool offsets are not determined (target {names[k] or '(unnamed)'} "
                         f"has {counts[k]} measurement(s); each needs at least 3, at different orientations)")
    D = _design(Rt, idx, K)
    sv = np.linalg.svd(D, compute_uv=False)
    if sv.min() < 1e-9 * sv.max():
        raise ValueError("registration: the tool offsets are not determined (the tool orientations are too similar)")
    # y(R) = G r - p with r = vec(R^T) row-major: (R^T m)_j = sum_l r[3j + l] m_l
    G = np.zeros((n, 3, 9))
    for j in range(3):
        G[:, j, 3 * j:3 * j + 3] = M
    G = G.reshape(3 * n, 9)
    Dp = np.linalg.pinv(D)
    PG = G - D @ (Dp @ G)
    Pp = p - D @ (Dp @ p)
    Q, c = G.T @ PG, G.T @ Pp
    from scipy.optimize import least_squares  # here: importing scipy takes about 1 s of a node's start
    from scipy.spatial.transform import Rotation
    cover = Rotation.concatenate([Rotation.create_group("O"), Rotation.random(COVER, random_state=20261201)])
    cands = [cover.as_matrix()]
    r_free = np.linalg.lstsq(Q, c, rcond=None)[0]
    cands.append(_nearest_rotation(r_free.reshape(3, 3).T)[None])
    Rs = np.concatenate(cands)                                       # candidate R (tracker <- base)
    r = np.transpose(Rs, (0, 2, 1)).reshape(len(Rs), 9)              # vec(R^T)
    cost = np.einsum("ci,ij,cj->c", r, Q, r) - 2.0 * r @ c
    order = np.argsort(cost)
    chosen = []
    for i in order:
        if all(np.linalg.norm(Rotation.from_matrix(Rs[i].T @ Rs[j]).as_rotvec()) > DISTINCT for j in chosen):
            chosen.append(i)
        if len(chosen) == REFINE:
            break
    best = None
    for i in chosen:
        R0 = Rs[i]
        z0 = Dp @ (G @ R0.T.reshape(9) - p)

        def rotated(w, R0=R0):
            return G @ (R0 @ Rotation.from_rotvec(w).as_matrix()).T.reshape(9) - p

        def resid(x):
            return rotated(x[:3]) - D @ x[3:]

        def jac(x, h=1e-7):
            cols = [(rotated(x[:3] + h * e) - rotated(x[:3] - h * e)) / (2 * h) for e in np.eye(3)]
            return np.column_stack(cols + [-D])

        sol = least_squares(resid, np.concatenate([np.zeros(3), z0]), jac=jac, method="lm", xtol=1e-13, ftol=1e-13,
                            gtol=1e-13, max_nfev=200)
        if best is None or sol.cost < best[0]:
            best = (sol.cost, R0 @ Rotation.from_rotvec(sol.x[:3]).as_matrix(), sol.x[3:])
    _, R, z = best
    return R, z[:3], z[3:].reshape(K, 3)


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
        return _matrix(R, cm - R @ cp)
