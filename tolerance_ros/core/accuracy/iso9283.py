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


def _attained(T, what) -> np.ndarray:
    T = np.asarray(T, dtype=float)
    if T.ndim != 3 or T.shape[1:] != (4, 4):
        raise ValueError(f"{what}: expected (n, 4, 4) poses, got shape {T.shape}")
    if not np.all(np.isfinite(T)):
        raise ValueError(f"{what}: poses must be finite")
    return T


def _angles(T, C) -> np.ndarray:
    """(n, 3) roll, pitch, yaw of T less those of the commanded C, wrapped (rad)."""
    return wrap(rpy_from_matrix(T[:, :3, :3]) - rpy_from_matrix(np.asarray(C, float)[None, :3, :3]))


def distance_characteristics(commanded1, commanded2, attained1, attained2, orientation: bool = True) -> dict:
    """ISO 9283 distance accuracy and repeatability between two commanded poses, from ``n >= 2`` paired visits
    (attained1[j] and attained2[j] of cycle j; (n, 4, 4) each, m and rad).

    ``D_j = |p1_j - p2_j|``, ``D_c = |c1 - c2|``: ``AD_p = mean(D) - D_c``; per axis ``D_xj = x1_j - x2_j`` and
    ``AD_x = mean(D_x) - D_cx`` (y, z); ``RD_p = 3 S_D`` and ``RD_x = 3 S_Dx`` with ``S`` the sample standard
    deviation. Orientation (rad): ``AD_a = mean(D_a) - D_ca`` with ``D_aj = a1_j - a2_j``, taken as the mean of
    ``(a1_j - a_c1) - (a2_j - a_c2)`` so that no angle wraps, and ``RD_a = 3 S_Da`` (b, c). Keys: n, D_c,
    D_bar, AD_p, AD_x, AD_y, AD_z, RD_p, RD_x, RD_y, RD_z and, with
    ``orientation``, AD_a, AD_b, AD_c, RD_a, RD_b, RD_c (None without).
    """
    T1, T2 = _attained(attained1, "attained1"), _attained(attained2, "attained2")
    if len(T1) != len(T2) or len(T1) < 2:
        raise ValueError(f"distance: expected n >= 2 paired visits, got {len(T1)} and {len(T2)}")
    C1, C2 = np.asarray(commanded1, float), np.asarray(commanded2, float)
    dc = C1[:3, 3] - C2[:3, 3]
    d = T1[:, :3, 3] - T2[:, :3, 3]
    D = np.linalg.norm(d, axis=1)
    out = {"n": len(D), "D_c": float(np.linalg.norm(dc)), "D_bar": float(D.mean()),
           "AD_p": float(D.mean() - np.linalg.norm(dc)), "RD_p": float(3 * np.std(D, ddof=1))}
    for k, ax in enumerate("xyz"):
        out[f"AD_{ax}"] = float(d[:, k].mean() - dc[k])
        out[f"RD_{ax}"] = float(3 * np.std(d[:, k], ddof=1))
    for k, ax in enumerate("abc"):
        out[f"AD_{ax}"] = out[f"RD_{ax}"] = None
    if orientation:
        da = wrap(_angles(T1, C1) - _angles(T2, C2))
        for k, ax in enumerate("abc"):
            out[f"AD_{ax}"] = float(da[:, k].mean())
            out[f"RD_{ax}"] = float(3 * np.std(da[:, k], ddof=1))
    return out


def multidirectional(commanded, approaches: dict, orientation: bool = True) -> dict:
    """ISO 9283 multi-directional pose accuracy variation of one test pose: ``approaches`` maps each approach
    (a name) to its attained poses ((n_h, 4, 4), n_h >= 1). ``vAP_p = max_{h,k} |x_bar_h - x_bar_k|`` over the
    approaches' barycentres (m); ``vAP_a = max_{h,k} |a_bar_h - a_bar_k|`` of the roll deviations' means (b, c;
    rad; None without ``orientation``). Keys also: approaches {name: n}, pair (the two approaches farthest
    apart)."""
    if len(approaches) < 2:
        raise ValueError(f"multi-directional: expected two or more approaches, got {len(approaches)}")
    names = list(approaches)
    Ts = [_attained(approaches[k], f"approach {k}") for k in names]
    if any(len(T) == 0 for T in Ts):
        raise ValueError("multi-directional: an approach without attained poses")
    bary = np.array([T[:, :3, 3].mean(axis=0) for T in Ts])
    dist = np.linalg.norm(bary[:, None] - bary[None], axis=2)
    h, k = np.unravel_index(np.argmax(dist), dist.shape)
    out = {"approaches": {n: len(T) for n, T in zip(names, Ts)}, "vAP_p": float(dist[h, k]),
           "pair": [names[h], names[k]], "vAP_a": None, "vAP_b": None, "vAP_c": None}
    if orientation:
        mean = np.array([_angles(T, commanded).mean(axis=0) for T in Ts])
        spread = np.abs(mean[:, None] - mean[None]).max(axis=(0, 1))
        out.update({f"vAP_{ax}": float(spread[i]) for i, ax in enumerate("abc")})
    return out


def drift(commanded, stamps, attained, window: float, orientation: bool = True) -> dict:
    """ISO 9283 drift of the pose characteristics of one test pose over a long campaign: AP and RP of each
    window of ``window`` s (from the first stamp; windows with fewer than 2 visits are skipped), and

    - ``dAP_p = |AP(first) - AP(last)|``, the shift of the barycentre between the first and the last window (m);
      ``dAP_a = |AP_a(first) - AP_a(last)|`` (b, c; rad);
    - ``dRP_l = |RP_l(first) - RP_l(last)|`` (m), ``dRP_a`` (b, c; rad);
    - each per hour: divided by the time between the two windows' mean stamps.

    Keys: window_s, span_s, windows [{t_s (mean stamp), n, AP_p, AP_x, AP_y, AP_z, RP_l, ...}], dAP_p, dRP_l,
    dAP_p_per_h, dRP_l_per_h, and the orientation ones (None without ``orientation``). Needs two windows.
    """
    T = _attained(attained, "attained")
    t = np.asarray(stamps, dtype=float)
    if t.shape != (len(T),) or not np.all(np.isfinite(t)):
        raise ValueError("stamps: expected one finite stamp (s) per attained pose")
    if not (np.isfinite(window) and window > 0):
        raise ValueError(f"window: expected a positive duration (s), got {window!r}")
    order = np.argsort(t, kind="stable")
    t, T = t[order], T[order]
    w = np.floor((t - t[0]) / window).astype(np.int64)
    starts = np.flatnonzero(np.r_[True, w[1:] != w[:-1]])
    ends = np.r_[starts[1:], len(w)]
    windows = []
    for a, b in zip(starts, ends):
        if b - a >= 2:
            pc = pose_characteristics(commanded, T[a:b], orientation).to_dict()
            windows.append({"t_s": float(t[a:b].mean()), **pc})
    if len(windows) < 2:
        raise ValueError(f"drift: the visits span {t[-1] - t[0]:.6g} s, fewer than two windows of {window:g} s with "
                         f"two visits each")
    first, last = windows[0], windows[-1]
    hours = (last["t_s"] - first["t_s"]) / 3600.0
    dap = np.linalg.norm([first[f"AP_{a}"] - last[f"AP_{a}"] for a in "xyz"])
    out = {"window_s": float(window), "span_s": float(t[-1] - t[0]), "windows": windows,
           "dAP_p": float(dap), "dRP_l": float(abs(first["RP_l"] - last["RP_l"]))}
    for a in "abc":
        out[f"dAP_{a}"] = abs(first[f"AP_{a}"] - last[f"AP_{a}"]) if orientation else None
        out[f"dRP_{a}"] = abs(first[f"RP_{a}"] - last[f"RP_{a}"]) if orientation else None
    for k in [k for k in out if k.startswith("d") and out[k] is not None]:
        out[f"{k}_per_h"] = out[k] / hours
    return out


def exchangeability(barycentres) -> dict:
    """ISO 9283 exchangeability of one test pose between robots of one type: ``E = sqrt((x_max - x_min)^2 +
    (y_max - y_min)^2 + (z_max - z_min)^2)`` over the robots' barycentres (r, 3), r >= 2 (m). Keys: E, spread
    (x, y, z)."""
    b = np.asarray(barycentres, dtype=float)
    if b.ndim != 2 or b.shape[1] != 3 or len(b) < 2 or not np.all(np.isfinite(b)):
        raise ValueError(f"exchangeability: expected the barycentres of two or more robots, shape (r, 3), got "
                         f"{b.shape}")
    spread = b.max(axis=0) - b.min(axis=0)
    return {"E": float(np.linalg.norm(spread)), "spread": spread.tolist(), "robots": len(b)}


def static_compliance(attained, load, orientation: bool = False) -> dict:
    """ISO 9283 static compliance of one test pose from its visits (n, 4, 4) (m) under the loads at the tool (base
    frame; unloaded visits included): (n, 3) forces N, or (n, 6) forces and torques N m. The least-squares
    ``x = x0 + C W`` of the position and, with ``orientation``, the small turn (the rotation vector from the first
    visit's orientation, base frame, rad) on the load components W that vary. Keys: C (6 x 6 or 3 x 6 rows: the
    position m, then the turn rad; columns fx, fy, fz, mx, my, mz; None where a component never varied),
    compliance_m_per_N {x, y, z} (the displacement along a force per newton), compliance_rad_per_Nm {x, y, z}
    (the turn about a torque's axis per N m; None without torques or orientation), max_load {fx ... mz}, n,
    residual_rms_m. Needs loads varying along at least one component."""
    from ..geometry import rotation_error
    T = _attained(attained, "attained")
    W = np.asarray(load, dtype=float)
    if W.ndim != 2 or W.shape not in ((len(T), 3), (len(T), 6)) or not np.all(np.isfinite(W)):
        raise ValueError(f"load: expected (n, 3) forces or (n, 6) forces and torques, finite, one row per attained "
                         f"pose, got shape {W.shape}")
    W = np.c_[W, np.zeros((len(W), 6 - W.shape[1]))]
    cols = [k for k in range(6) if np.ptp(W[:, k]) > 0]
    if not cols:
        raise ValueError("static compliance: the loads never vary")
    Wc = W[:, cols] - W[:, cols].mean(axis=0)
    if len(W) <= len(cols) + 1 or np.linalg.matrix_rank(Wc) < len(cols):
        raise ValueError(f"static compliance: {len(W)} visits do not determine the compliance along {len(cols)} load "
                         f"component(s)")
    y = T[:, :3, 3]
    if orientation:
        y = np.c_[y, rotation_error(T[:, :3, :3], T[:1, :3, :3])]
    A = np.c_[np.ones(len(W)), W[:, cols]]
    coef, *_ = np.linalg.lstsq(A, y, rcond=None)
    resid = y[:, :3] - (A @ coef)[:, :3]
    C = [[None] * 6 for _ in range(y.shape[1])]
    for j, k in enumerate(cols):
        for i in range(y.shape[1]):
            C[i][k] = float(coef[1 + j, i])
    names = ("fx", "fy", "fz", "mx", "my", "mz")
    return {"C": C, "compliance_m_per_N": {ax: C[k][k] for k, ax in enumerate("xyz")},
            "compliance_rad_per_Nm": {ax: C[3 + k][3 + k] if orientation else None for k, ax in enumerate("xyz")},
            "max_load": {nm: float(np.abs(W[:, k]).max()) for k, nm in enumerate(names)}, "n": len(W),
            "residual_rms_m": float(np.sqrt(np.mean(np.sum(resid ** 2, axis=1))))}


class DriftTracker:
    """ISO 9283 drift followed on line, in constant memory: for each test pose, the mean position error (m, base
    frame; its barycentre less the commanded position) over its first window of ``window`` s and over each later
    window; when a window closes (a visit stamped past its end) with two visits or more, ``dAP_p`` is the distance
    between its mean and the first window's, as ``drift`` computes it offline. ``limit`` (m, None: no limit):
    ``over`` names the test poses whose latest dAP_p exceeds it."""

    def __init__(self, window: float = 600.0, limit: float | None = None):
        if not (np.isfinite(window) and window > 0):
            raise ValueError(f"drift window: expected a positive duration (s), got {window!r}")
        if limit is not None and not (np.isfinite(limit) and limit > 0):
            raise ValueError(f"drift limit: expected a positive length (m) or none, got {limit!r}")
        self.window, self.limit = float(window), limit
        self.poses = {}

    def add(self, pose: str, stamp: float, error) -> None:
        """One visit of test pose ``pose`` stamped ``stamp`` s with position error ``error`` (3,) m."""
        e = np.asarray(error, float)
        if not pose or not np.isfinite(stamp) or e.shape != (3,) or not np.all(np.isfinite(e)):
            return
        s = self.poses.get(pose)
        if s is None:
            s = self.poses[pose] = {"first": None, "start": stamp, "sum": np.zeros(3), "n": 0,
                                    "t_sum": 0.0, "dAP_p": None, "dAP_p_max": 0.0, "per_h": None, "windows": 0}
        if stamp < s["start"]:          # out of order or a clock reset: that visit does not count
            return
        if stamp >= s["start"] + self.window:
            self._close(s)
            s["start"] += self.window * np.floor((stamp - s["start"]) / self.window)
        s["sum"] += e
        s["t_sum"] += stamp
        s["n"] += 1

    def _close(self, s):
        if s["n"] >= 2:
            mean, t = s["sum"] / s["n"], s["t_sum"] / s["n"]
            if s["first"] is None:
                s["first"] = (mean, t)
            else:
                d = float(np.linalg.norm(mean - s["first"][0]))
                s["dAP_p"], s["dAP_p_max"] = d, max(s["dAP_p_max"], d)
                s["per_h"] = d / ((t - s["first"][1]) / 3600.0)
            s["windows"] += 1
        s["sum"], s["t_sum"], s["n"] = np.zeros(3), 0.0, 0

    @property
    def largest(self) -> float | None:
        """The largest latest dAP_p of the test poses (m), or None before any window closed after the first."""
        return max((s["dAP_p"] for s in self.poses.values() if s["dAP_p"] is not None), default=None)

    @property
    def over(self) -> list:
        """(pose, dAP_p) of the test poses whose latest drift exceeds the limit."""
        if self.limit is None:
            return []
        return [(p, s["dAP_p"]) for p, s in self.poses.items() if s["dAP_p"] is not None and s["dAP_p"] > self.limit]

    def summary(self) -> dict:
        """JSON-ready: window_s, limit_m, poses {pose: {windows, dAP_p_m, dAP_p_max_m, dAP_p_per_h_m}}."""
        return {"window_s": self.window, "limit_m": self.limit,
                "poses": {p: {"windows": s["windows"], "dAP_p_m": s["dAP_p"], "dAP_p_max_m": s["dAP_p_max"],
                              "dAP_p_per_h_m": s["per_h"]} for p, s in self.poses.items()}}


def reference_posture(model) -> np.ndarray:
    """(dof,) the robot's reference posture (rad or m): each joint at its zero (a URDF's or a D-H table's home)
    where its limits hold zero, else at the middle of its limits."""
    lim = np.asarray(model.joint_limits, float)
    mid = np.where(np.isfinite(lim).all(axis=1), lim.mean(axis=1), 0.0)
    return np.where((lim[:, 0] <= 0.0) & (lim[:, 1] >= 0.0), 0.0, mid)


def posture_distance(model, q, reference) -> np.ndarray:
    """(n,) distance of the configurations q (n, dof) from ``reference`` (dof,): each joint's difference (a
    continuous joint's within a turn) over its range (a turn where the range is not finite), RMS over joints."""
    lim = np.asarray(model.joint_limits, float)
    span = np.where(np.isfinite(lim).all(axis=1), lim[:, 1] - lim[:, 0], 2 * np.pi)
    d = model.within_turn(np.atleast_2d(np.asarray(q, float)) - np.asarray(reference, float))
    return np.sqrt(np.mean((d / np.maximum(span, 1e-12)) ** 2, axis=1))


WALK_STEPS = 10  # a test pose is reached from the cube's centre in this many steps, each solved from the last


def walk_to(model, T_from, targets, q_from, steps=WALK_STEPS, **tol) -> np.ndarray:
    """(k, dof) joints at the ``targets`` (k, 4, 4) reached from the pose ``T_from`` (4, 4) at joints ``q_from``
    (dof,) in ``steps`` straight steps of the position (orientation as the targets'), each solved from the
    last: the configuration of the start kept (no jump to another branch of the inverse kinematics)."""
    from ..models.ik import nominal_solution
    targets = np.asarray(targets, float)
    q = np.tile(np.asarray(q_from, float), (len(targets), 1))
    for f in np.linspace(1.0 / steps, 1.0, steps):
        step = targets.copy()
        step[:, :3, 3] = T_from[:3, 3] + f * (targets[:, :3, 3] - T_from[:3, 3])
        q = nominal_solution(model, step, seed=q, **tol)
    return q


def iso_cube_joints(model, q_candidates, rng=0, centres=10, allowed=None, reference=None):
    """(joints (5, dof) of the ISO 9283 cube's test poses P1-P5, note), or (None, note).

    The cube is centred on a candidate tool pose in front of the robot (x > 0 in the base frame) and in the
    middle of the workspace (no farther from the candidates' median tool position than half of them), at that
    pose's orientation, in the arm configuration nearest the reference posture (``reference`` (dof,), or else
    ``reference_posture``; ``posture_distance``): the ``centres`` nearest candidates in turn, the reference
    itself first when given. Its edge is the largest (halving from half the median distance of the
    candidates from their median) whose five poses the nominal model reaches from the centre's configuration
    without changing it (``walk_to``), within the joint limits (and, with ``allowed``, a function of joints
    (k, dof) -> (k,) bool, that it allows).
    """
    q_candidates = np.asarray(q_candidates, float)
    given = reference is not None
    ref = reference_posture(model) if reference is None else np.asarray(reference, float)
    T = model.fk(q_candidates)
    front = T[:, 0, 3] > 0
    T = T[front] if front.sum() >= 5 else T
    qf = q_candidates[front] if front.sum() >= 5 else q_candidates
    P = T[:, :3, 3]
    dist = np.linalg.norm(P - np.median(P, axis=0), axis=1)
    central = np.flatnonzero(dist <= np.median(dist))
    order = list(central[np.argsort(posture_distance(model, qf[central], ref), kind="stable")][:centres])
    starts = [(T[c], qf[c]) for c in order]
    if given:
        starts.insert(0, (model.fk(ref[None])[0], ref))
    tol = dict(tol_position=1e-7, tol_orientation=1e-7)
    for Tc, qc in starts:
        side = 0.5 * np.median(dist)
        for _ in range(5):
            targets = np.tile(Tc, (5, 1, 1))
            targets[:, :3, 3] = iso_cube_points(Tc[:3, 3], side)
            q = walk_to(model, Tc, targets, qc, **tol)
            if np.allclose(model.fk(q), targets, atol=1e-6) and not model.out_of_limits(q).any() and \
                    (allowed is None or allowed(q).all()):
                return q, (f"ISO 9283 cube P1-P5, edge {side * 1e3:.0f} mm, centred at "
                           f"[{', '.join(f'{v * 1e3:.0f}' for v in Tc[:3, 3])}] mm, in the configuration nearest "
                           + ("the one given" if given else "the reference posture"))
            side /= 2.0
    return None, ("ISO 9283 cube: no reachable cube found in front of the robot" +
                  (" within the restrictions" if allowed is not None else ""))
