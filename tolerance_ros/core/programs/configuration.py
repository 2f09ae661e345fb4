"""The configuration of a 6-axis arm's joint solution, and the nominal inverse kinematics in a given configuration.

A pose of the tool is reached by up to eight joint solutions of an industrial arm; a controller picks one from the
configuration stored with the target. Three signs tell the solutions apart (``flags``), each measured on the arm's
own geometry at the joints, whatever the joints' sign conventions:

- shoulder: +1 when the wrist centre lies in front of joint 1's axis, along the arm's forward direction (the base
  frame's x axis at joint 1's zero, turned with joint 1), -1 behind it (ABB: wrist centre in front of or behind
  axis 1; KUKA: the basic or the overhead area, status bit 0; FANUC: T or B);
- elbow: +1 when the wrist centre lies in front of the lower arm (the line from joint 2's axis to joint 3's, seen
  along the axis that turns the upright towards the forward direction), -1 behind it (ABB: in front of or behind
  the lower arm; KUKA: status bit 1, set in front; FANUC: U or D);
- wrist: the sign of joint 5 (ABB: axis 5 positive or negative; KUKA: status bit 2, set for A5 < 0; FANUC: F for
  J5 > 0, N otherwise, FANUC's joint 5 turning against ABB's).

The wrist centre is the point of joint 5's axis nearest joint 4's (their intersection on a spherical wrist). A
sign changes only where the arm passes a singularity (the wrist centre on joint 1's axis, the arm stretched or
folded, joint 5 at zero); each sign's distance from its change is given with it (``margins``: m, m, rad).

``ArmGeometry.solve`` finds the nominal joints of pose targets in a wanted configuration: seeds from a table of the
wrist centre over joints 2 and 3 and the wrist's Euler angles, then the damped least squares of ``models.ik``; a
solution is kept when it converged, has the wanted signs, lies in the wanted turn of each joint (a window per joint,
e.g. ABB's quadrants, FANUC's turn numbers, KUKA's turn bits) and within the joint limits. SI throughout.
"""
from __future__ import annotations

import numpy as np

from ..models.base import PRISMATIC, Mechanism, ModelError
from ..models.ik import into_limits, joint_jacobian, solve

SHOULDER, ELBOW, WRIST = 0, 1, 2
GRID = 72                   # samples of joints 2 and 3 each in the wrist-centre table
TOL = 1e-9                  # m and rad: convergence of the nominal solution
WINDOW_TOL = 1e-9           # rad: a joint this close outside its turn window is inside it
JITTER = 1e-5 / 6           # rad: seeds start this far (times 1 to 6, alternating) from where they were computed


def keeps(q, lo, hi) -> bool:
    """True when ``q`` (rad) lies in the window [lo, hi) to within ``WINDOW_TOL``: a configuration number written for
    that window still holds (a correction below the tolerance never moves it across a boundary)."""
    return lo - WINDOW_TOL <= q < hi + WINDOW_TOL


def _unit(v):
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(n > 0, n, 1.0)


def _rotate(v, axis, angle):
    """(n, 3) vectors ``v`` turned by ``angle`` (n,) about the unit ``axis`` (3,) (Rodrigues)."""
    c, s = np.cos(angle)[:, None], np.sin(angle)[:, None]
    return v * c + np.cross(axis, v) * s + axis * (v @ axis)[:, None] * (1 - c)


def _closest_on_first(p1, d1, p2, d2):
    """(n, 3) points of line 1 nearest line 2 (lines through p with unit directions d; parallel lines: p1)."""
    w = p1 - p2
    b = np.einsum("ni,ni->n", d1, d2)
    d, e = np.einsum("ni,ni->n", d1, w), np.einsum("ni,ni->n", d2, w)
    den = 1.0 - b * b
    t = np.where(den > 1e-12, (b * e - d) / np.where(den > 1e-12, den, 1.0), 0.0)
    return p1 + t[:, None] * d1


class ArmGeometry:
    """The configuration geometry of a 6-joint revolute arm (see the module docstring); ModelError for another."""

    def __init__(self, model: Mechanism):
        if model.dof != 6 or any(t == PRISMATIC for t in model.joint_types):
            raise ModelError(f"robot {model.name!r}: configurations are those of 6-joint revolute arms; it has "
                             f"{model.dof} joints ({', '.join(model.joint_types)})")
        self.model = model
        q0 = np.zeros((1, 6))
        T0, J0 = joint_jacobian(model, q0)
        w = J0[0, 3:]
        self.a1 = _unit(w[:, 0])
        x = np.array([1.0, 0.0, 0.0]) - self.a1[0] * self.a1
        if np.linalg.norm(x) < 1e-6:          # joint 1 along the base x axis: forward is the base y axis
            x = np.array([0.0, 1.0, 0.0]) - self.a1[1] * self.a1
        self.forward0 = _unit(x)
        R0 = T0[0, :3, :3]
        self.b = [R0.T @ _unit(w[:, k]) for k in (3, 4, 5)]   # the wrist's axes in the flange frame, zero wrist
        c, _ = self.axes(q0)
        self.c1 = c[0, 0]
        wc = self.wrist_center(q0)[0]
        self.wc_flange = R0.T @ (wc - T0[0, :3, 3])             # the wrist centre in the flange frame
        b4, b5, b6 = self.b
        self.euler_wrist = abs(abs(b4 @ b6) - 1) < 1e-9 and abs(b4 @ b5) < 1e-9 and abs(b5 @ b6) < 1e-9
        self.spherical = self.euler_wrist and np.linalg.norm(self._wrist_spread(q0)) < 1e-9
        self._table()

    # ---------------------------------------------------------------- geometry at the joints

    def axes(self, q):
        """(points (n, 6, 3) on each joint axis, unit directions (n, 6, 3)) at joints ``q``, base frame; a
        direction is the one a positive joint turns about."""
        q = np.atleast_2d(np.asarray(q, float))
        T, J = joint_jacobian(self.model, q)
        w = np.swapaxes(J[:, 3:], 1, 2)
        v = np.swapaxes(J[:, :3], 1, 2)
        d = _unit(w)
        p = T[:, None, :3, 3]
        return p + np.cross(d, v) / np.maximum(np.linalg.norm(w, axis=2, keepdims=True), 1e-300), d

    def _wrist_spread(self, q):
        c, d = self.axes(q)
        on5 = _closest_on_first(c[:, 4], d[:, 4], c[:, 3], d[:, 3])
        on4 = _closest_on_first(c[:, 3], d[:, 3], c[:, 4], d[:, 4])
        on6 = _closest_on_first(c[:, 5], d[:, 5], c[:, 4], d[:, 4])
        return np.concatenate([on5 - on4, on6 - on5], axis=1)

    def wrist_center(self, q, axes=None) -> np.ndarray:
        """(n, 3) the point of joint 5's axis nearest joint 4's, base frame, m."""
        c, d = self.axes(q) if axes is None else axes
        return _closest_on_first(c[:, 4], d[:, 4], c[:, 3], d[:, 3])

    def forward(self, q) -> np.ndarray:
        """(n, 3) the arm's forward direction at joint 1's angle."""
        q = np.atleast_2d(np.asarray(q, float))
        return _rotate(np.tile(self.forward0, (len(q), 1)), self.a1, q[:, 0] * self.model.joint_direction[0])

    def flags(self, q):
        """((n, 3) signs shoulder, elbow, wrist in {-1, +1}, (n, 3) margins: m from joint 1's axis, m from the lower
        arm's line, |joint 5| rad) at joints ``q``."""
        q = np.atleast_2d(np.asarray(q, float))
        c, d = self.axes(q)
        w = self.wrist_center(q, (c, d))
        f = self.forward(q)
        s = np.einsum("ni,ni->n", w - c[:, 0], f)
        u = c[:, 2] - c[:, 1]
        side = np.cross(self.a1, f)
        e_raw = np.einsum("ni,ni->n", np.cross(u, w - c[:, 2]), side)
        e = e_raw / np.maximum(np.linalg.norm(u, axis=1), 1e-300)
        q5 = q[:, 4]
        signs = np.stack([np.where(s >= 0, 1, -1), np.where(e >= 0, 1, -1), np.where(q5 >= 0, 1, -1)], axis=1)
        return signs, np.stack([np.abs(s), np.abs(e), np.abs(q5)], axis=1)

    # ---------------------------------------------------------------- seeds

    def _cylinder(self, w):
        """(r, h, azimuth) of points (n, 3) about joint 1's axis."""
        rel = w - self.c1
        h = rel @ self.a1
        e1, e2 = self.forward0, np.cross(self.a1, self.forward0)
        x, y = rel @ e1, rel @ e2
        return np.hypot(x, y), h, np.arctan2(y, x)

    def _table(self):
        from scipy.spatial import cKDTree
        lim = np.clip(self.model.joint_limits[1:3], -np.pi, np.pi)
        g2, g3 = np.meshgrid(np.linspace(lim[0, 0], lim[0, 1], GRID), np.linspace(lim[1, 0], lim[1, 1], GRID),
                             indexing="ij")
        q = np.zeros((g2.size, 6))
        q[:, 1], q[:, 2] = g2.ravel(), g3.ravel()
        signs, _ = self.flags(q)
        r, h, az = self._cylinder(self.wrist_center(q))
        self.grid_q, self.grid_az = q, az
        self.trees = {}
        for sh in (1, -1):
            for el in (1, -1):
                idx = np.flatnonzero((signs[:, SHOULDER] == sh) & (signs[:, ELBOW] == el))
                if len(idx):
                    self.trees[(sh, el)] = (cKDTree(np.stack([r[idx], h[idx]], axis=1)), idx)

    def _wrist_angles(self, N):
        """Both solutions ((n, 3), (n, 3)) of N = R(b4, q4) R(b5, q5) R(b6, q6) (joint 5 >= 0, then < 0)."""
        b4, b5, b6 = self.b
        U = np.stack([np.cross(b5, b4), b5, b4], axis=1)       # columns x, y, z: b4 along z, b5 along y
        M = U.T @ N @ U
        s6 = np.sign(b4 @ b6)
        beta = np.arctan2(np.hypot(M[:, 0, 2], M[:, 1, 2]), M[:, 2, 2])
        alpha = np.arctan2(M[:, 1, 2], M[:, 0, 2])
        gamma = np.arctan2(M[:, 2, 1], -M[:, 2, 0])
        pos = np.stack([alpha, beta, s6 * gamma], axis=1)
        neg = np.stack([alpha + np.pi, -beta, s6 * (gamma + np.pi)], axis=1)
        return pos, neg

    def seeds(self, T_flange, want):
        """(seeds (m, 6), owner (m,) target index) for pose targets ``T_flange`` (n, 4, 4) in the wanted signs
        ``want`` (n, 3) (0: either)."""
        T_flange = np.asarray(T_flange, float)
        wc = T_flange[:, :3, 3] + np.einsum("nij,j->ni", T_flange[:, :3, :3], self.wc_flange)
        r, h, az = self._cylinder(wc)
        rows, owner = [], []
        for (sh, el), (tree, idx) in self.trees.items():
            pick = np.flatnonzero(((want[:, SHOULDER] == 0) | (want[:, SHOULDER] == sh))
                                  & ((want[:, ELBOW] == 0) | (want[:, ELBOW] == el)))
            if not len(pick):
                continue
            _, k = tree.query(np.stack([r[pick], h[pick]], axis=1))
            g = idx[k]
            q = self.grid_q[g].copy()
            q[:, 0] = (az[pick] - self.grid_az[g]) * self.model.joint_direction[0]
            rows.append(q)
            owner.append(pick)
        if not rows:
            return np.zeros((0, 6)), np.zeros(0, int)
        q, owner = np.vstack(rows), np.concatenate(owner)
        if not self.euler_wrist:
            wrist = np.array([[a, b, 0.0] for a in (-np.pi / 2, 0.0, np.pi / 2, np.pi) for b in (-1.0, 1.0)])
            q = np.repeat(q, len(wrist), axis=0)
            q[:, 3:] = np.tile(wrist, (len(owner), 1))
            return q, np.repeat(owner, len(wrist))
        R0 = self.model.fk(q)[:, :3, :3]
        N = np.einsum("nji,njk->nik", R0, T_flange[owner, :3, :3])
        pos, neg = self._wrist_angles(N)
        out, who = [], []
        for sol, sign in ((pos, 1), (neg, -1)):
            keep = np.flatnonzero((want[owner, WRIST] == 0) | (want[owner, WRIST] == sign))
            s = q[keep].copy()
            s[:, 3:] = sol[keep]
            out.append(s)
            who.append(owner[keep])
        return np.vstack(out), np.concatenate(who)

    # ---------------------------------------------------------------- solve

    def into_windows(self, q, windows):
        """(q shifted by full turns into each joint's window [lo, hi) (rad; NaN: none) and within the limits, (n,)
        True where every window and limit is met)."""
        q = np.array(q, float)
        lo, hi = windows[..., 0], windows[..., 1]
        has = np.isfinite(lo)
        k = np.where(has, np.ceil((lo - WINDOW_TOL - q) / (2 * np.pi)), 0.0)
        q = q + 2 * np.pi * k
        inside = ~has | ((q >= lo - WINDOW_TOL) & (q < hi + WINDOW_TOL))
        free = into_limits(self.model, q)
        q = np.where(has, q, free)
        ok = inside.all(axis=1) & ~self.model.out_of_limits(q).any(axis=1)
        return q, ok

    def solve(self, T_flange, want=None, windows=None, near=None, restarts=16, rng=0):
        """(q (n, 6), ok (n,), reason [str or None]) nominal joints of flange poses ``T_flange`` (n, 4, 4) with the
        wanted signs ``want`` (n, 3) (0: either), in the turn ``windows`` (n, 6, 2) rad (NaN: any) and the joint
        limits; among several, the one nearest ``near`` (n, 6) (a NaN row: none), else the first found."""
        T_flange = np.asarray(T_flange, float)
        n = len(T_flange)
        want = np.zeros((n, 3), int) if want is None else np.asarray(want, int)
        windows = np.full((n, 6, 2), np.nan) if windows is None else np.asarray(windows, float)
        near = np.full((n, 6), np.nan) if near is None else np.asarray(near, float)
        q_out = np.full((n, 6), np.nan)
        best = np.full(n, np.inf)
        has_near = np.flatnonzero(np.all(np.isfinite(near), axis=1))
        if len(has_near):       # from the joints before it first: the solution the robot moves on to
            self._take(T_flange, want, windows, near, near[has_near], has_near, q_out, best)
        missing = np.flatnonzero(~np.isfinite(best))
        if len(missing):
            seeds, owner = self.seeds(T_flange[missing], want[missing])
            self._take(T_flange, want, windows, near, seeds, missing[owner], q_out, best)
        missing = np.flatnonzero(~np.isfinite(best))
        if len(missing) and restarts:
            starts = self.model.sample_joints(restarts, rng)
            self._take(T_flange, want, windows, near, np.tile(starts, (len(missing), 1)),
                       np.repeat(missing, restarts), q_out, best)
        ok = np.isfinite(best)
        reasons = [None] * n
        bad = np.flatnonzero(~ok)
        for i, why in zip(bad, self._why(T_flange[bad], want[bad], windows[bad])):
            reasons[i] = why
        return q_out, ok, reasons

    def _take(self, T_flange, want, windows, near, seeds, owner, q_out, best):
        """Solve from ``seeds`` (each for target ``owner``); keep, per target, the admissible solution nearest its
        ``near`` (the first one without)."""
        if not len(seeds):
            return
        # a seed exactly at a singularity (a table's stretched arm, a wrist at zero) would make the damped step's
        # system singular to the last bit: seeds start a hair (1e-5 rad) away
        seeds = seeds + JITTER * np.arange(1, 7) * (-1.0) ** np.arange(6)
        try:
            q, rp, ro, _ = solve(self.model, T_flange[owner], seeds, tol_position=TOL, tol_orientation=TOL)
        except np.linalg.LinAlgError:
            q, rp, ro, _ = solve(self.model, T_flange[owner], seeds + 1e3 * JITTER, tol_position=TOL,
                                 tol_orientation=TOL)
        conv = (rp <= TOL) & (ro <= TOL)
        ref = near[owner]
        has_ref = np.all(np.isfinite(ref), axis=1)
        ref_q = np.where(has_ref[:, None], ref, q)
        # into the windows, else next to the reference (a solution of the sequence keeps its turns); the signs
        # are those of the joints as written (joint 5's sign is that of its value)
        q_w, in_w = self.into_windows(np.where(has_ref[:, None] & ~np.isfinite(windows[owner][..., 0]),
                                               into_limits(self.model, q, ref_q), q), windows[owner])
        signs, _ = self.flags(q_w)
        match = np.all((want[owner] == 0) | (want[owner] == signs), axis=1)
        good = conv & match & in_w
        score = np.where(has_ref, np.linalg.norm(q_w - ref, axis=1), 0.0)
        for j in np.flatnonzero(good):
            i = owner[j]
            if score[j] < best[i]:
                best[i], q_out[i] = score[j], q_w[j]

    def _why(self, T_flange, want, windows) -> list:
        """Why no admissible nominal solution was found, for each target."""
        n = len(T_flange)
        if not n:
            return []
        seeds, owner = self.seeds(T_flange, np.zeros((n, 3), int))
        starts = self.model.sample_joints(16, 1)
        seeds, owner = np.vstack([seeds, np.tile(starts, (n, 1))]), np.concatenate([owner, np.repeat(np.arange(n), 16)])
        seeds = seeds + JITTER * np.arange(1, 7) * (-1.0) ** np.arange(6)
        q, rp, ro, _ = solve(self.model, T_flange[owner], seeds, tol_position=TOL, tol_orientation=TOL)
        conv = (rp <= TOL) & (ro <= TOL)
        signs, _ = self.flags(q)
        out = []
        for i in range(n):
            mine = owner == i
            if not (conv & mine).any():
                k = np.flatnonzero(mine)[np.argmin(rp[mine])]
                out.append(f"out of the nominal robot's reach (nearest {rp[k] * 1e3:.3g} mm, {ro[k] * 1e3:.3g} mrad "
                           f"away)")
                continue
            found = sorted({tuple(s) for s in signs[conv & mine].tolist()})
            if not any(all(w == 0 or w == s for w, s in zip(want[i], f)) for f in found):
                out.append(f"no nominal solution in the configuration asked ({_signs_text(want[i])}); there are "
                           + "; ".join(_signs_text(f) for f in found))
            else:
                out.append("the nominal solution in the configuration asked is outside the turns asked or the joint "
                           "limits")
        return out


def _signs_text(s) -> str:
    names = (("front", "back"), ("elbow in front", "elbow behind"), ("joint 5 >= 0", "joint 5 < 0"))
    return ", ".join(n[0] if v > 0 else n[1] for n, v in zip(names, s) if v != 0) or "any"
