"""Elastostatics: an arm bends under gravity, each joint by its compliance times its gravity load.

``Load`` says what loads the joints: the URDF's ``<inertial>`` link masses (pinocchio's generalized
gravity, every joint outside the chain at its neutral value), a point mass in the tool frame (a
``payload``), or both. Industrial URDFs rarely carry inertials; without them the default load is a point
mass of 1 kg at the tool frame's origin, a lumped model whose compliances then carry the unknown mass
(rad/(N m) per kg of the real load). ``Load.torques`` gives the generalized force of gravity on each chain
joint, ``g(q) = -dV/dq`` with V the potential energy (N m for a revolute joint, N for a prismatic one; gravity
9.81 m/s^2 along -z of the chain's base frame): the way the joint yields. The deflected robot reaches
``q + c * g(q)`` when its joints read ``q``, a joint that yields to its load having a compliance ``c > 0``;
``DeflectedChain`` is that robot as a Mechanism (its error model is the inner chain's at the deflected joints, the load's own
change with the parameter errors neglected). SI throughout.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np

from ..models.base import Mechanism, ModelError, WrappedMechanism
from ..models.urdf import URDFChain

GRAVITY = 9.81          # m/s^2, along -z of the chain's base frame
DEFAULT_MASS = 1.0      # kg: the lumped point mass at the tool frame when the URDF has no inertials
MAX_MASS = 5000.0       # kg: no robot arm carries more (the heaviest payloads are 2.3 t); beyond, a unit slip
MAX_REACH = 20.0        # m: no payload's centre of mass lies farther from the tool frame
MODELS = ("inertials", "point-mass", "inertials+payload")


def has_inertials(model: Mechanism) -> bool:
    """True when the model is a URDF chain whose links carry mass (so that gravity loads its joints)."""
    if not isinstance(model, URDFChain):
        return False
    return bool(sum(model.pin_model.inertias[j].mass for j in range(model.pin_model.njoints)) > 0)


@dataclass(frozen=True)
class Load:
    """What loads the joints: ``kind`` one of ``MODELS``; ``mass`` (kg) at ``point`` (3,) m in the tool frame
    for a point mass or payload."""

    kind: str
    mass: float = 0.0
    point: tuple = (0.0, 0.0, 0.0)

    def __post_init__(self):
        if self.kind not in MODELS:
            raise ValueError(f"load: expected one of {list(MODELS)}, got {self.kind!r}")
        if self.kind != "inertials" and not (np.isfinite(self.mass) and self.mass > 0):
            raise ValueError(f"load: the point mass must be positive and finite, got {self.mass!r} kg")
        if self.kind != "inertials" and self.mass > MAX_MASS:
            raise ValueError(f"load: a point mass of {self.mass:.6g} kg is beyond {MAX_MASS:g} kg, more than any robot arm "
                             f"carries (a unit slip: g for kg?)")
        if len(self.point) != 3 or not all(np.isfinite(self.point)):
            raise ValueError(f"load: the point must be three finite coordinates (m), got {self.point!r}")
        if float(np.linalg.norm(self.point)) > MAX_REACH:
            raise ValueError(f"load: the point {tuple(self.point)} m lies more than {MAX_REACH:g} m from the tool frame "
                             f"(a unit slip: mm for m?)")

    @classmethod
    def for_model(cls, model: Mechanism, payload=None) -> "Load | None":
        """The load of ``model``: its inertials (plus ``payload`` = (kg, (3,) m in the tool frame) when
        given), the payload alone, or the default lumped point mass; None for a model that is not a URDF chain, or
        one whose base link moves with joints (no gravity direction is known for it)."""
        if not isinstance(model, URDFChain) or getattr(model, "base_moves", False):
            return None   # a chain from a moving link (a foot, a head) has no gravity direction of its own
        if payload is not None:
            mass, point = payload
            return cls("inertials+payload" if has_inertials(model) else "point-mass", float(mass),
                       tuple(float(v) for v in point))
        if has_inertials(model):
            return cls("inertials")
        return cls("point-mass", DEFAULT_MASS, (0.0, 0.0, 0.0))

    @property
    def lumped(self) -> bool:
        """True for the default point mass that stands for a load nobody gave (its compliances carry the mass)."""
        return self.kind == "point-mass" and self.mass == DEFAULT_MASS and self.point == (0.0, 0.0, 0.0)

    def describe(self, tip="the tool frame") -> str:
        """The load model in words."""
        pm = f"a point mass of {self.mass:g} kg at {tuple(round(v, 6) for v in self.point)} m in {tip}"
        if self.kind == "inertials":
            return "the URDF's link masses (<inertial>)"
        if self.kind == "inertials+payload":
            return f"the URDF's link masses (<inertial>) and {pm}"
        if self.lumped:
            return (f"{pm} (the URDF has no <inertial> and no --payload was given: a lumped model, each "
                    f"compliance carries the real load's mass)")
        return pm

    def to_dict(self) -> dict:
        return {"model": self.kind, "mass_kg": self.mass if self.kind != "inertials" else None,
                "point_m": list(self.point) if self.kind != "inertials" else None}

    @classmethod
    def from_dict(cls, doc) -> "Load":
        if not isinstance(doc, dict) or "model" not in doc:
            raise ValueError(f"load: expected {{model, mass_kg, point_m}}, got {doc!r}")
        if doc["model"] == "inertials":
            return cls("inertials")
        return cls(str(doc["model"]), float(doc.get("mass_kg")), tuple(float(v) for v in doc.get("point_m")))

    def torques(self, model: Mechanism, q) -> np.ndarray:
        """(n, dof) the generalized force of gravity on each chain joint at joints q (n, dof), ``-dV/dq``: N m
        (revolute), N (prismatic)."""
        q = model.check_joints(q)
        out = np.zeros((len(q), model.dof))
        if self.kind in ("inertials", "inertials+payload"):
            out += _inertial_torques(model, q)
        if self.kind in ("point-mass", "inertials+payload"):
            out += _point_mass_torques(model, q, self.mass, np.asarray(self.point, float))
        return -out


def _inertial_torques(model: Mechanism, q) -> np.ndarray:
    if not isinstance(model, URDFChain):
        raise ModelError(f"elastostatics: robot {model.name!r} is a {type(model).__name__}; link masses come from "
                         f"a URDF's inertials")
    import pinocchio as pin
    pm = model.pin_model
    data = pm.createData()
    cols = [pm.idx_vs[j] for j in model.chain_ids]
    out = np.empty((len(q), model.dof))
    for i, qi in enumerate(q):
        out[i] = pin.computeGeneralizedGravity(pm, data, model.pinocchio_configuration(qi))[cols]
    return out


def _point_mass_torques(model: Mechanism, q, mass, point) -> np.ndarray:
    """m g dz/dq of a point at ``point`` (tool frame, m): the joint columns of the error model, moved to it."""
    T, EJ = model.fk_and_jacobian(q)
    cols = model.joint_columns()
    arm = np.einsum("nij,j->ni", T[:, :3, :3], point)
    jz = EJ.J[:, 2, cols] + EJ.J[:, 3, cols] * arm[:, 1, None] - EJ.J[:, 4, cols] * arm[:, 0, None]
    return mass * GRAVITY * jz


def gravity_loads(model: Mechanism, q, load: Load | None = None) -> np.ndarray:
    """(n, dof) the generalized force of gravity (``-dV/dq``) on each chain joint at joints q (n, dof) under ``load`` (default: the model's own,
    ``Load.for_model``): N m (revolute), N (prismatic)."""
    load = load or Load.for_model(model)
    if load is None:
        raise ModelError(f"elastostatics: robot {model.name!r} is a {type(model).__name__}; gravity loads need a "
                         f"URDF chain (its base frame gives the direction of gravity)")
    return load.torques(model, q)


class DeflectedChain(WrappedMechanism):
    """A serial chain whose joints deflect by ``compliance * load.torques(q)``: the calibrated robot with its
    elastostatic term. ``compliance`` (dof,) rad/(N m) or m/N; the rest is the inner chain's."""

    def __init__(self, inner: URDFChain, compliance, load: Load | None = None):
        super().__init__(inner)
        self.compliance = np.asarray(compliance, float).reshape(inner.dof)
        self.load = load or Load.for_model(inner)

    def deflected(self, q) -> np.ndarray:
        """(n, dof) joints the deflected robot reaches when its joints read q."""
        q = self.inner.check_joints(q)
        return q + self.load.torques(self.inner, q) * self.compliance

    def fk_and_jacobian(self, q, dx=None, jacobian: bool = True):
        return self.inner.fk_and_jacobian(self.deflected(q), dx, jacobian)

    def with_joint_limits(self, limits) -> "DeflectedChain":
        out = copy.copy(self)
        out.inner = self.inner.with_joint_limits(limits)
        out.joint_limits = out.inner.joint_limits
        return out
