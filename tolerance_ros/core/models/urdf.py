"""Serial chains from URDF, parsed by pinocchio, with a batched analytic error model.

Error parameters of each movable joint ``j`` (revolute, continuous or prismatic), in this order:
``j.x j.y j.z`` (m), a shift of the joint's fixed ``<origin xyz>`` along the axes of its parent link frame;
``j.rx j.ry j.rz`` (rad), small turns of the origin's frame about its own x, y and z axes, applied in that
order after its nominal ``rpy`` (``R = R(rpy) Rx(rx) Ry(ry) Rz(rz)``: to first order the three components
of a rotation vector in the origin's frame, so that every origin keeps three independent rotation errors,
even one with pitch +-pi/2, where roll and yaw turn about the same axis); then ``j.offset``, the joint's
zero offset (rad, or m for a prismatic joint). Fixed joints carry no parameters of their own: to first
order an error of a fixed origin is an error of the next movable origin, which already has all six
components.

A chain runs from ``base_link`` to ``tip_link`` either way through the tree: the joints from the base link up to
the links' common ancestor are traversed from child to parent (a foot's sole back through the leg to the torso,
each such joint's transform inverted, ``M(q)^-1 O^-1``), then down to the tip; the base link may be moved by
joints (a chain from a camera's link). Such a chain's parameters are its joints' physical origin errors as
above, whichever way it runs; a chain with joints traversed upward has a compiled kernel of its own
(``chain_kernels.urdf_either_way``, column by column).

pinocchio parses the file and validates the tree; the batched forward kinematics and the Jacobian are
our own code (a compiled kernel, and numpy as the reference), checked against pinocchio's FK in the tests.
"""
from __future__ import annotations

import math
import os
import sys
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from ..compat import frame_joint
from ..geometry import axis_angle_matrix, cross3, rpy_to_matrix
from ..resources import did_you_mean, not_a_file
from ..yamlio import decode_utf8, read_bytes
from .base import PRISMATIC, REVOLUTE, CompiledChain, ErrorJacobian, ModelError

ORIGIN_FIELDS = ("x", "y", "z", "rx", "ry", "rz")
MAX_URDF_BYTES = 8 * 1024 * 1024  # of a URDF file or robot_description text
MAX_URDF_DEPTH = 64               # elements inside elements
MAX_URDF_JOINTS = 1000
_LEADING = "\ufeff \t\r\n"       # dropped before the XML: a byte-order mark and white space


def _pin():
    try:
        import pinocchio
    except ImportError as exc:  # pragma: no cover - pinocchio is a hard dependency
        raise ModelError("URDF chains need pinocchio (pip install pin)") from exc
    return pinocchio


def _mul(A, B):
    """Product of a rotation stack (3, 3, n) with (3, 3) or (3, 3, n)."""
    if B.ndim == 2:
        return np.einsum("ikn,kj->ijn", A, B)
    return np.einsum("ikn,kjn->ijn", A, B)


def _apply(R, v):
    """R (3, 3, n) times v (3,) or (3, n) -> (3, n)."""
    if v.ndim == 1:
        return np.einsum("ikn,k->in", R, v)
    return np.einsum("ikn,kn->in", R, v)


class URDFChain(CompiledChain):
    """Serial chain from ``base_link`` to ``tip_link`` of a URDF (see the module docstring).

    ``fk_and_jacobian`` runs the compiled kernel (``chain_kernels.urdf_chain``) unless ``backend`` is 'numpy'.
    """

    kernel_family = "urdf"

    def __init__(self, urdf, tip_link=None, base_link=None, name=None):
        text, source = read_urdf(urdf)
        root = _xml(text, source)
        model = _parse(text, source)
        self.name = str(name or root.get("name") or "urdf_robot")
        self.pin_model = model
        self.source = source
        self.urdf_text = text
        joints_xml = {j.get("name"): j for j in root.findall("joint")}
        self.tip_chosen = tip_link is None
        moving = moving_leaves(model, root)
        self.fixed_leaves = [] if tip_link is not None else [n for n in leaves(root) if n not in moving]
        where = f"robot {self.name!r}" if source == "<string>" else f"{source} (robot {self.name!r})"
        tip_fid, tip_link = self._tip_frame(model, root, tip_link, where)
        base_T = np.eye(4)
        base_joint = 0
        if base_link is not None:
            if not model.existFrame(base_link):
                raise ModelError(f"base_link: no link named {base_link!r} in the URDF"
                                 f"{did_you_mean(base_link, [f.name for f in model.frames])}")
            bf = model.frames[model.getFrameId(base_link)]
            base_joint = frame_joint(bf)
            base_T = np.linalg.inv(bf.placement.homogeneous)
        upward, chain = _path(model, base_joint, frame_joint(model.frames[tip_fid]))
        if not chain and not upward:
            raise ModelError(f"tip_link: {tip_link!r} is not moved by any joint" if base_joint == 0 else
                             f"tip_link: {tip_link!r} is not moved against base_link {base_link!r} by any joint")
        chain = upward + chain
        names, types, limits, axes, origins, fixed, continuous = [], [], [], [], [], [], []
        for jid in chain:
            jname = model.names[jid]
            jm = model.joints[jid]
            xml = joints_xml.get(jname)
            if xml is None:
                raise ModelError(f"urdf: joint {jname!r} from pinocchio not found in the XML")
            jtype = xml.get("type")
            if jtype in ("revolute", "continuous"):
                types.append(REVOLUTE)
            elif jtype == "prismatic":
                types.append(PRISMATIC)
            else:
                raise ModelError(f"urdf: joint {jname!r} has type {jtype!r}; only revolute, continuous "
                                 f"and prismatic joints are supported in a serial chain")
            if xml.find("mimic") is not None:
                raise ModelError(f"urdf: joint {jname!r} is a mimic joint; mimic joints are not supported")
            axis = _vector(xml.find("axis"), "xyz", (1.0, 0.0, 0.0), f"joint {jname!r} axis")
            scale = np.abs(axis).max()  # scaled first: no length of a finite axis overflows or underflows
            if not scale > 0:
                raise ModelError(f"urdf: joint {jname!r} has a zero axis")
            unit = axis / scale
            axes.append(unit / np.linalg.norm(unit))
            org = xml.find("origin")
            xyz = _vector(org, "xyz", (0.0, 0.0, 0.0), f"joint {jname!r} origin")
            rpy = _vector(org, "rpy", (0.0, 0.0, 0.0), f"joint {jname!r} origin")
            origins.append(np.concatenate([xyz, rpy]))
            O = np.eye(4)
            O[:3, :3] = rpy_to_matrix(rpy)
            O[:3, 3] = xyz
            F = model.jointPlacements[jid].homogeneous @ np.linalg.inv(O)
            if jid in upward:   # traversed from child to parent: (F O M)^-1 = M^-1 O^-1 F^-1, F^-1 after
                F = np.linalg.inv(F)
            fixed.append(np.eye(4) if np.abs(F - np.eye(4)).max() < 1e-12 else F)
            iq = model.idx_qs[jid]
            continuous.append(jtype == "continuous" or jm.nq == 2)
            if continuous[-1]:
                limits.append((-math.pi, math.pi))
            else:
                lo, hi = float(model.lowerPositionLimit[iq]), float(model.upperPositionLimit[iq])
                if lo > hi:
                    lim = xml.find("limit")
                    raise ModelError(f"urdf ({source}): joint {jname!r}: <limit lower=\"{lim.get('lower')}\" "
                                     f"upper=\"{lim.get('upper')}\">: the lower limit is above the upper one")
                lim = xml.find("limit")
                if lim is not None and lim.get("lower") is not None and lim.get("upper") is not None and lo == hi:
                    raise ModelError(f"urdf ({source}): joint {jname!r}: <limit lower=\"{lim.get('lower')}\" "
                                     f"upper=\"{lim.get('upper')}\">: a {jtype} joint whose limits leave it no motion; "
                                     f"give its range, or make it a fixed joint")
                if not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
                    if jtype == "prismatic":
                        raise ModelError(f"urdf: prismatic joint {jname!r} needs finite <limit lower upper>")
                    lo, hi = -math.pi, math.pi
                limits.append((lo, hi))
            names.append(jname)
        self._check_serial(model, chain)
        self.chain_ids = tuple(chain)
        self.joint_names = tuple(names)
        self.joint_types = tuple(types)
        self._revolute = np.array([t == REVOLUTE for t in types])
        self.joint_limits = np.array(limits, dtype=float)
        self.continuous = np.array(continuous, dtype=bool)
        self.tip_link = tip_link
        self.root_link = root_link(root) or model.frames[0].name
        self.base_link = base_link or self.root_link
        self._axes = np.array(axes)
        self._fixed = np.array(fixed)
        self._reversed = np.array([jid in upward for jid in chain], dtype=bool)
        self._start = base_T        # before the first element: the base link's frame in its joint's frame
        if not self._reversed.any():
            self._fixed[0] = base_T @ self._fixed[0]
        self.base_moves = base_joint != 0   # the base link is moved by joints (its frame is not fixed to the root)
        self.base_from_root = base_T  # (4, 4): the chain's base frame from pinocchio's world (the URDF root), or
        #                               from its joint's frame where the base moves
        self._tool = model.frames[tip_fid].placement.homogeneous.copy()
        self.param_names = tuple(f"{j}.{f}" for j in names for f in ORIGIN_FIELDS + ("offset",))
        self.param_kinds = tuple(k for t in types for k in ("length",) * 3 + ("angle",) * 3 +
                                 (("angle",) if t == REVOLUTE else ("length",)))
        self.origin_rpy = np.array([o[3:] for o in origins]).reshape(-1, 3)  # (dof, 3) nominal origin rpy, rad
        self.nominal = np.concatenate([np.r_[o[:3], 0.0, 0.0, 0.0, 0.0] for o in origins])

    @staticmethod
    def _tip_frame(model, root, tip_link, where):
        """Frame id and name of the tip: ``tip_link``, or else the one leaf link moved by a joint; ``where``
        (the file and robot) heads the errors."""
        if tip_link is not None:
            if not model.existFrame(tip_link):
                names = [f.name for f in model.frames]
                raise ModelError(f"tip_link: no link or frame named {tip_link!r} in {where}"
                                 f"{did_you_mean(tip_link, names)}")
            return model.getFrameId(tip_link), tip_link
        leaves = moving_leaves(model, root)
        if len(leaves) != 1:
            raise ModelError(f"{where}: the URDF branches, its chains end in the links {leaves}; give tip_link "
                             f"(--tip-link on the command line) to choose one"
                             if leaves else f"{where}: no link is moved by a joint; nothing to model")
        return model.getFrameId(leaves[0]), leaves[0]

    @staticmethod
    def _check_serial(model, chain):
        for jid in chain:
            nq = model.joints[jid].nq
            if nq not in (1, 2):
                raise ModelError(f"urdf: joint {model.names[jid]!r} has {nq} configuration variables; "
                                 f"a serial chain needs 1-DOF joints")

    def beyond_tip(self, joint_names) -> list:
        """The names among ``joint_names`` of the URDF's joints that move links past the tip link (a tip chosen
        short of where the measured point is)."""
        m = self.pin_model
        tip = frame_joint(m.frames[m.getFrameId(self.tip_link)])
        out = []
        for name in joint_names:
            if not m.existJointName(str(name)):
                continue
            j = m.getJointId(str(name))
            while j > 0 and j != tip:
                j = m.parents[j]
            if j == tip and m.getJointId(str(name)) != tip and tip > 0:
                out.append(str(name))
        return out

    def joint_columns(self) -> np.ndarray:
        """(dof,) column of each joint's zero offset ``j.offset``."""
        return 7 * np.arange(self.dof) + 6

    def _run_kernel(self, kernels, q, dx, T, J, jacobian):
        if self._reversed.any():
            return kernels.urdf_either_way(q, self.nominal, dx, self._revolute, self._reversed, self._fixed,
                                           self.origin_rpy, self._axes, self._start, self._tool, T, J, jacobian)
        from .jacobian_writers import writer_for
        return kernels.urdf_chain(q, self.nominal, dx, self._revolute, self._fixed, self.origin_rpy, self._axes,
                                  self._tool, T, J,
                                  jacobian, writer_for(J.nbytes) if jacobian else 0)

    def _fk_and_jacobian_numpy(self, q, dx=None, jacobian=True):
        """The numpy reference implementation of ``fk_and_jacobian``."""
        if self._reversed.any():
            return self._fk_and_jacobian_either_way(q, dx, jacobian)
        q = self.check_joints(q)
        n, dof = q.shape
        dx = self.check_dx(dx, n)
        p = self.nominal if dx is None else self.nominal + dx
        P = np.broadcast_to(p, (n, self.n_params)).T  # (p, n): one row per parameter
        R = np.repeat(np.eye(3)[:, :, None], n, axis=2)
        o = np.zeros((3, n))
        lines = []
        for k in range(dof):
            x, y, z, rx, ry, rz, off = P[7 * k:7 * k + 7]
            F = self._fixed[k]
            RW = _mul(R, F[:3, :3])
            oW = o + _apply(R, F[:3, 3])
            RN = _mul(RW, rpy_to_matrix(self.origin_rpy[k]))
            RX = _mul(RN, axis_angle_matrix(np.array([1.0, 0.0, 0.0]), rx))
            RJ = _mul(_mul(RX, axis_angle_matrix(np.array([0.0, 1.0, 0.0]), ry)),
                      axis_angle_matrix(np.array([0.0, 0.0, 1.0]), rz))
            oJ = oW + _apply(RW, np.stack([x, y, z]))
            w_joint = _apply(RJ, self._axes[k])
            if self.joint_types[k] == REVOLUTE:
                R = _mul(RJ, axis_angle_matrix(self._axes[k], q[:, k] + off))
                o = oJ
            else:
                R = RJ
                o = oJ + w_joint * (q[:, k] + off)
            lines.append(((RW[:, 0], RW[:, 1], RW[:, 2]), (RN[:, 0], RX[:, 1], RJ[:, 2]), w_joint, oJ))
        T, Pend = self._tool_pose(R, o)
        if not jacobian:
            return T, None
        Jt = np.zeros((self.n_params, 6, n))
        for k, (shifts, turns, w_joint, oJ) in enumerate(lines):
            c = 7 * k
            arm = Pend - oJ
            for i, u in enumerate(shifts):
                Jt[c + i, :3] = u
            for i, w in enumerate(turns):
                Jt[c + 3 + i, :3] = cross3(w, arm)
                Jt[c + 3 + i, 3:] = w
            if self.joint_types[k] == REVOLUTE:
                Jt[c + 6, :3] = cross3(w_joint, arm)
                Jt[c + 6, 3:] = w_joint
            else:
                Jt[c + 6, :3] = w_joint
        return T, ErrorJacobian(Jt.transpose(2, 1, 0), self.param_names, self.param_units)

    def _fk_and_jacobian_either_way(self, q, dx=None, jacobian=True):
        """``fk_and_jacobian`` of a chain with joints traversed from child to parent (see the module docstring).

        Each column is the exact derivative of the end pose in one parameter: a shift along a world direction, or
        a turn about a world axis through a point (position rows ``w x (P_end - point)``); a traversed-upward
        joint's element ``M(q + off)^-1 O^-1 F^-1`` turns by ``-rz, -ry, -rx`` about its joint frame's axes and
        shifts by ``-xyz`` along its parent's."""
        q = self.check_joints(q)
        n, dof = q.shape
        dx = self.check_dx(dx, n)
        p = self.nominal if dx is None else self.nominal + dx
        P = np.broadcast_to(p, (n, self.n_params)).T
        start = self._start
        R = np.repeat(start[:3, :3][:, :, None], n, axis=2)
        o = np.repeat(start[:3, 3][:, None], n, axis=1)
        ex, ey, ez = np.eye(3)
        all_cols = []   # per parameter: (sign, world direction (3, n)) or (sign, axis (3, n), point (3, n))
        for k in range(dof):
            x, y, z, rx, ry, rz, off = P[7 * k:7 * k + 7]
            F, axis, rev = self._fixed[k], self._axes[k], self.joint_types[k] == REVOLUTE
            theta = q[:, k] + off
            if not self._reversed[k]:
                RW = _mul(R, F[:3, :3])
                oW = o + _apply(R, F[:3, 3])
                RN = _mul(RW, rpy_to_matrix(self.origin_rpy[k]))
                RX = _mul(RN, axis_angle_matrix(ex, rx))
                RY = _mul(RX, axis_angle_matrix(ey, ry))
                RJ = _mul(RY, axis_angle_matrix(ez, rz))
                oJ = oW + _apply(RW, np.stack([x, y, z]))
                w = _apply(RJ, axis)
                cols = [(1.0, RW[:, 0]), (1.0, RW[:, 1]), (1.0, RW[:, 2]),
                        (1.0, RN[:, 0], oJ), (1.0, RX[:, 1], oJ), (1.0, RJ[:, 2], oJ)]
                cols.append((1.0, w, oJ) if rev else (1.0, w))
                R, o = (_mul(RJ, axis_angle_matrix(axis, theta)), oJ) if rev else (RJ, oJ + w * theta)
            else:
                w = _apply(R, axis)
                joint = (-1.0, w, o) if rev else (-1.0, w)
                if rev:
                    RG = _mul(R, axis_angle_matrix(axis, -theta))
                    oG = o
                else:
                    RG, oG = R, o - w * theta
                R1 = _mul(RG, axis_angle_matrix(ez, -rz))
                R2 = _mul(R1, axis_angle_matrix(ey, -ry))
                R3 = _mul(R2, axis_angle_matrix(ex, -rx))
                R4 = _mul(R3, rpy_to_matrix(self.origin_rpy[k]).T)
                o4 = oG - _apply(R4, np.stack([x, y, z]))
                cols = [(-1.0, R4[:, 0]), (-1.0, R4[:, 1]), (-1.0, R4[:, 2]),
                        (-1.0, R2[:, 0], oG), (-1.0, R1[:, 1], oG), (-1.0, RG[:, 2], oG), joint]
                R = _mul(R4, F[:3, :3])
                o = o4 + _apply(R4, F[:3, 3])
            all_cols += cols
        T, Pend = self._tool_pose(R, o)
        if not jacobian:
            return T, None
        Jt = np.zeros((self.n_params, 6, n))
        for c, col in enumerate(all_cols):
            if len(col) == 2:
                Jt[c, :3] = col[0] * col[1]
            else:
                sign, w, point = col
                Jt[c, :3] = sign * cross3(w, Pend - point)
                Jt[c, 3:] = sign * w
        return T, ErrorJacobian(Jt.transpose(2, 1, 0), self.param_names, self.param_units)

    def _tool_pose(self, R, o):
        """((n, 4, 4) tool poses, (3, n) tool points) of the last joint frames' rotations R (3, 3, n) and origins o
        (3, n)."""
        Pend = o + _apply(R, self._tool[:3, 3])
        T = np.zeros((o.shape[1], 4, 4))
        T[:, :3, :3] = np.moveaxis(_mul(R, self._tool[:3, :3]), 2, 0)
        T[:, :3, 3] = Pend.T
        T[:, 3, 3] = 1.0
        return T, Pend

    def pinocchio_configuration(self, q) -> np.ndarray:
        """pinocchio configuration vector for one chain configuration ``q`` (dof,); other joints neutral."""
        pin = _pin()
        cfg = pin.neutral(self.pin_model)
        for k, jid in enumerate(self.chain_ids):
            iq = self.pin_model.idx_qs[jid]
            if self.pin_model.joints[jid].nq == 2:
                cfg[iq:iq + 2] = (math.cos(q[k]), math.sin(q[k]))
            else:
                cfg[iq] = q[k]
        return cfg


def _path(model, base_joint, tip_joint):
    """(joints traversed from child to parent, from the base link's joint up; joints traversed from parent to child,
    down to the tip's joint): the path between two joints of pinocchio's tree through their common ancestor."""
    def up(j):
        out = []
        while j > 0:
            out.append(j)
            j = model.parents[j]
        return out
    above_base, above_tip = up(base_joint), up(tip_joint)
    common = set(above_base) & set(above_tip)
    upward = [j for j in above_base if j not in common]
    downward = [j for j in above_tip if j not in common]
    return upward, downward[::-1]


def root_link(root):
    """Name of the URDF's root link (the child of no joint), or None when there is not exactly one."""
    children = {j.find("child").get("link") for j in root.findall("joint") if j.find("child") is not None}
    roots = [link.get("name") for link in root.findall("link") if link.get("name") not in children]
    return roots[0] if len(roots) == 1 else None


def leaves(root) -> list:
    """Names of the URDF's leaf links (the parent of no joint), in file order."""
    parents = {j.find("parent").get("link") for j in root.findall("joint") if j.find("parent") is not None}
    return [name for name in (link.get("name") for link in root.findall("link")) if name not in parents]


def moving_leaves(model, root) -> list:
    """Names of the URDF's leaf links (the parent of no joint) that some joint moves, in file order."""
    return [name for name in leaves(root)
            if model.existFrame(name) and frame_joint(model.frames[model.getFrameId(name)]) > 0]


def _parse(text, source):
    """pinocchio model of URDF text; urdfdom's messages on stderr become part of the ModelError instead."""
    pin = _pin()
    with tempfile.TemporaryFile() as captured:
        saved = os.dup(2)
        os.dup2(captured.fileno(), 2)
        try:
            model = pin.buildModelFromXML(text)
            failure = None
        except Exception as exc:  # pinocchio raises plain RuntimeError / ValueError
            failure = exc
        finally:
            os.dup2(saved, 2)
            os.close(saved)
        captured.seek(0)
        said = captured.read().decode(errors="replace").strip()
    if failure is not None:
        lines = [line.strip().removeprefix("Error:").strip() for line in said.splitlines()]
        detail = "; ".join(line for line in lines if line and not line.startswith("at line"))[:500]
        raise ModelError(f"urdf ({source}): not a valid URDF: {failure}" + (f" ({detail})" if detail else ""))
    if said:
        sys.stderr.write(said + "\n")
    return model


def read_urdf(urdf, text_only=False) -> tuple:
    """(text, source) of a URDF given as XML text or as a file path: the one reader of both, so that the
    same content gives the same answer. At most ``MAX_URDF_BYTES``, UTF-8; a leading byte-order mark and
    white space are dropped. ``text_only``: a string that is not XML text is an error, never a path."""
    if isinstance(urdf, (bytes, bytearray)):
        urdf = decode_utf8(bytes(urdf), "urdf", ModelError)
    if isinstance(urdf, str):
        text = urdf.lstrip(_LEADING)
        if text.startswith("<"):
            if len(text) > MAX_URDF_BYTES:
                raise ModelError(f"urdf: {len(text)} characters; a URDF may have at most {MAX_URDF_BYTES} bytes")
            return text, "<string>"
        if text_only:
            raise ModelError(f"urdf: not URDF XML text (never a path): {text.strip()[:40]!r}")
    path = Path(urdf)
    if not path.is_file():
        raise ModelError(f"urdf: {not_a_file(path)}: {path}")
    data = read_bytes(path, ModelError, MAX_URDF_BYTES, "URDF")
    return decode_utf8(data, path, ModelError).lstrip(_LEADING), str(path)


def _xml(text, source):
    """The URDF's XML tree, checked: no entity declarations (expat would expand them, urdfdom would not),
    at most ``MAX_URDF_DEPTH`` elements deep and ``MAX_URDF_JOINTS`` joints, and a tree of links (every
    link the child of at most one joint, no kinematic cycle)."""
    if "<!ENTITY" in text:
        raise ModelError(f"urdf ({source}): entity declarations (<!ENTITY ...>) are not supported in a URDF")
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise ModelError(f"urdf ({source}): not well-formed XML: {exc}") from None
    todo = [(root, 1)]
    while todo:
        elem, depth = todo.pop()
        if depth > MAX_URDF_DEPTH:
            raise ModelError(f"urdf ({source}): elements nested deeper than {MAX_URDF_DEPTH} levels")
        todo.extend((child, depth + 1) for child in elem)
    joints = root.findall("joint")
    if len(joints) > MAX_URDF_JOINTS:
        raise ModelError(f"urdf ({source}): {len(joints)} joints; a URDF may have at most {MAX_URDF_JOINTS}")
    _check_tree(joints, source)
    return root


def _check_tree(joints, source):
    """ModelError for a link that is the child of two joints or for a kinematic cycle (urdfdom would root
    the tree at a link outside the cycle and drop the cycle's links silently)."""
    parent = {}  # child link -> (joint name, parent link)
    for j in joints:
        p, c = j.find("parent"), j.find("child")
        if p is None or c is None:
            continue  # urdfdom names the joint
        child = c.get("link")
        if child == p.get("link"):
            raise ModelError(f"urdf ({source}): joint {j.get('name')!r} has link {child!r} as both its parent and its "
                             f"child")
        if child in parent:
            raise ModelError(f"urdf ({source}): link {child!r} is the child of two joints, {parent[child][0]!r} "
                             f"and {j.get('name')!r}; every link has one parent joint")
        parent[child] = (j.get("name"), p.get("link"))
    state = {}  # link -> 1 on the path being followed, 2 when known to reach a root
    for start in parent:
        path = []
        link = start
        while link in parent and state.get(link) is None:
            state[link] = 1
            path.append(link)
            link = parent[link][1]
        if state.get(link) == 1:  # back on the path: a cycle
            cycle = path[path.index(link):]
            names = [parent[c][0] for c in reversed(cycle)]
            shown = " -> ".join([parent[cycle[-1]][1]] + [c for c in reversed(cycle)])
            raise ModelError(f"urdf ({source}): joints {names} form a kinematic cycle ({shown}); a URDF must be a "
                             f"tree (a reversed parent and child of a joint makes one)")
        for visited in path:
            state[visited] = 2


def _vector(elem, attr, default, field):
    if elem is None or elem.get(attr) is None:
        return np.array(default, dtype=float)
    try:
        v = np.array([float(t) for t in elem.get(attr).split()], dtype=float)
    except ValueError:
        raise ModelError(f"urdf: {field} {attr}={elem.get(attr)!r} is not three numbers") from None
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise ModelError(f"urdf: {field} {attr}={elem.get(attr)!r} is not three finite numbers")
    return v
