"""Elastostatics: an arm bends under gravity, each joint by its compliance times its gravity load.

``Load`` says what loads the joints: the URDF's ``<inertial>`` link masses (pinocchio's generalized
gravity, every joint outside the chain at its neutral value), a point mass in the tool frame (a
``payload``), or both; for a chain from the link a robot stands on (a humanoid's sole), the whole robot's
link masses with that link held (``stands_on``; the joints outside the chain as the rows recorded them, where
they did). Industrial URDFs rarely carry inertials; without them the default load is a point
mass of 1 kg at the tool frame's origin, a lumped model whose compliances then carry the unknown mass
(rad/(N m) per kg of the real load). ``Load.torques`` gives the generalized force of gravity on each chain
joint, ``g(q) = -dV/dq`` with V the potential energy (N m for a revolute joint, N for a prismatic one; gravity
9.81 m/s^2 along -z of the chain's base frame): the way the joint yields. The deflected robot reaches
``q + c * g(q)`` when its joints read ``q``, a joint that yields to its load having a compliance ``c > 0``;
``DeflectedChain`` is that robot as a Mechanism (its error model is the inner chain's at the deflected joints,
the load's own change with the parameter errors neglected); ``ElasticJoints`` has the compliances among its
parameters, to fit them. SI throughout.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np

from ..models.base import ErrorJacobian, Mechanism, ModelError, WrappedMechanism
from ..models.urdf import URDFChain

GRAVITY = 9.81          # m/s^2, along -z of the chain's base frame
DEFAULT_MASS = 1.0      # kg: the lumped point mass at the tool frame when the URDF has no inertials
MAX_MASS = 5000.0       # kg: no robot arm carries more (the heaviest payloads are 2.3 t); beyond, a unit slip
MAX_REACH = 20.0        # m: no payload's centre of mass lies farther from the tool frame
STAND_TILT = 1e-2      # rad: a base link stood on has its z axis this close to the root's at the neutral posture
STAND_LOW = 1e-3       # m: ... and no link of the robot more than this below its origin there
STANDING, HELD = "standing", "standing, root held"
MODELS = ("inertials", "point-mass", "inertials+payload", STANDING, HELD)
INERTIAL = ("inertials", STANDING, HELD)   # the kinds whose masses are the URDF's alone


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
        if self.kind not in INERTIAL and not (np.isfinite(self.mass) and self.mass > 0):
            raise ValueError(f"load: the point mass must be positive and finite, got {self.mass!r} kg")
        if self.kind not in INERTIAL and self.mass > MAX_MASS:
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
        given), the payload alone, or the default lumped point mass; for a chain whose base link moves with joints,
        ``STANDING`` where the robot stands on that link (``stands_on``, a URDF with inertials, no payload), else
        None (no gravity direction is known for it); None for a model that is not a URDF chain."""
        if isinstance(model, URDFChain) and getattr(model, "base_moves", False):
            # a chain from a moving link has no gravity direction of its own, unless the robot stands on it
            return cls(STANDING) if payload is None and has_inertials(model) and stands_on(model) else None
        if not isinstance(model, URDFChain):
            return None
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
        if self.kind == STANDING:
            return "the whole robot's link masses (<inertial>), standing on the chain's base link"
        if self.kind == HELD:
            return ("the robot's link masses (<inertial>) but its root link's, which a harness or gantry holds, standing "
                    "on the chain's base link")
        if self.kind == "inertials+payload":
            return f"the URDF's link masses (<inertial>) and {pm}"
        if self.lumped:
            return (f"{pm} (the URDF has no <inertial> and no --payload was given: a lumped model, each "
                    f"compliance carries the real load's mass)")
        return pm

    def to_dict(self) -> dict:
        inertial = self.kind in INERTIAL
        return {"model": self.kind, "mass_kg": None if inertial else self.mass,
                "point_m": None if inertial else list(self.point)}

    @classmethod
    def from_dict(cls, doc) -> "Load":
        if not isinstance(doc, dict) or "model" not in doc:
            raise ValueError(f"load: expected {{model, mass_kg, point_m}}, got {doc!r}")
        if doc["model"] in INERTIAL:
            return cls(doc["model"])
        return cls(str(doc["model"]), float(doc.get("mass_kg")), tuple(float(v) for v in doc.get("point_m")))

    def torques(self, model: Mechanism, q, others=None) -> np.ndarray:
        """(n, dof) the generalized force of gravity on each chain joint at joints q (n, dof), ``-dV/dq``: N m
        (revolute), N (prismatic). ``others``: (names, (n, m) readings) of the robot's joints outside the chain (the
        rest of its posture; the others at their neutral value)."""
        q = model.check_joints(q)
        out = np.zeros((len(q), model.dof))
        if self.kind in (STANDING, HELD):
            return -_standing_torques(model, q, others, root=self.kind == STANDING)
        if self.kind in ("inertials", "inertials+payload"):
            out += _inertial_torques(model, q, others)
        if self.kind in ("point-mass", "inertials+payload"):
            out += _point_mass_torques(model, q, self.mass, np.asarray(self.point, float))
        return -out


def _configurations(model: URDFChain, q, others):
    """Each row's pinocchio configuration: the chain's joints q (n, dof), ``others`` (names, (n, m)) of the rest."""
    pm = model.pin_model
    names, values = others if others is not None else ((), np.zeros((len(q), 0)))
    at = []
    for k, name in enumerate(names):
        jid = pm.getJointId(str(name))
        if jid < pm.njoints and pm.joints[jid].nq == 1:
            at.append((pm.idx_qs[jid], k))
    for i, qi in enumerate(q):
        cfg = model.pinocchio_configuration(qi)
        for iq, k in at:
            cfg[iq] = values[i, k]
        yield cfg


def _inertial_torques(model: Mechanism, q, others=None) -> np.ndarray:
    if not isinstance(model, URDFChain):
        raise ModelError(f"elastostatics: robot {model.name!r} is a {type(model).__name__}; link masses come from "
                         f"a URDF's inertials")
    import pinocchio as pin
    pm = model.pin_model
    data = pm.createData()
    cols = [pm.idx_vs[j] for j in model.chain_ids]
    out = np.empty((len(q), model.dof))
    for i, cfg in enumerate(_configurations(model, q, others)):
        out[i] = pin.computeGeneralizedGravity(pm, data, cfg)[cols]
    return out


def stands_on(model: URDFChain) -> bool:
    """True when the robot stands on the chain's base link (a sole): at the neutral posture of the whole URDF its z
    axis is the root's (within ``STAND_TILT``) and no link lies lower than its origin (``STAND_LOW``), so that
    gravity runs along its -z when it stands flat on a level floor."""
    import pinocchio as pin
    pm = model.pin_model
    data = pm.createData()
    pin.framesForwardKinematics(pm, data, pin.neutral(pm))
    base = data.oMf[pm.getFrameId(model.base_link)]
    if base.rotation[2, 2] < np.cos(STAND_TILT):
        return False
    lowest = min(float(data.oMf[f].translation[2]) for f in range(pm.nframes) if pm.frames[f].type == pin.BODY)
    return bool(base.translation[2] <= lowest + STAND_LOW)


def _standing_torques(model: URDFChain, q, others=None, root=True) -> np.ndarray:
    """(n, dof) generalized gravity (N m, N) of the chain's joints with the base link held, gravity along its -z:
    ``m g dz/dq``, z the height of the whole robot's centre of mass (mass m, the root link's included unless ``root``
    is False: a harness holds it) over the base link (the joints outside the chain as ``others`` gives them, else at
    their neutral value)."""
    import pinocchio as pin
    pm = model.pin_model
    data = pm.createData()
    fid = pm.getFrameId(model.base_link)
    cols = [pm.idx_vs[j] for j in model.chain_ids]
    top = pm.inertias[0]             # the URDF root link's mass (pinocchio's centre of mass leaves it out): fixed in
    top_mass = top.mass if root else 0.0    # pinocchio's world, it moves over the sole
    out = np.empty((len(q), model.dof))
    for i, cfg in enumerate(_configurations(model, q, others)):
        Jc = pin.jacobianCenterOfMass(pm, data, cfg)
        moving = data.mass[0]
        mass = moving + top_mass
        Jc = Jc * (moving / mass)
        com = (moving * data.com[0] + top_mass * top.lever) / mass
        pin.computeJointJacobians(pm, data, cfg)
        pin.updateFramePlacements(pm, data)
        Jb = pin.getFrameJacobian(pm, data, fid, pin.LOCAL_WORLD_ALIGNED)
        base = data.oMf[fid]
        arm = com - base.translation
        dc = Jc[:, cols] - Jb[:3, cols] + np.cross(arm, Jb[3:, cols].T).T   # d(com - base), turned with the base
        out[i] = mass * GRAVITY * (base.rotation[:, 2] @ dc)
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


COMPLIANCE = "compliance"   # the kind of a compliance among a model's parameters (``ElasticJoints``)


class ElasticJoints(WrappedMechanism):
    """A chain whose joints' compliances are parameters, to be fitted with its geometric ones: ``param_names`` the
    inner chain's, then ``<joint>.compliance`` (kind ``COMPLIANCE``, rad/(N m) or m/N, nominally 0); the joints read
    q reach ``q + c * load.torques(q)``. Its error model is the inner chain's at the deflected joints, and a
    compliance's column is its joint's column times the joint's load (the load's own change with the parameters
    neglected, as in ``DeflectedChain``)."""

    def __init__(self, inner: Mechanism, load: Load, recorded=None):
        super().__init__(inner)
        self.load = load
        self._recorded = {}
        self._other_names = ()
        if recorded is not None:
            rq, self._other_names, values = recorded
            rq = inner.check_joints(rq)
            self._recorded = {row.tobytes(): v for row, v in zip(rq, np.asarray(values, float))}
        self.geometric = inner.n_params
        self.param_names = tuple(inner.param_names) + tuple(f"{j}.{COMPLIANCE}" for j in inner.joint_names)
        self.param_kinds = tuple(inner.param_kinds) + (COMPLIANCE,) * inner.dof
        self.nominal = np.r_[np.asarray(inner.nominal, float).reshape(-1), np.zeros(inner.dof)]
        self._loads = (None, None)

    def loads(self, q) -> np.ndarray:
        """(n, dof) the joints' gravity load at joints q (the last one asked kept): the robot's other joints as
        ``recorded`` (q (N, dof), their names, their readings (N, m)) at the same chain joints, else neutral."""
        q = self.inner.check_joints(q)
        key = (q.shape, q.tobytes())
        if self._loads[0] != key:
            others = None
            if self._recorded:
                neutral = np.full(len(self._other_names), np.nan)
                values = np.array([self._recorded.get(row.tobytes(), neutral) for row in q]).reshape(len(q), -1)
                values = np.where(np.isnan(values), 0.0, values)
                others = (self._other_names, values)
            self._loads = (key, self.load.torques(self.inner, q, others))
        return self._loads[1]

    def largest_loads(self, q) -> np.ndarray:
        """(dof,) each joint's largest load (N m, N) in magnitude over the joints q (n, dof)."""
        return np.abs(self.loads(q)).max(axis=0)

    def reach(self, samples: int = 512) -> float:
        return self.inner.reach(samples)

    @property
    def param_units(self) -> tuple:
        return tuple(self.inner.param_units) + tuple("m/N" if t == "prismatic" else "rad/(N m)"
                                                     for t in self.inner.joint_types)

    def compliance_columns(self) -> np.ndarray:
        """(dof,) the column of each joint's compliance."""
        return np.arange(self.geometric, self.geometric + self.inner.dof)

    def fk_and_jacobian(self, q, dx=None, jacobian: bool = True):
        q = self.inner.check_joints(q)
        dx = np.zeros(self.n_params) if dx is None else np.asarray(dx, float).reshape(self.n_params)
        g = self.loads(q)
        T, EJ = self.inner.fk_and_jacobian(q + g * dx[self.geometric:], dx[:self.geometric], jacobian)
        if not jacobian:
            return T, EJ
        J = np.concatenate([EJ.J, EJ.J[:, :, self.inner.joint_columns()] * g[:, None, :]], axis=2)
        return T, ErrorJacobian(J, self.param_names, self.param_units)
