"""Serial chains described by Denavit-Hartenberg parameters, standard or modified (Craig).

Error parameters, in the order of Gao et al. (2023): ``a1..an, d1..dn, alpha1..alphan, theta1..thetan``
(m and rad). For a revolute joint ``theta_i`` is its zero offset; for a prismatic joint ``d_i`` is.

Standard D-H: ``T_i = Trans_z(d_i) Rot_z(theta_i) Trans_x(a_i) Rot_x(alpha_i)``.
Modified D-H: ``T_i = Rot_x(alpha_i) Trans_x(a_i) Rot_z(theta_i) Trans_z(d_i)``, where ``alpha_i`` and
``a_i`` are Craig's ``alpha_{i-1}`` and ``a_{i-1}`` (the row of joint i in a modified D-H table).
The chain is ``T = base · T_1 ... T_n · tool``.

Each error is a screw along or about a known line, so the Jacobian is analytic: with ``P`` the tool
point, a length error along unit vector ``u`` moves P by ``u``; an angle error about the line
``(u, o)`` moves P by ``u x (P - o)`` and turns the tool by ``u``.
"""
from __future__ import annotations

import numpy as np

from ..geometry import cross3
from .base import PRISMATIC, REVOLUTE, CompiledChain, ErrorJacobian, ModelError

CONVENTIONS = ("standard", "modified")
SMALL_BATCH = 128  # up to this many poses the numpy path multiplies 4x4 link transforms (faster below, slower above)
KINDS = ("a", "d", "alpha", "theta")


class DHChain(CompiledChain):
    """Serial chain from a D-H table (SI units).

    a, alpha, d, theta : (dof,) link lengths (m), twists (rad), offsets (m) and joint-angle offsets (rad).
    joint_types : 'revolute' or 'prismatic' per joint.  joint_limits : (dof, 2), rad or m.
    base, tool : 4x4 transforms (m).  convention : 'standard' or 'modified'.  direction, offset : (dof,)
    each joint's direction (+1 or -1) and zero offset (rad or m) as its controller reports it: the joints
    ``q`` of every call are the controller's, and the model turns them into ``direction * q + offset``
    (limits are the controller's too).
    ``fk_and_jacobian`` runs the compiled kernel (``chain_kernels.dh_chain``) unless ``backend`` is 'numpy'.
    """

    kernel_family = "dh"

    def __init__(self, name, a, alpha, d, theta, joint_types=None, joint_limits=None, joint_names=None,
                 convention="standard", base=None, tool=None, direction=None, offset=None):
        self.name = str(name)
        cols = {}
        for field, values in (("a", a), ("alpha", alpha), ("d", d), ("theta", theta)):
            arr = np.asarray(values, dtype=float)
            if arr.ndim != 1:
                raise ModelError(f"{field}: expected a list of numbers, got shape {arr.shape}")
            bad = np.flatnonzero(~np.isfinite(arr))
            if bad.size:
                raise ModelError(f"joints[{bad[0]}].{field}: not a finite number")
            cols[field] = arr
        dof = cols["a"].size
        if dof == 0:
            raise ModelError("joints: a chain needs at least one joint")
        for field, arr in cols.items():
            if arr.size != dof:
                raise ModelError(f"{field}: expected {dof} values (one per joint), got {arr.size}")
        if convention not in CONVENTIONS:
            raise ModelError(f"convention: expected one of {CONVENTIONS}, got {convention!r}")
        self.convention = convention
        self.a, self.alpha, self.d, self.theta = cols["a"], cols["alpha"], cols["d"], cols["theta"]
        types = tuple(joint_types) if joint_types is not None else (REVOLUTE,) * dof
        if len(types) != dof:
            raise ModelError(f"joint types: expected {dof}, got {len(types)}")
        for i, t in enumerate(types):
            if t not in (REVOLUTE, PRISMATIC):
                raise ModelError(f"joints[{i}].type: expected 'revolute' or 'prismatic', got {t!r}")
        self.joint_types = types
        self.joint_names = tuple(joint_names) if joint_names is not None else tuple(f"joint{i + 1}" for i in range(dof))
        if len(self.joint_names) != dof or len(set(self.joint_names)) != dof:
            raise ModelError(f"joint names: expected {dof} distinct names, got {list(self.joint_names)}")
        if joint_limits is None:
            if PRISMATIC in types:
                raise ModelError("limits: prismatic joints need explicit limits")
            joint_limits = [[-np.pi, np.pi]] * dof
        lim = np.asarray(joint_limits, dtype=float)
        if lim.shape != (dof, 2):
            raise ModelError(f"limits: expected shape ({dof}, 2), got {lim.shape}")
        for i in range(dof):
            if not (np.all(np.isfinite(lim[i])) and lim[i, 0] < lim[i, 1]):
                raise ModelError(f"joints[{i}].limits: expected finite [lower, upper] with lower < upper, "
                                 f"got {lim[i].tolist()}")
        self.joint_limits = lim
        self.base = _check_transform(base, "base")
        self.tool = _check_transform(tool, "tool")
        idx = [str(i + 1) for i in range(dof)]
        self.param_names = tuple(k + j for k in KINDS for j in idx)
        self.param_kinds = ("length",) * (2 * dof) + ("angle",) * (2 * dof)
        self.nominal = np.concatenate([self.a, self.d, self.alpha, self.theta])
        self._revolute = np.array([t == REVOLUTE for t in types])
        self.direction = np.ones(dof) if direction is None else np.asarray(direction, float).reshape(-1)
        self.joint_offset = np.zeros(dof) if offset is None else np.asarray(offset, float).reshape(-1)
        if self.direction.shape != (dof,) or not np.all(np.abs(self.direction) == 1):
            raise ModelError(f"direction: expected +1 or -1 for each of the {dof} joints, got {self.direction.tolist()}")
        if self.joint_offset.shape != (dof,) or not np.all(np.isfinite(self.joint_offset)):
            raise ModelError(f"offset: expected a finite zero offset for each of the {dof} joints")
        self._controller = bool(np.any(self.direction != 1) or np.any(self.joint_offset != 0))

    @property
    def joint_direction(self) -> np.ndarray:
        """(dof,) +1 or -1: the sign of each controller joint in the model."""
        return self.direction

    def fk_and_jacobian(self, q, dx=None, jacobian: bool = True):
        if self._controller:
            q = self.check_joints(q) * self.direction + self.joint_offset
        return super().fk_and_jacobian(q, dx, jacobian)

    def joint_columns(self) -> np.ndarray:
        """(dof,) column of each joint's zero offset: d_i for a prismatic joint, theta_i for a revolute one."""
        n = self.dof
        return np.array([(n + i) if t == PRISMATIC else (3 * n + i) for i, t in enumerate(self.joint_types)])

    def _run_kernel(self, kernels, q, dx, T, J, jacobian):
        return kernels.dh_chain(q, self.nominal, dx, self._revolute, self.convention == "standard", self.base,
                                self.tool, T, J, jacobian)

    def _fk_and_jacobian_numpy(self, q, dx=None, jacobian=True):
        """The numpy reference implementation of ``fk_and_jacobian``: up to ``SMALL_BATCH`` poses a product of
        4x4 link transforms (fewer numpy calls), beyond it a walk along the chain on (3, n) axis arrays (no
        stacked 4x4 products, slow in numpy for many poses)."""
        q = self.check_joints(q)
        n, dof = q.shape
        dx = self.check_dx(dx, n)
        p = self.nominal if dx is None else self.nominal + dx
        if n <= SMALL_BATCH:
            return self._few_poses_numpy(q, p, jacobian)
        # Per-joint parameters: scalars, or (n,) columns when dx varies per pose.
        P = p.T if p.ndim == 2 else p
        a, d, alpha, theta = (P[k * dof:(k + 1) * dof] for k in range(4))
        qT = q.T
        R0, o0 = self.base[:3, :3], self.base[:3, 3]
        X = np.repeat(R0[:, 0:1], n, axis=1)
        Y = np.repeat(R0[:, 1:2], n, axis=1)
        Z = np.repeat(R0[:, 2:3], n, axis=1)
        O = np.repeat(o0[:, None], n, axis=1)
        # Lines (unit vector, point) of each error screw; collected while walking the chain.
        lines = {k: [None] * dof for k in KINDS}
        standard = self.convention == "standard"
        for i in range(dof):
            if self._revolute[i]:
                th, di = qT[i] + theta[i], d[i]
            else:
                th, di = theta[i], qT[i] + d[i]
            ct, st = np.cos(th), np.sin(th)
            ca, sa = np.cos(alpha[i]), np.sin(alpha[i])
            if standard:
                lines["d"][i] = lines["theta"][i] = (Z, O)
                Xn = ct * X + st * Y
                Yr = ct * Y - st * X
                O = O + di * Z + a[i] * Xn
                Yn = ca * Yr + sa * Z
                Z = ca * Z - sa * Yr
                X, Y = Xn, Yn
                lines["a"][i] = lines["alpha"][i] = (X, O)
            else:
                lines["a"][i] = lines["alpha"][i] = (X, O)
                Y1 = ca * Y + sa * Z
                Z = ca * Z - sa * Y
                O = O + a[i] * X
                Xn = ct * X + st * Y1
                Y = ct * Y1 - st * X
                X = Xn
                O = O + di * Z
                lines["d"][i] = lines["theta"][i] = (Z, O)
        Rt, tt = self.tool[:3, :3], self.tool[:3, 3]
        Pend = O + X * tt[0] + Y * tt[1] + Z * tt[2]
        T = np.empty((n, 4, 4))
        for c in range(3):
            T[:, :3, c] = (X * Rt[0, c] + Y * Rt[1, c] + Z * Rt[2, c]).T
        T[:, :3, 3] = Pend.T
        T[:, 3, :] = (0.0, 0.0, 0.0, 1.0)
        if not jacobian:
            return T, None
        Jt = np.zeros((4 * dof, 6, n))
        for k, kind in enumerate(KINDS):  # one column at a time keeps the arrays contiguous and the copies few
            for i, (u, o) in enumerate(lines[kind]):
                col = Jt[k * dof + i]
                if kind in ("a", "d"):
                    col[:3] = u
                else:
                    col[:3] = cross3(u, Pend - o)
                    col[3:] = u
        return T, ErrorJacobian(Jt.transpose(2, 1, 0), self.param_names, self.param_units)

    def _few_poses_numpy(self, q, p, jacobian):
        """``_fk_and_jacobian_numpy`` for a few poses (a service request, a search's batch of 15): the link
        transforms of every joint and pose at once, (dof, n, 4, 4), multiplied along the chain; the same
        screws as the walk (a, alpha about the x axis and origin of the frame after each joint's table row
        in standard D-H, before it in modified; d, theta along the z axis of the other frame)."""
        n, dof = q.shape
        P = p.T if p.ndim == 2 else p[:, None]
        a, d, alpha, theta = (P[k * dof:(k + 1) * dof] for k in range(4))
        revolute = self._revolute[:, None]
        th = np.where(revolute, q.T + theta, theta)
        di = np.where(revolute, d, q.T + d)
        ct, st, ca, sa = np.cos(th), np.sin(th), np.cos(alpha), np.sin(alpha)
        A = np.zeros((dof, n, 4, 4))
        A[..., 3, 3] = 1.0
        standard = self.convention == "standard"
        if standard:  # Trans_z(d) Rot_z(theta) Trans_x(a) Rot_x(alpha)
            rows = ((ct, -st * ca, st * sa, a * ct), (st, ct * ca, -ct * sa, a * st), (0.0, sa, ca, di))
        else:  # Rot_x(alpha) Trans_x(a) Rot_z(theta) Trans_z(d)
            rows = ((ct, -st, 0.0, a), (st * ca, ct * ca, -sa, -sa * di), (st * sa, ct * sa, ca, ca * di))
        for r, row in enumerate(rows):
            for c, value in enumerate(row):
                A[..., r, c] = value
        F = np.empty((dof + 1, n, 4, 4))  # the frames along the chain, base first
        F[0] = self.base
        for i in range(dof):
            np.matmul(F[i], A[i], out=F[i + 1])
        T = F[dof] @ self.tool
        if not jacobian:
            return T, None
        along_z, about_x = (F[:-1], F[1:]) if standard else (F[1:], F[:-1])
        U = np.concatenate([about_x[..., :3, 0], along_z[..., :3, 2]])  # (2 dof, n, 3): alpha's axes, theta's
        arm = T[:, :3, 3] - np.concatenate([about_x[..., :3, 3], along_z[..., :3, 3]])
        J = np.zeros((n, 6, 4 * dof))
        J[:, :3, :2 * dof] = U.transpose(1, 2, 0)  # a along alpha's axis, d along theta's
        J[:, 0, 2 * dof:] = (U[..., 1] * arm[..., 2] - U[..., 2] * arm[..., 1]).T
        J[:, 1, 2 * dof:] = (U[..., 2] * arm[..., 0] - U[..., 0] * arm[..., 2]).T
        J[:, 2, 2 * dof:] = (U[..., 0] * arm[..., 1] - U[..., 1] * arm[..., 0]).T
        J[:, 3:, 2 * dof:] = U.transpose(1, 2, 0)
        return T, ErrorJacobian(J, self.param_names, self.param_units)

    def to_pinocchio(self, dx=None):
        """An equivalent pinocchio model (one RZ/PZ joint per D-H joint) and the id of its 'tool' frame.

        ``dx`` (p,) perturbs the parameters. Used to check the analytic model against pinocchio.
        """
        import pinocchio as pin

        p = self.nominal if dx is None else self.nominal + np.asarray(dx, dtype=float)
        n = self.dof
        a, d, alpha, theta = (p[k * n:(k + 1) * n] for k in range(4))

        def tf(rot_axis=None, angle=0.0, shift=(0.0, 0.0, 0.0)):
            R = pin.utils.rotate(rot_axis, angle) if rot_axis else np.eye(3)
            return pin.SE3(R, np.asarray(shift, dtype=float))

        model = pin.Model()
        parent, pending = 0, pin.SE3(self.base)
        for i in range(n):
            rev = self._revolute[i]
            offset = tf("z", theta[i]) if rev else tf("z", theta[i]) * tf(shift=(0, 0, d[i]))
            lead = tf(shift=(0, 0, d[i])) * tf("z", theta[i]) if rev else offset
            if self.convention == "standard":
                place, after = pending * lead, tf(shift=(a[i], 0, 0)) * tf("x", alpha[i])
            else:
                place, after = pending * tf("x", alpha[i]) * tf(shift=(a[i], 0, 0)) * lead, pin.SE3.Identity()
            joint = pin.JointModelRZ() if rev else pin.JointModelPZ()
            parent = model.addJoint(parent, joint, place, self.joint_names[i])
            pending = after
        fid = model.addFrame(pin.Frame("tool", parent, 0, pending * pin.SE3(self.tool), pin.FrameType.OP_FRAME))
        return model, fid


def _check_transform(T, field):
    if T is None:
        return np.eye(4)
    arr = np.asarray(T, dtype=float)
    if arr.shape != (4, 4) or not np.all(np.isfinite(arr)):
        raise ModelError(f"{field}: expected a finite 4x4 transform")
    R = arr[:3, :3]
    if not np.allclose(R @ R.T, np.eye(3), atol=1e-9) or np.linalg.det(R) < 0:
        raise ModelError(f"{field}: rotation part is not a proper rotation")
    return np.array(arr, order="C")
