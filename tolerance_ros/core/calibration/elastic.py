"""Elastostatics: an arm bends under its own weight, a joint by its compliance times its gravity load.

``gravity_loads`` gives the generalized gravity force of each chain joint at configurations q (N m for a
revolute joint, N for a prismatic one), computed by pinocchio from the URDF's inertials with every joint
outside the chain at its neutral value. The deflected robot reaches ``q + c * g(q)`` when its joints
read ``q``; ``DeflectedChain`` is that robot as a Mechanism (its error model is the inner chain's at the
deflected joints, the load's own change with the parameter errors neglected). SI throughout.
"""
from __future__ import annotations

import copy

import numpy as np

from ..models.base import Mechanism, ModelError
from ..models.urdf import URDFChain


def has_inertials(model: Mechanism) -> bool:
    """True when the model is a URDF chain whose links carry mass (so that gravity loads its joints)."""
    if not isinstance(model, URDFChain):
        return False
    return bool(sum(model.pin_model.inertias[j].mass for j in range(model.pin_model.njoints)) > 0)


def gravity_loads(model: Mechanism, q) -> np.ndarray:
    """(n, dof) gravity load of each chain joint at joints q (n, dof): N m (revolute), N (prismatic);
    gravity along -z of the URDF's root frame, 9.81 m/s^2."""
    if not isinstance(model, URDFChain):
        raise ModelError(f"elastostatics: robot {model.name!r} is a {type(model).__name__}; gravity loads come "
                         f"from a URDF's inertials")
    import pinocchio as pin
    q = model.check_joints(q)
    pm = model.pin_model
    data = pm.createData()
    cols = [pm.idx_vs[j] for j in model.chain_ids]
    out = np.empty((len(q), model.dof))
    for i, qi in enumerate(q):
        out[i] = pin.computeGeneralizedGravity(pm, data, model.pinocchio_configuration(qi))[cols]
    return out


class DeflectedChain(Mechanism):
    """A serial chain whose joints deflect by ``compliance * gravity_loads(q)``: the calibrated robot with
    its elastostatic term. ``compliance`` (dof,) rad/(N m) or m/N; the rest is the inner chain's."""

    def __init__(self, inner: URDFChain, compliance):
        self.inner = inner
        self.compliance = np.asarray(compliance, float).reshape(inner.dof)
        for attr in ("name", "joint_names", "joint_types", "joint_limits", "param_names", "param_kinds", "nominal"):
            setattr(self, attr, getattr(inner, attr))
        for attr in ("tip_link", "base_link", "source", "config_path"):
            if hasattr(inner, attr):
                setattr(self, attr, getattr(inner, attr))

    def deflected(self, q) -> np.ndarray:
        """(n, dof) joints the deflected robot reaches when its joints read q."""
        q = self.inner.check_joints(q)
        return q + gravity_loads(self.inner, q) * self.compliance

    def fk_and_jacobian(self, q, dx=None, jacobian: bool = True):
        return self.inner.fk_and_jacobian(self.deflected(q), dx, jacobian)

    def joint_columns(self) -> np.ndarray:
        return self.inner.joint_columns()

    @property
    def joint_direction(self) -> np.ndarray:
        return self.inner.joint_direction

    def with_joint_limits(self, limits) -> "DeflectedChain":
        out = copy.copy(self)
        out.inner = self.inner.with_joint_limits(limits)
        out.joint_limits = out.inner.joint_limits
        return out
