"""The correction envelope: how far a calibration would move the robot, and whether that is within bounds.

A calibration put in force changes what the robot does: the compensated joints differ from the planned ones
by the calibration's correction. ``correction(cal, model)`` measures it over the calibration's own campaign
postures (its ``training``, at most ``MAX_POSTURES`` of them) and ``SAMPLES`` seeded configurations spread
over the joint range: the largest joint change of the compensation (rad for revolute joints, m for prismatic
ones) and the largest displacement of the tool point between the calibrated and the nominal robot at the
same joints (m). The joint change is taken where the compensation reaches its target and the arm is away
from its singularities (smallest over largest singular value of the joint Jacobian at least ``CONDITIONED``):
near one, a sub-millimetre correction needs large joint changes (57 mrad for 0.36 mm on a UR5, 21 mrad still
where that ratio is 0.01), which the
trajectory compensator flags point by point (``Envelope.point_changes``) instead. ``Envelope`` bounds both; a calibration with a
50 mrad error on one joint exceeds its defaults by far (50 mrad, and 46 mm at the tool of the 7-DOF arm and
of a UR5), a calibration of a robot built within its tolerance budget stays well inside (at most 3 mrad and
0.7 mm on both).
SI throughout.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..models.base import PRISMATIC, Mechanism, ModelError
from .compensate import compensate
from ..models.ik import LENGTH, joint_jacobian

MAX_JOINT_CORRECTION = 0.02   # rad: 20 mrad (1.15 deg) on a revolute joint
MAX_TOOL_CORRECTION = 0.005   # m: 5 mm of the tool point (also the bound of a prismatic joint's change)
SAMPLES = 64                  # configurations over the joint range, beside the campaign's
MAX_POSTURES = 200            # of the calibration's own campaign postures (evenly spaced when it has more)
CONDITIONED = 0.05            # smallest / largest singular value of the joint Jacobian where joint changes count


class CorrectionError(ValueError):
    """A calibration whose correction exceeds the envelope; the message names the joint or the tool and by
    how much."""


@dataclass(frozen=True)
class Envelope:
    """Largest correction a calibration may make: ``max_joint`` rad on a revolute joint, ``max_tool`` m of the
    tool point (and of a prismatic joint)."""

    max_joint: float = MAX_JOINT_CORRECTION
    max_tool: float = MAX_TOOL_CORRECTION

    def __post_init__(self):
        for name, value, top in (("max_joint_correction", self.max_joint, np.pi),
                                 ("max_tool_correction", self.max_tool, 1.0)):
            if not (isinstance(value, (int, float)) and 0.0 < value <= top):
                raise ValueError(f"{name}: expected a value in (0, {top:g}] ({'rad' if top == np.pi else 'm'}), "
                                 f"got {value!r}")

    def bounds(self, model: Mechanism) -> np.ndarray:
        """(dof,) bound of each joint's change: ``max_joint`` rad (revolute) or ``max_tool`` m (prismatic)."""
        return np.array([self.max_tool if t == PRISMATIC else self.max_joint for t in model.joint_types])

    def check(self, cal, model: Mechanism) -> dict:
        """``correction(cal, model)`` with ``ok``, the bounds and ``reason``; raises nothing."""
        c = correction(cal, model)
        bounds = self.bounds(model)
        reasons = []
        if c["tool_m"] > self.max_tool:
            reasons.append(f"it moves the tool point by up to {c['tool_m'] * 1e3:.3g} mm (max_tool_correction "
                           f"{self.max_tool * 1e3:.3g} mm)")
        over = np.flatnonzero(c["joint_max"] > bounds)
        for j in over[:3]:
            unit, scale = ("mm", 1e3) if model.joint_types[j] == PRISMATIC else ("mrad", 1e3)
            limit = "max_tool_correction" if model.joint_types[j] == PRISMATIC else "max_joint_correction"
            reasons.append(f"it changes {model.joint_names[j]} by up to {c['joint_max'][j] * scale:.3g} {unit} "
                           f"({limit} {bounds[j] * scale:.3g} {unit})")
        return {"ok": not reasons, "reason": "; ".join(reasons), "joint_rad": c["joint_rad"], "tool_m": c["tool_m"],
                "joint": c["joint"], "max_joint_rad": self.max_joint, "max_tool_m": self.max_tool,
                "poses": c["poses"]}

    def require(self, cal, model: Mechanism) -> dict:
        """``check``, raising CorrectionError with the reason when the correction is outside the envelope."""
        out = self.check(cal, model)
        if not out["ok"]:
            raise CorrectionError(f"correction outside the envelope: {out['reason']}")
        return out

    def point_changes(self, model: Mechanism, correction) -> dict:
        """{point index: reason} of the points of a compensated trajectory ((m, dof) joint changes) whose change
        of some joint exceeds its bound."""
        d = np.abs(np.asarray(correction, float))
        bounds = self.bounds(model)
        out = {}
        for i in np.flatnonzero((d > bounds).any(axis=1)):
            j = int(np.argmax(d[i] / bounds))
            unit = "m" if model.joint_types[j] == PRISMATIC else "rad"
            out[int(i)] = (f"joint change {d[i, j]:.4g} {unit} on {model.joint_names[j]} exceeds "
                           f"{'max_tool_correction' if unit == 'm' else 'max_joint_correction'} {bounds[j]:.4g} {unit}")
        return out


def envelope_postures(cal, model: Mechanism, samples: int = SAMPLES, seed: int = 0) -> np.ndarray:
    """(n, dof) configurations the correction is measured at: the calibration's campaign postures (at most
    ``MAX_POSTURES``, those within the joint limits) and ``samples`` seeded ones over the joint range (a
    continuous joint's over one turn)."""
    lim = np.array(model.joint_limits, float)
    lim = np.where(np.isfinite(lim), lim, np.array([-np.pi, np.pi]))
    rng = np.random.default_rng(seed)
    q = lim[:, 0] + (lim[:, 1] - lim[:, 0]) * rng.random((int(samples), model.dof))
    postures = (cal.training or {}).get("postures") if isinstance(cal.training, dict) else None
    try:
        own = np.asarray(postures, float) if postures else np.zeros((0, model.dof))
    except (TypeError, ValueError):
        own = np.zeros((0, model.dof))
    if own.ndim == 2 and own.shape[1] == model.dof and len(own):
        own = own[np.all(np.isfinite(own), axis=1) & ~model.out_of_limits(own).any(axis=1)]
        if len(own) > MAX_POSTURES:
            own = own[np.linspace(0, len(own) - 1, MAX_POSTURES).round().astype(int)]
        q = np.vstack([own, q])
    return q


def correction(cal, model: Mechanism, samples: int = SAMPLES, seed: int = 0) -> dict:
    """How far ``cal`` moves ``model`` (see the module docstring): {"joint_rad": largest revolute joint change,
    "joint": its joint's name, "joint_max": (dof,) largest change of each joint (rad or m), "tool_m": largest
    tool-point displacement, "poses": configurations measured, "unreached": those whose joint change is not
    counted (not reached, or near a singularity)}. ModelError for a robot that cannot be compensated."""
    q = envelope_postures(cal, model, samples, seed)
    calibrated, nominal = cal.mechanism(model), cal.nominal_at_tool_point(model)
    tool = np.linalg.norm(calibrated.fk(q)[:, :3, 3] - nominal.fk(q)[:, :3, 3], axis=1)
    if not np.all(np.isfinite(tool)):
        raise ModelError("correction: the calibrated robot's tool point is not finite")
    comp = compensate(calibrated, nominal, joints=q)
    J = joint_jacobian(nominal, q)[1].copy()
    J[:, 3:] *= LENGTH
    sv = np.linalg.svd(J, compute_uv=False)
    solved = comp.reached & ~comp.near_singularity & (sv[:, -1] >= CONDITIONED * sv[:, 0])
    d = np.abs(comp.correction[solved]) if solved.any() else np.zeros((0, model.dof))
    joint_max = d.max(axis=0) if len(d) else np.zeros(model.dof)
    revolute = np.array([t != PRISMATIC for t in model.joint_types])
    j = int(np.argmax(np.where(revolute, joint_max, -1.0))) if revolute.any() else 0
    return {"joint_rad": float(joint_max[j]) if revolute.any() else 0.0, "joint": model.joint_names[j],
            "joint_max": joint_max, "tool_m": float(tool.max()), "poses": int(len(q)),
            "unreached": int((~solved).sum())}
