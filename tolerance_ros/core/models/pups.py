"""The 3-PUPS hyper-redundant metamorphic parallel manipulator of Rong, Han, Liu, Qu (2018).

Geometry (the paper's Fig. 2 and eqs. 1-3; the paper prints the transposed, frame-to-frame matrices,
used here as active rotations; SI):

- base frame O-xyz: z normal to the base, pointing towards the platform; limb i's slider frame
  ``A_i`` is ``R_Ai = Rz(s_i)``, ``s_i = (i - 1) 120 deg`` (eq. 1); its x_i axis points from the first
  U-joint centre A_i to O, so ``A_i = -a_i R_Ai x`` (``a_i = |OA_i|``, the slider position);
- U-joint: first revolute (actuated, angle psi_i) about ``e1``, second revolute (passive, theta_i)
  about the once-turned ``e2``; the leg frame is ``R_Bi = R_e1(psi_i) R_e2(theta_i)`` (eq. 2) and the
  leg ``B_i C_i = l_i`` lies along its w_i (z) axis.  ``u_joint_axes = (e1, e2)`` is ``(x, y)`` by
  default: the paper's text puts the second revolute on the leg frame's p_i (y) axis; its eq. 2 prints
  ``R_psi`` about y and ``R_theta`` about x, and that literal reading, ``(y, x)``, also loads (it makes
  the symmetric pose PE1 a singularity: every passive theta_i then moves C_i tangentially and the
  platform can turn about z with all nine actuators held);
- platform frame O'-upw: ``C_i = p + R c_i``, ``c_i = -c Rz(s_i) x`` (u points from C_1 to O'),
  ``R = Rz(gamma) Ry(beta) Rx(alpha)`` (eq. 3; REP 103 roll alpha, pitch beta, yaw gamma).

Joints ``q`` (9): ``a1 a2 a3`` (slider positions, m), ``psi1 psi2 psi3`` (first U-joint revolutes,
rad), ``l1 l2 l3`` (leg lengths, m), all actuated.  The passive theta_i follow from the loop closure.
Metamorphic variants lock some actuators (``locked``: 3-UPS = sliders locked, 3-PRPS = U-joints
locked, 3-RPS = both): a locked joint keeps its joint entry, with limits ``[v, v]``, and any other
value is rejected.  With psi_i locked the platform loses one degree of freedom per limb.

Error parameters (27, m), the paper's ``delta epsilon = [da_1 db_1 dl_1 da_2 ... dl_3]`` of eq. 5,
``p + dp = a_i + da_i + R_Ai db_i + R_Ai R_Bi (l_i + dl_i) - dR R c_i``:
``ai.x ai.y ai.z`` the error of A_i in the base frame; ``bi.*`` the offset A_iB_i of the two
U-joint revolute centres in the slider frame A_i (a constant vector there, as eq. 5 writes it);
``li.*`` the error of the vector B_iC_i in the leg frame B_i (``li.z`` the leg-length error along w_i,
``li.x``, ``li.y`` lateral offsets of the sphere centre).  Nominal values are all 0.  The platform
sphere errors dc_i of eq. 5 are not among the sources (the paper drops them).

Error transfer.  Linearising eq. 5 at a configuration, with the passive angle error dtheta_i and
``dR = I + [dphi]x`` (dphi: small rotation in the base frame; the paper's ``R_dgamma R_dbeta R_dalpha``
is the same to first order), each limb gives three equations
``dp + dphi x (R c_i) - t_i dtheta_i = S_i e_i``, ``t_i = dC_i/dtheta_i``, ``S_i = [I, R_Ai, R_Ai R_Bi]``,
``e_i = [da_i; db_i; dl_i]``.  The paper projects them on the leg direction w_i only (eq. 8), three
equations that cannot fix six platform errors.  Here each limb is also projected on the second
U-joint axis k_i: w_i and k_i are both normal to t_i, so the two projections eliminate dtheta_i exactly
and leave the two independent equations of the limb.  Stacking the six rows gives a square
``J1 = [n^T, (R c_i x n)^T]`` (n = w_i, k_i; the w_i rows are the paper's J1) and
``J2 = [n^T S_i]`` (6 x 27), and ``[dp; dphi] = G e`` with ``G = J1^-1 J2``: exactly the solution of
the full 9-equation loop system.  A displacement of C_i along t_i is taken up by theta_i, so
``li.x`` (with the default axes) has no first-order effect.  J1 singular is a forward-kinematic
(type II) singularity: poses where J1, with its orientation columns scaled by 1/c, has a condition
number above ``COND_LIMIT`` raise ModelError.

Inverse kinematics resolves the 3-fold redundancy by holding each free slider at ``redundancy``
(mid-travel by default) or at values passed by the caller.  Forward kinematics solves the six
projected closure equations (sphere ``|C_i - O_i| = rho_i`` and circle plane ``k_i (C_i - O_i) = 0``
of each limb, O_i the circle centre) for the platform pose by damped Newton steps vectorised over
poses, from a start found with the platform shrunk to a point and R = I (other yaw starts where that
fails).  It returns the assembly it reaches; other assemblies of the same joints exist, near
singularities close by, so ``sample_joints`` keeps only configurations whose forward kinematics
returns the sampled pose.  Joints that do not close the loop raise ModelError; ``tolerant()`` gives a
copy that returns NaN rows instead (for searches that step outside the assemblable joint set).

``fk_and_jacobian`` and ``passive_angles`` run a compiled kernel (``pups_kernels``: the same algorithm pose by
pose, about 5 us a pose against 45 us here) unless ``backend`` is 'numpy' or numba cannot be imported; this
module's numpy code is the reference the tests hold it to.
"""
from __future__ import annotations

import copy
import time
from pathlib import Path

import numpy as np

from ..units import angle_scale, length_scale, parse_number
from ..geometry import axis_rotations, exp_so3, pose_matrices, rpy_from_matrix, rpy_to_matrices
from .base import PRISMATIC, REVOLUTE, ErrorJacobian, Mechanism, ModelError

AXES = {"x": 0, "y": 1, "z": 2}
GROUPS = ("a", "b", "l")
WORKSPACE_KEYS = ("x", "y", "z", "roll", "pitch", "yaw")
COND_LIMIT = 1e6
RETRY_YAW = np.radians([60.0, -60.0, 120.0, -120.0, 180.0])
LOCKABLE = ("a", "psi")
_NONE = np.zeros(0, dtype=np.intp)  # no failing pose
_KEYS = {"name", "kind", "units", "source", "description", "notes", "slider_angles", "slider_travel",
         "platform_radius", "leg_length", "psi_range", "theta_range", "u_joint_axes", "redundancy", "workspace",
         "locked"}


def _solve_rows(A, b):
    """``np.linalg.solve`` of stacks A (n, k, k), b (n, k, 1), with NaN rows where a matrix is singular (joints
    far outside the mechanism's range), so that one such pose fails alone, with its reason, not the batch."""
    try:
        return np.linalg.solve(A, b)
    except np.linalg.LinAlgError:
        out = np.full(b.shape, np.nan)
        for i in range(len(A)):
            try:
                out[i] = np.linalg.solve(A[i], b[i])
            except np.linalg.LinAlgError:
                pass
        return out

class PUPS3(Mechanism):
    """The 3-PUPS platform (see the module docstring for frames, joints and error parameters).

    ``fk_and_jacobian`` and ``passive_angles`` run the compiled kernel (``pups_kernels.pups_solve``) unless
    ``backend`` is 'numpy', when the numpy reference (``_solve``, ``_error_transfer``) runs instead.

    travel : (2,) slider range of a_i, m.  platform_radius : c, m.  leg_length : (2,) range of l_i, m.
    psi_range, theta_range : (2,) ranges of the actuated and passive U-joint angles, rad.
    slider_angles : (3,) s_i, rad.  u_joint_axes : ('x', 'y') or ('y', 'x').
    redundancy : (3,) slider positions used by the inverse kinematics, m (mid-travel by default).
    workspace : (6, 2) box of x, y, z (m) and roll, pitch, yaw (rad) sampled by ``sample_joints``.
    locked : {'a': [v or None] * 3, 'psi': [...]}, SI; None leaves a joint free.
    """

    compiled = True
    kernel_family = "pups"

    def __init__(self, name, travel, platform_radius, leg_length, psi_range, theta_range,
                 slider_angles=(0.0, 2 * np.pi / 3, 4 * np.pi / 3), u_joint_axes=("x", "y"), redundancy=None,
                 workspace=None, locked=None, cond_limit=COND_LIMIT):
        self.name = str(name)
        self.travel = _range(travel, "slider_travel")
        self.leg_length = _range(leg_length, "leg_length")
        self.psi_range = _range(psi_range, "psi_range")
        self.theta_range = _range(theta_range, "theta_range")
        if self.travel[0] <= 0 or self.leg_length[0] <= 0:
            raise ModelError("slider_travel, leg_length: ranges must be positive lengths")
        self.c = float(platform_radius)
        if not (np.isfinite(self.c) and self.c > 0):
            raise ModelError(f"platform_radius: expected a positive length, got {platform_radius!r}")
        s = np.asarray(slider_angles, dtype=float)
        if s.shape != (3,) or not np.all(np.isfinite(s)):
            raise ModelError("slider_angles: expected three angles")
        self.slider_angles = s
        axes = tuple(u_joint_axes)
        if axes not in (("x", "y"), ("y", "x")):
            raise ModelError(f"u_joint_axes: expected [x, y] or [y, x], got {list(axes)}")
        self.u_joint_axes = axes
        self.e1, self.e2 = AXES[axes[0]], AXES[axes[1]]
        self.RA = axis_rotations(2, s)
        self.c_local = -self.c * self.RA[:, :, 0]
        # The compiled kernel's model arguments (pups_kernels.solve): C-contiguous float64, as it is compiled for.
        self._kernel_constants = (np.ascontiguousarray(self.RA), np.ascontiguousarray(self.c_local), self.c,
                                  np.ascontiguousarray(axis_rotations(2, RETRY_YAW)), self.e1, self.e2)
        red = np.full(3, self.travel.mean()) if redundancy is None else np.asarray(redundancy, dtype=float)
        if red.shape != (3,) or np.any(red < self.travel[0]) or np.any(red > self.travel[1]):
            raise ModelError(f"redundancy.a: expected three slider positions within the travel, got {red.tolist()}")
        self.redundancy = red
        ws = np.asarray(workspace, dtype=float) if workspace is not None else None
        if ws is not None and (ws.shape != (6, 2) or not np.all(np.isfinite(ws)) or np.any(ws[:, 0] > ws[:, 1])):
            raise ModelError("workspace: expected finite [lower, upper] ranges for x, y, z, roll, pitch, yaw")
        self.workspace = ws
        self.cond_limit = float(cond_limit)
        self.on_failure = "raise"
        self.locked = {}
        for key, values in (locked or {}).items():
            if key not in LOCKABLE:
                raise ModelError(f"locked.{key}: only {list(LOCKABLE)} can be locked")
            vals = list(values)
            if len(vals) != 3:
                raise ModelError(f"locked.{key}: expected three values (null for a free joint)")
            rng = self.travel if key == "a" else self.psi_range
            for i, v in enumerate(vals):
                if v is None:
                    continue
                if not (np.isfinite(v) and rng[0] <= v <= rng[1]):
                    raise ModelError(f"locked.{key}[{i}]: {v!r} is outside the joint range {rng.tolist()}")
                self.locked[(key, i)] = float(v)
        self.joint_names = tuple(f"{k}{i + 1}" for k in ("a", "psi", "l") for i in range(3))
        self.joint_types = (PRISMATIC,) * 3 + (REVOLUTE,) * 3 + (PRISMATIC,) * 3
        lim = np.array([self.travel] * 3 + [self.psi_range] * 3 + [self.leg_length] * 3)
        for (key, i), v in self.locked.items():
            lim[self.joint_names.index(f"{key}{i + 1}")] = (v, v)
        self.joint_limits = lim
        self.param_names = tuple(f"{g}{i + 1}.{ax}" for i in range(3) for g in GROUPS for ax in "xyz")
        self.param_kinds = ("length",) * 27
        self.nominal = np.zeros(27)

    # ------------------------------------------------------------------ variants

    @property
    def variant(self) -> str:
        """'3-PUPS', '3-UPS', '3-PRPS', '3-RPS' or 'asymmetric'."""
        a = sum(("a", i) in self.locked for i in range(3))
        p = sum(("psi", i) in self.locked for i in range(3))
        names = {(0, 0): "3-PUPS", (3, 0): "3-UPS", (0, 3): "3-PRPS", (3, 3): "3-RPS"}
        return names.get((a, p), "asymmetric")

    def with_locked(self, **locked) -> "PUPS3":
        """A copy with joints locked, e.g. ``with_locked(a=[0.25] * 3)`` (SI; None frees a joint)."""
        return PUPS3(self.name, self.travel, self.c, self.leg_length, self.psi_range, self.theta_range,
                     self.slider_angles, self.u_joint_axes, self.redundancy, self.workspace, locked, self.cond_limit)

    def tolerant(self) -> "PUPS3":
        """A copy whose forward kinematics returns NaN rows where the loop cannot close (no ModelError)."""
        out = copy.copy(self)
        out.on_failure = "nan"
        return out

    def _locked_mask(self, key):
        return np.array([(key, i) in self.locked for i in range(3)])

    def _locked_values(self, key):
        return np.array([self.locked.get((key, i), np.nan) for i in range(3)])

    # ------------------------------------------------------------------ kinematics

    def _limbs(self, q, dx):
        """Per-limb geometry for joints (n, 9) and errors dx (n, 27) or None."""
        n = len(q)
        a, psi, l = q[:, 0:3], q[:, 3:6], q[:, 6:9]
        E = np.zeros((n, 3, 3, 3)) if dx is None else np.broadcast_to(dx, (n, 27)).reshape(n, 3, 3, 3)
        RA = self.RA
        hub = -a[:, :, None] * RA[None, :, :, 0] + E[:, :, 0] + np.einsum("ijk,nik->nij", RA, E[:, :, 1])
        M = np.einsum("ijk,nikl->nijl", RA, axis_rotations(self.e1, psi))
        L = E[:, :, 2].copy()
        L[:, :, 2] += l
        along = L[:, :, self.e2]
        k = M[:, :, :, self.e2]
        centre = hub + k * along[:, :, None]
        Lperp = L.copy()
        Lperp[:, :, self.e2] = 0.0
        rho = np.linalg.norm(Lperp, axis=2)
        return {"M": M, "L": L, "Lperp": Lperp, "k": k, "centre": centre, "rho": rho}

    def _residual(self, p, R, g):
        C = p[:, None, :] + np.einsum("nij,kj->nki", R, self.c_local)
        d = C - g["centre"]
        f = np.empty((len(p), 6))
        f[:, 0::2] = (np.einsum("nki,nki->nk", d, d) - g["rho"] ** 2) / (2.0 * g["rho"])
        f[:, 1::2] = np.einsum("nki,nki->nk", g["k"], d)
        return f, C, d

    def _jacobian_rows(self, R, dirs):
        """(n, 6, 6) rows [n^T, (R c_i x n)^T] for directions dirs (n, 6, 3) ordered limb by limb."""
        r = np.repeat(np.einsum("nij,kj->nki", R, self.c_local), 2, axis=1)
        return np.concatenate([dirs, np.cross(r, dirs)], axis=2)

    @staticmethod
    def _directions(d, g, unit=False):
        """(n, 6, 3) row directions, limb by limb: the sphere gradient d / rho (w_i if ``unit``), then k_i."""
        out = np.empty(d.shape[:1] + (6, 3))
        out[:, 0::2] = d / (np.linalg.norm(d, axis=2) if unit else g["rho"])[:, :, None]
        out[:, 1::2] = g["k"]
        return out

    def _start(self, g):
        """Platform position with the platform shrunk to a point (Gauss-Newton), then R = I."""
        n = len(g["rho"])
        p = g["centre"].mean(axis=1) + np.array([0.0, 0.0, 1.0]) * g["rho"].mean(axis=1)[:, None]
        for _ in range(30):
            d = p[:, None, :] - g["centre"]
            f = np.concatenate([(np.einsum("nki,nki->nk", d, d) - g["rho"] ** 2) / (2 * g["rho"]),
                                np.einsum("nki,nki->nk", g["k"], d)], axis=1)
            J = np.concatenate([d / g["rho"][:, :, None], g["k"]], axis=1)
            step = _solve_rows(np.einsum("nki,nkj->nij", J, J) + 1e-12 * np.eye(3),
                               np.einsum("nki,nk->ni", J, f)[:, :, None])[:, :, 0]
            p = p - step
            if np.max(np.abs(step), initial=0.0) < 1e-10:
                break
        return p, np.broadcast_to(np.eye(3), (n, 3, 3)).copy()

    def _newton(self, p, R, g):
        """Damped Newton on the six closure equations from (p, R); returns p, R, d, residual norm."""
        f, _, d = self._residual(p, R, g)
        norm = np.linalg.norm(f, axis=1)
        active = np.ones(len(p), dtype=bool)
        for _ in range(60):
            idx = np.flatnonzero(active & (norm > 1e-14))
            if idx.size == 0:
                break
            gi = {key: v[idx] for key, v in g.items()}
            J = self._jacobian_rows(R[idx], self._directions(d[idx], gi))
            JT = J.transpose(0, 2, 1)
            step = -_solve_rows(JT @ J + 1e-14 * np.eye(6), JT @ f[idx][:, :, None])[:, :, 0]
            t = np.ones(idx.size)
            pending = np.arange(idx.size)
            for _ls in range(12):
                rows = idx[pending]
                st = step[pending] * t[pending, None]
                pt, Rt = p[rows] + st[:, :3], exp_so3(st[:, 3:]) @ R[rows]
                ft, _, dt = self._residual(pt, Rt, {key: v[pending] for key, v in gi.items()})
                nt = np.linalg.norm(ft, axis=1)
                better = nt < norm[rows]
                acc = rows[better]
                p[acc], R[acc], f[acc], d[acc], norm[acc] = pt[better], Rt[better], ft[better], dt[better], nt[better]
                t[pending[~better]] *= 0.5
                pending = pending[~better]
                if pending.size == 0:
                    break
            active[idx[pending]] = False
        return p, R, d, norm

    def _solve(self, q, dx):
        """Platform poses for joints q (n, 9): dict with p, R, theta, J1, its scaled condition, ok, reason.

        Newton starts from the platform shrunk to a point and R = I; where that fails, from R = Rz(y)
        for the yaw angles ``RETRY_YAW`` in turn (the first assembly found, not turned over, is kept).
        """
        g = self._limbs(q, dx)
        p0, R0 = self._start(g)
        n = len(q)
        p, R, d, norm = self._newton(p0.copy(), R0, g)
        for yaw in RETRY_YAW:
            redo = np.flatnonzero((norm > 1e-10) | (R[:, 2, 2] <= 0.0))
            if redo.size == 0:
                break
            gi = {key: v[redo] for key, v in g.items()}
            Ry = np.broadcast_to(axis_rotations(2, yaw), (redo.size, 3, 3)).copy()
            pr, Rr, dr, nr = self._newton(p0[redo].copy(), Ry, gi)
            take = (nr <= 1e-10) & (Rr[:, 2, 2] > 0.0)
            rows = redo[take]
            p[rows], R[rows], d[rows], norm[rows] = pr[take], Rr[take], dr[take], nr[take]
        ok = norm <= 1e-10
        reason = np.where(ok, "", "the legs cannot close the platform triangle (no assembly near the start)")
        flipped = ok & (R[:, 2, 2] <= 0.0)
        reason = np.where(flipped, "the only assembly found has the platform turned over", reason)
        ok &= ~flipped
        dirs = self._directions(d, g, unit=True)
        J1 = self._jacobian_rows(R, dirs)
        cond = np.full(n, np.inf)
        fin = np.all(np.isfinite(J1), axis=(1, 2))
        scaled = J1[fin].copy()
        scaled[:, :, 3:] /= self.c
        cond[fin] = np.linalg.cond(scaled)
        singular = ok & ~(cond <= self.cond_limit)
        reason = reason.astype(object)
        reason[singular] = [f"J1 is singular (condition number {x:.3g} > {self.cond_limit:.3g}): a forward-kinematic "
                            f"singularity" for x in cond[singular]]
        ok &= ~singular
        v = np.einsum("nkji,nkj->nki", g["M"], d)
        e2 = np.zeros(3)
        e2[self.e2] = 1.0
        theta = np.arctan2(np.einsum("i,nki->nk", e2, np.cross(g["Lperp"], v)),
                           np.einsum("nki,nki->nk", g["Lperp"], v))
        return {"p": p, "R": R, "theta": theta, "J1": J1, "dirs": dirs, "cond": cond, "ok": ok, "reason": reason,
                "g": g, "residual": norm}

    def _check_locked(self, q, field="joints"):
        for (key, i), v in self.locked.items():
            j = self.joint_names.index(f"{key}{i + 1}")
            bad = np.flatnonzero(np.abs(q[:, j] - v) > 1e-9)
            if bad.size:
                raise ModelError(f"{field}[{bad[0]}][{j}] ({self.joint_names[j]}) = {q[bad[0], j]:.9g} but "
                                 f"{self.joint_names[j]} is locked at {v:.9g} ({self.variant})")

    def fk_and_jacobian(self, q, dx=None, jacobian=True):
        q = self.check_joints(q)
        self._check_locked(q)
        dx = self.check_dx(dx, len(q))
        if self._kernels() is None:
            return self._fk_and_jacobian_numpy(q, dx, jacobian)
        T, G, theta, bad, reason = self._solve_compiled(q, dx, jacobian)
        if bad.size:
            if self.on_failure == "raise":
                i = bad[0]
                raise ModelError(f"joints[{i}] = {_fmt_q(q[i])}: {reason[i]}")
            T[bad] = np.nan
            if jacobian:
                G[bad] = np.nan
        return T, (ErrorJacobian(G, self.param_names, self.param_units) if jacobian else None)

    def _fk_and_jacobian_numpy(self, q, dx, jacobian=True):
        """The numpy reference of ``fk_and_jacobian`` (checked joints and dx)."""
        n = len(q)
        s = self._solve(q, dx)
        bad = np.flatnonzero(~s["ok"])
        if bad.size and self.on_failure == "raise":
            i = bad[0]
            raise ModelError(f"joints[{i}] = {_fmt_q(q[i])}: {s['reason'][i]}")
        T = np.zeros((n, 4, 4))
        T[:, :3, :3] = s["R"]
        T[:, :3, 3] = s["p"]
        T[:, 3, 3] = 1.0
        T[bad] = np.nan
        if not jacobian:
            return T, None
        J = self._error_transfer(s)
        J[bad] = np.nan
        return T, ErrorJacobian(J, self.param_names, self.param_units)

    def _solve_compiled(self, q, dx, jacobian):
        """``pups_kernels.pups_solve`` for checked joints and dx: (T, G or None, theta, bad, reason), ``bad`` the
        indices of the poses that fail and ``reason`` {index: text} (the numpy ``_solve``'s texts)."""
        from . import pups_kernels
        T, G, theta, J1s, kappa, status, attention = pups_kernels.solve(self, q, dx, jacobian)
        if not attention:
            return T, G, theta, _NONE, {}
        ok = status == 0
        # kappa (Frobenius) >= the 2-norm condition number: only poses whose kappa reaches the limit need an SVD.
        check = np.flatnonzero(ok & ~(kappa <= 0.5 * self.cond_limit))
        sing_cond = {}
        if check.size:
            fin = np.all(np.isfinite(J1s[check]), axis=(1, 2))
            cond = np.full(check.size, np.inf)
            cond[fin] = np.linalg.cond(J1s[check[fin]])
            singular = ~(cond <= self.cond_limit)
            ok[check[singular]] = False
            sing_cond = dict(zip(check[singular].tolist(), cond[singular].tolist()))
        bad = np.flatnonzero(~ok)
        reason = {}
        for i in bad.tolist():
            if status[i] == 1:
                reason[i] = "the legs cannot close the platform triangle (no assembly near the start)"
            elif status[i] == 2:
                reason[i] = "the only assembly found has the platform turned over"
            else:
                reason[i] = (f"J1 is singular (condition number {sing_cond[i]:.3g} > {self.cond_limit:.3g}): a "
                             f"forward-kinematic singularity")
        return T, G, theta, bad, reason

    def warm_up(self) -> float:
        """Compile or load from the cache the compiled 3-PUPS kernel (when the backend is numba); seconds."""
        t0 = time.perf_counter()
        if self._kernels() is not None:
            from . import pups_kernels
            pups_kernels.solve(self, np.zeros((1, 9)), None, True)
        return time.perf_counter() - t0

    def _error_transfer(self, s):
        """(n, 6, 27) G = J1^-1 J2 (see the module docstring)."""
        n = len(s["p"])
        g = s["g"]
        B = np.einsum("nkij,nkjl->nkil", g["M"], axis_rotations(self.e2, s["theta"]))
        J2 = np.zeros((n, 6, 27))
        for i in range(3):
            D = s["dirs"][:, 2 * i:2 * i + 2]
            cols = 9 * i
            J2[:, 2 * i:2 * i + 2, cols:cols + 3] = D
            J2[:, 2 * i:2 * i + 2, cols + 3:cols + 6] = D @ self.RA[i]
            J2[:, 2 * i:2 * i + 2, cols + 6:cols + 9] = D @ B[:, i]
        J1 = s["J1"].copy()
        fin = np.all(np.isfinite(J1), axis=(1, 2)) & s["ok"]
        G = np.full((n, 6, 27), np.nan)
        G[fin] = np.linalg.solve(J1[fin], J2[fin])
        return G

    def passive_angles(self, q, dx=None) -> np.ndarray:
        """(n, 3) passive angles theta_i (rad) of the assembled mechanism."""
        q = self.check_joints(q)
        dx = self.check_dx(dx, len(q))
        if self._kernels() is None:
            s = self._solve(q, dx)
            return np.where(s["ok"][:, None], s["theta"], np.nan)
        _, _, theta, bad, _ = self._solve_compiled(q, dx, False)
        theta[bad] = np.nan
        return theta

    def inverse_kinematics(self, T, a=None, passive: bool = False, field: str = "pose"):
        """Joints (n, 9) for platform poses T (n, 4, 4) (nominal geometry).

        a : (3,) or (n, 3) slider positions (m) for the free sliders; default ``redundancy``.
        passive : also return theta (n, 3), rad.  Raises ModelError naming the pose and the reason when
        a pose is out of reach (leg, slider, U-joint range), violates a locked joint, or is singular.
        """
        T = np.asarray(T, dtype=float)
        if T.ndim == 2:
            T = T[None]
        if T.ndim != 3 or T.shape[1:] != (4, 4) or not np.all(np.isfinite(T)):
            raise ModelError(f"{field}: expected finite (n, 4, 4) poses, got shape {T.shape}")
        q, theta, reason = self._ik(T, a)
        bad = np.flatnonzero(reason != "")
        if bad.size:
            i = bad[0]
            raise ModelError(f"{field}[{i}] ({_fmt_pose(T[i])}): {reason[i]}")
        return (q, theta) if passive else q

    def _ik(self, T, a=None):
        """(q, theta, reason) without raising; reason '' where the pose is reachable."""
        n = len(T)
        p, R = T[:, :3, 3], T[:, :3, :3]
        C = p[:, None, :] + np.einsum("nij,kj->nki", R, self.c_local)
        CA = np.einsum("kji,nkj->nki", self.RA, C)
        if a is None:
            a_val = np.broadcast_to(self.redundancy, (n, 3)).copy()
        else:
            a_val = np.array(np.broadcast_to(np.asarray(a, dtype=float), (n, 3)))
            if np.any(self._locked_mask("a")):
                raise ModelError("a: the sliders of a locked variant cannot be chosen")
        a_lock, psi_lock = self._locked_mask("a"), self._locked_mask("psi")
        a_val[:, a_lock] = self._locked_values("a")[a_lock]
        reason = np.full(n, "", dtype=object)
        solve_a = psi_lock & ~a_lock if self.e1 == AXES["y"] else np.zeros(3, dtype=bool)
        for i in np.flatnonzero(solve_a):
            a_val[:, i] = CA[:, i, 2] * np.tan(self.locked[("psi", i)]) - CA[:, i, 0]
        v = CA.copy()
        v[:, :, 0] += a_val
        l = np.linalg.norm(v, axis=2)
        w = v / l[:, :, None]
        if self.e1 == AXES["x"]:
            theta, psi = np.arcsin(np.clip(w[:, :, 0], -1, 1)), np.arctan2(-w[:, :, 1], w[:, :, 2])
        else:
            theta, psi = np.arcsin(np.clip(-w[:, :, 1], -1, 1)), np.arctan2(w[:, :, 0], w[:, :, 2])
        for i in np.flatnonzero(psi_lock):
            off = np.abs(psi[:, i] - self.locked[("psi", i)])
            gap = l[:, i] * np.sin(off)
            bad = (off > 1e-9) & (reason == "")
            reason[bad] = [f"C{i + 1} is {x * 1e3:.4g} mm off the plane of limb {i + 1} fixed by the locked psi{i + 1} "
                           f"({self.variant}); the pose is not reachable" for x in gap[bad]]
            psi[:, i] = self.locked[("psi", i)]
        q = np.concatenate([a_val, psi, l], axis=1)
        checks = [("a", a_val, self.travel, 1e3, "mm", "slider"), ("l", l, self.leg_length, 1e3, "mm", "leg"),
                  ("psi", psi, self.psi_range, 180 / np.pi, "deg", "U-joint angle"),
                  ("theta", theta, self.theta_range, 180 / np.pi, "deg", "passive U-joint angle")]
        for key, val, rng, scale, unit, what in checks:
            out = (val < rng[0] - 1e-12) | (val > rng[1] + 1e-12)
            for i in range(3):
                bad = out[:, i] & (reason == "")
                reason[bad] = [f"{what} {key}{i + 1} = {x * scale:.6g} {unit} is outside "
                               f"[{rng[0] * scale:.6g}, {rng[1] * scale:.6g}] {unit}" for x in val[bad, i]]
        okq = reason == ""
        if okq.any():
            dirs = np.empty((int(okq.sum()), 6, 3))
            dirs[:, 0::2] = np.einsum("kij,nkj->nki", self.RA, w[okq])
            M = np.einsum("ijk,nikl->nijl", self.RA, axis_rotations(self.e1, psi[okq]))
            dirs[:, 1::2] = M[:, :, :, self.e2]
            J1 = self._jacobian_rows(R[okq], dirs)
            J1[:, :, 3:] /= self.c
            cond = np.linalg.cond(J1)
            sing = ~(cond <= self.cond_limit)
            idx = np.flatnonzero(okq)[sing]
            reason[idx] = [f"J1 is singular (condition number {x:.3g} > {self.cond_limit:.3g}): a forward-kinematic "
                           f"singularity" for x in cond[sing]]
        return q, theta, reason

    # ------------------------------------------------------------------ sampling

    def _plane_constraints(self):
        """[(limb, normal (3,), point (3,))]: limbs whose locked U-joint confines C_i to a plane."""
        out = []
        for i in range(3):
            if ("psi", i) not in self.locked:
                continue
            psi = self.locked[("psi", i)]
            if self.e1 == AXES["x"]:
                out.append((i, self.RA[i] @ axis_rotations(0, psi)[:, 1], np.zeros(3)))
            elif ("a", i) in self.locked:
                out.append((i, self.RA[i] @ axis_rotations(1, psi)[:, 0], -self.locked[("a", i)] * self.RA[i][:, 0]))
        return out

    def project_poses(self, T):
        """(T (n, 4, 4), ok (n,)): poses moved onto the planes that locked U-joints confine C_i to.

        Gauss-Newton with minimum-norm steps in (dp, c dphi); poses of six-DOF variants are returned
        unchanged.
        """
        T = np.array(T, dtype=float)
        cons = self._plane_constraints()
        if not cons:
            return T, np.ones(len(T), dtype=bool)
        limbs = [i for i, _, _ in cons]
        nrm = np.array([v for _, v, _ in cons])
        pts = np.array([v for _, _, v in cons])
        p, R = T[:, :3, 3].copy(), T[:, :3, :3].copy()
        for _ in range(30):
            r = np.einsum("nij,kj->nki", R, self.c_local[limbs])
            f = np.einsum("kj,nkj->nk", nrm, p[:, None, :] + r - pts)
            if np.abs(f).max(initial=0.0) < 1e-14:
                break
            J = np.concatenate([np.broadcast_to(nrm, r.shape), np.cross(r, nrm) / self.c], axis=2)
            step = -np.einsum("nij,nj->ni", np.linalg.pinv(J), f)
            p += step[:, :3]
            R = exp_so3(step[:, 3:] / self.c) @ R
        T[:, :3, :3], T[:, :3, 3] = R, p
        return T, np.abs(f).max(axis=1) < 1e-12

    def sample_poses(self, m: int, seed=0):
        """(q (m, 9), T (m, 4, 4)) reachable configurations, seeded and deterministic.

        Poses are drawn uniformly in the workspace box (variants with locked U-joints first move them
        onto their constraint planes, ``project_poses``, and keep those still in the box); a pose is
        kept when its inverse kinematics is reachable and the forward kinematics of those joints
        returns the same pose.
        """
        if self.workspace is None:
            raise ModelError(f"workspace: robot {self.name!r} has no workspace box to sample")
        rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
        m = int(m)
        qs, Ts, got, tries = [np.zeros((0, 9))], [np.zeros((0, 4, 4))], 0, 0
        lo, hi = self.workspace[:, 0], self.workspace[:, 1]
        while got < m:
            batch = max(64, 2 * (m - got))
            x = lo + (hi - lo) * rng.random((batch, 6))
            T, keep = self.project_poses(pose_matrices(x[:, :3], rpy_to_matrices(x[:, 3:])))
            x = np.concatenate([T[:, :3, 3], rpy_from_matrix(T[:, :3, :3])], axis=1)
            keep &= np.all((x >= lo - 1e-12) & (x <= hi + 1e-12), axis=1)
            q, _, reason = self._ik(T)
            keep &= reason == ""
            if keep.any():
                s = self._solve(q[keep], None)
                same = s["ok"] & (np.linalg.norm(s["p"] - T[keep, :3, 3], axis=1) < 1e-9) & \
                    (np.abs(s["R"] - T[keep, :3, :3]).max(axis=(1, 2)) < 1e-9)
                keep[np.flatnonzero(keep)[~same]] = False
            qs.append(q[keep])
            Ts.append(T[keep])
            got += int(keep.sum())
            tries += batch
            if tries > 200 * max(m, 50) and got < m:
                raise ModelError(f"workspace: fewer than {m} reachable configurations in {tries} draws "
                                 f"({self.variant}); widen the box or the joint ranges")
        return np.concatenate(qs)[:m], np.concatenate(Ts)[:m]

    def search_space(self):
        """Local searches move the platform pose (x y z m, roll pitch yaw rad) within the workspace box;
        joints follow by inverse kinematics (NaN rows where out of reach)."""
        if self.workspace is None:
            raise ModelError(f"workspace: robot {self.name!r} has no workspace box to search")

        def to_joints(x):
            x = np.atleast_2d(x)
            q, _, reason = self._ik(pose_matrices(x[:, :3], rpy_to_matrices(x[:, 3:])))
            q = np.array(q, dtype=float)
            q[reason != ""] = np.nan
            return q

        def from_joints(q):
            T = self.fk(q)
            return np.concatenate([T[:, :3, 3], rpy_from_matrix(T[:, :3, :3])], axis=1)

        return self.workspace, to_joints, from_joints

    def sample_joints(self, m: int, seed=0) -> np.ndarray:
        """(m, 9) reachable joints (see ``sample_poses``), seeded and deterministic."""
        return self.sample_poses(m, seed)[0]

    def describe(self) -> dict:
        out = super().describe()
        out.update({"variant": self.variant, "u_joint_axes": list(self.u_joint_axes), "platform_radius_m": self.c,
                    "redundancy_a_m": self.redundancy.tolist(),
                    "locked": {f"{k}{i + 1}": v for (k, i), v in sorted(self.locked.items())}})
        return out


def _fmt_q(q):
    return (f"a = {np.round(q[0:3] * 1e3, 4).tolist()} mm, psi = {np.round(np.degrees(q[3:6]), 4).tolist()} deg, "
            f"l = {np.round(q[6:9] * 1e3, 4).tolist()} mm")


def _fmt_pose(T):
    return (f"xyz = {np.round(T[:3, 3] * 1e3, 4).tolist()} mm, "
            f"rpy = {np.round(np.degrees(rpy_from_matrix(T[None, :3, :3])[0]), 4).tolist()} deg")


def _range(v, field):
    arr = np.asarray(v, dtype=float)
    if arr.shape != (2,) or not np.all(np.isfinite(arr)) or arr[0] >= arr[1]:
        raise ModelError(f"{field}: expected finite [lower, upper] with lower < upper, got {v!r}")
    return arr


def _pair(data, key, scale, required=True, default=None):
    v = data.get(key, default)
    if v is None:
        if required:
            raise ModelError(f"{key}: missing")
        return None
    if not isinstance(v, (list, tuple)) or len(v) != 2:
        raise ModelError(f"{key}: expected [lower, upper]")
    out = [parse_number(x, f"{key}[{i}]") * scale for i, x in enumerate(v)]
    return _range(out, key)


def pups_from_dict(data: dict, path=None) -> PUPS3:
    """PUPS3 from a parsed robot file of kind '3pups' (units stated in the file; see config/robots)."""
    extra = sorted(set(data) - _KEYS)
    if extra:
        raise ModelError(f"robot: unknown key(s) {extra}; allowed: {sorted(_KEYS)}")
    units = data.get("units", {}) or {}
    if not isinstance(units, dict) or set(units) - {"length", "angle"}:
        raise ModelError("units: expected a mapping like {length: mm, angle: deg}")
    ls = length_scale(units.get("length", "m"))
    as_ = angle_scale(units.get("angle", "rad"))
    travel = _pair(data, "slider_travel", ls)
    legs = _pair(data, "leg_length", ls)
    psi = _pair(data, "psi_range", as_)
    theta = _pair(data, "theta_range", as_)
    if "platform_radius" not in data:
        raise ModelError("platform_radius: missing")
    c = parse_number(data["platform_radius"], "platform_radius") * ls
    if c <= 0:
        raise ModelError(f"platform_radius: expected a positive length, got {data['platform_radius']!r}")
    angles = data.get("slider_angles", [0, 2 * np.pi / 3 / as_, 4 * np.pi / 3 / as_])
    if not isinstance(angles, (list, tuple)) or len(angles) != 3:
        raise ModelError("slider_angles: expected three angles")
    angles = [parse_number(x, f"slider_angles[{i}]") * as_ for i, x in enumerate(angles)]
    axes = data.get("u_joint_axes", ["x", "y"])
    if not isinstance(axes, (list, tuple)) or tuple(axes) not in (("x", "y"), ("y", "x")):
        raise ModelError(f"u_joint_axes: expected [x, y] or [y, x], got {axes!r}")
    red = data.get("redundancy")
    red_a = None
    if red is not None:
        if not isinstance(red, dict) or set(red) != {"a"}:
            raise ModelError("redundancy: expected {a: [a1, a2, a3]} (slider positions used by the inverse kinematics)")
        if not isinstance(red["a"], (list, tuple)) or len(red["a"]) != 3:
            raise ModelError("redundancy.a: expected three slider positions")
        red_a = [parse_number(x, f"redundancy.a[{i}]") * ls for i, x in enumerate(red["a"])]
    ws = data.get("workspace")
    box = None
    if ws is not None:
        if not isinstance(ws, dict) or set(ws) != set(WORKSPACE_KEYS):
            raise ModelError(f"workspace: expected ranges for exactly {list(WORKSPACE_KEYS)}")
        box = [_pair(ws, k, ls if k in "xyz" else as_).tolist() for k in WORKSPACE_KEYS]
    locked = data.get("locked") or {}
    if not isinstance(locked, dict):
        raise ModelError("locked: expected a mapping like {a: [250, 250, 250]}")
    lock = {}
    for key, vals in locked.items():
        if key not in LOCKABLE:
            raise ModelError(f"locked.{key}: only {list(LOCKABLE)} can be locked")
        if not isinstance(vals, (list, tuple)) or len(vals) != 3:
            raise ModelError(f"locked.{key}: expected three values (null for a free joint)")
        scale = ls if key == "a" else as_
        lock[key] = [None if v is None else parse_number(v, f"locked.{key}[{i}]") * scale for i, v in enumerate(vals)]
    name = data.get("name") or (Path(path).stem if path else "3pups")
    return PUPS3(name, travel, c, legs, psi, theta, angles, tuple(axes), red_a, box, lock)
