"""The correction of a program's targets through a calibration, all targets at once.

The controller keeps its nominal model; the correction changes what it is given. A joint target ``q`` becomes the
joints at which the calibrated robot reaches the pose the nominal robot reaches at ``q`` (``compensate``). A
Cartesian target (a tool pose ``T`` in the base frame) is solved on the nominal robot in its own configuration
(``ArmGeometry.solve``: the controller's solution), the calibrated robot's joints that put the tool at ``T`` are
found from there (``compensate``), and the target written is the nominal robot's tool pose at those joints: run
through the nominal inverse kinematics in the same configuration, it gives the joints that put the as-built robot
at ``T``. Poses are meant in the calibration's base frame (its registration).

Every correction passes the envelope of the trajectory compensator (``calibration.envelope``): the target
reached, away from singularities, within the joint limits, no joint changed by more than ``max_joint_correction``
(a prismatic one by ``max_tool_correction``), a Cartesian target moved by at most ``max_tool_correction``, and its
configuration kept (the signs of ``configuration.flags``). A target outside it is left as written, with the reason.
SI throughout.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..calibration.compensate import compensate
from ..calibration.envelope import Envelope
from ..models.base import Mechanism
from .configuration import ArmGeometry


@dataclass
class Requests:
    """n targets: ``pose`` (n,) True for Cartesian ones; ``T`` (n, 4, 4) their tool poses in the base frame (m);
    ``tool`` (n, 4, 4) the tool frame in the flange frame; ``q`` (n, dof) joint targets (model joints, SI; NaN rows
    for poses); ``want`` (n, 3) configuration signs (0: any); ``windows`` (n, dof, 2) turn windows (rad, NaN: any);
    ``near`` (n, dof) joints a pose's solution is to be nearest (NaN: none)."""

    pose: np.ndarray
    T: np.ndarray
    tool: np.ndarray
    q: np.ndarray
    want: np.ndarray
    windows: np.ndarray
    near: np.ndarray

    @classmethod
    def empty(cls, n: int, dof: int) -> "Requests":
        eye = np.tile(np.eye(4), (n, 1, 1))
        return cls(np.zeros(n, bool), eye.copy(), eye.copy(), np.full((n, dof), np.nan), np.zeros((n, 3), int),
                   np.full((n, dof, 2), np.nan), np.full((n, dof), np.nan))


@dataclass
class Corrections:
    """Per target: ``ok``; ``reason`` (None when ok); ``q_nominal`` the nominal joints (the controller's before),
    ``q`` the corrected joints (the controller's after); ``T`` the corrected tool pose (poses); ``shift`` m of the
    tool point between the target written and the corrected one (poses); ``signs`` the configuration of ``q`` (6-joint
    arms); ``margin`` (n, 3) its distance from a change (m, m, rad)."""

    ok: np.ndarray
    reason: list
    q_nominal: np.ndarray
    q: np.ndarray
    T: np.ndarray
    shift: np.ndarray
    signs: np.ndarray | None = None
    margin: np.ndarray | None = None
    notes: list = field(default_factory=list)

    @property
    def correction(self) -> np.ndarray:
        d = self.q - self.q_nominal
        return np.pi - np.mod(np.pi - d, 2 * np.pi)


def correct(model: Mechanism, calibrated: Mechanism, req: Requests, envelope: Envelope,
            geometry: ArmGeometry | None = None) -> Corrections:
    """Correct every target of ``req`` (see the module docstring); ``calibrated`` is the calibrated chain with the
    model's tool frame (the flange), ``geometry`` the model's ``ArmGeometry`` (needed for Cartesian targets)."""
    n = len(req.pose)
    q_nom = np.where(req.pose[:, None], np.nan, req.q)
    q_cal = q_nom.copy()
    T_new = np.full((n, 4, 4), np.nan)
    shift = np.zeros(n)
    reason = [None] * n
    ok = np.ones(n, bool)
    reached = np.ones(n, bool)
    singular = np.zeros(n, bool)
    limits = np.zeros(n, bool)
    pose = np.flatnonzero(req.pose)
    T_flange = np.einsum("nij,njk->nik", req.T, np.linalg.inv(req.tool))
    if len(pose):
        qn, found, why = geometry.solve(T_flange[pose], req.want[pose], req.windows[pose], req.near[pose])
        for k in np.flatnonzero(~found):
            ok[pose[k]], reason[pose[k]] = False, why[k]
        q_nom[pose[found]] = qn[found]
        idx = pose[found]
        if len(idx):
            comp = compensate(calibrated, model, poses=T_flange[idx], seed=q_nom[idx])
            q_cal[idx] = comp.q
            reached[idx], singular[idx], limits[idx] = comp.reached, comp.near_singularity, comp.out_of_limits
    joints = np.flatnonzero(~req.pose)
    if len(joints):
        comp = compensate(calibrated, model, joints=req.q[joints])
        q_cal[joints] = comp.q
        reached[joints], singular[joints], limits[joints] = comp.reached, comp.near_singularity, comp.out_of_limits
    done = np.flatnonzero(ok)
    signs = margin = None
    if geometry is not None and len(done):
        signs = np.zeros((n, 3), int)
        margin = np.full((n, 3), np.nan)
        signs[done], margin[done] = geometry.flags(q_cal[done])
        before, _ = geometry.flags(q_nom[done])
        changed = np.any(before != signs[done], axis=1) & req.pose[done]
        for k in np.flatnonzero(changed):
            i = done[k]
            names = [nm for nm, a, b in zip(("shoulder", "elbow", "wrist"), before[k], signs[done][k]) if a != b]
            ok[i], reason[i] = False, (f"the correction changes the configuration ({', '.join(names)}): the target is "
                                       f"too near a singularity to be corrected in its own configuration")
    corr = np.pi - np.mod(np.pi - (q_cal - q_nom), 2 * np.pi)
    revolute = np.array([t != "prismatic" for t in model.joint_types])
    corr = np.where(revolute, corr, q_cal - q_nom)
    over = envelope.point_changes(model, np.where(np.isfinite(corr), corr, 0.0))
    if len(pose):
        good = pose[np.isfinite(q_cal[pose]).all(axis=1)]
        if len(good):
            T_new[good] = model.fk(q_cal[good]) @ req.tool[good]
            shift[good] = np.linalg.norm(T_new[good, :3, 3] - req.T[good, :3, 3], axis=1)
    for i in done:
        if not ok[i]:
            continue
        why = [w for w, on in (("out of the calibrated robot's reach", not reached[i]),
                               ("near a singularity", singular[i]),
                               ("out of the joint limits once corrected", limits[i])) if on]
        if i in over:
            why.append(over[i])
        if req.pose[i] and shift[i] > envelope.max_tool:
            why.append(f"the target moves by {shift[i] * 1e3:.4g} mm, more than max_tool_correction "
                       f"{envelope.max_tool * 1e3:.4g} mm")
        if why:
            ok[i], reason[i] = False, "; ".join(why)
    return Corrections(ok, reason, q_nom, q_cal, T_new, shift, signs, margin)
