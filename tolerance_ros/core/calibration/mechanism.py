"""The calibrated mechanism: a model of the input's own kind with the identified errors folded in exactly
(D-H values, or corrected URDF origins). SI throughout."""
from __future__ import annotations

import copy

import numpy as np

from ..identification import base_matrix
from ..geometry import axis_angle_matrix, rpy_from_matrix, transform
from ..models.base import PRISMATIC, Mechanism, ModelError
from ..models.dh import DHChain
from ..models.urdf import URDFChain


def calibrated_mechanism(model: Mechanism, dx, base=None) -> Mechanism:
    """The model with parameter errors dx (p,) and base correction [x y z, rotation vector] applied.

    D-H: a DHChain with the identified values and ``base := B @ base``. URDF: a copy of the chain whose
    origins (nominal xyz and rpy) are the corrected ones (``corrected_origins``), no errors, zero offsets.
    """
    dx = np.asarray(dx, float)
    B = base_matrix(np.zeros(6) if base is None else np.asarray(base, float))
    if isinstance(model, DHChain):
        p = model.nominal + dx
        n = model.dof
        return DHChain(model.name, p[:n], p[2 * n:3 * n], p[n:2 * n], p[3 * n:], model.joint_types,
                       model.joint_limits, model.joint_names, model.convention, B @ model.base, model.tool,
                       model.direction, model.joint_offset)
    if isinstance(model, URDFChain):
        xyz_rpy, _ = corrected_origins(model, dx, B)
        out = copy.copy(model)
        out.nominal = np.concatenate([np.r_[xyz_rpy[k, :3], 0.0, 0.0, 0.0, 0.0] for k in range(model.dof)])
        out.origin_rpy = xyz_rpy[:, 3:].copy()
        return out
    raise ModelError(f"calibration: robot {model.name!r} is a {type(model).__name__}; calibrated models are "
                     f"built for D-H and URDF chains")


def corrected_origins(model: URDFChain, dx, B=None):
    """((dof, 6) xyz (m) and rpy (rad) of each joint origin of a URDF chain with the parameter errors dx
    folded in exactly, (dof,) mask of the joints that changed).

    Each origin takes its shift, its turns ``Rx(rx) Ry(ry) Rz(rz)`` after its nominal rotation, then its zero
    offset (a turn about, or a shift along, the joint axis); the base correction B (4x4, model base frame)
    is folded into the first origin. An origin whose rotation nothing changes keeps its rpy values as they
    are (no round trip through a matrix); a changed one is written as the rpy of its exact rotation matrix.
    """
    dx = np.asarray(dx, float)
    p = model.nominal + dx
    out = np.empty((model.dof, 6))
    changed = np.zeros(model.dof, bool)
    identity = B is None or np.array_equal(B, np.eye(4))
    for k in range(model.dof):
        x, y, z, rx, ry, rz, off = p[7 * k:7 * k + 7]
        changed[k] = bool(np.any(dx[7 * k:7 * k + 7] != 0)) or (k == 0 and not identity)
        rpy = model.origin_rpy[k]
        if off == 0 and rx == 0 and ry == 0 and rz == 0 and (k > 0 or identity):
            out[k] = (x, y, z, *rpy)
            continue
        O = transform([x, y, z], rpy)
        O[:3, :3] = O[:3, :3] @ axis_angle_matrix((1.0, 0.0, 0.0), rx) @ axis_angle_matrix((0.0, 1.0, 0.0), ry) \
            @ axis_angle_matrix((0.0, 0.0, 1.0), rz)
        axis = model._axes[k]
        if model.joint_types[k] == PRISMATIC:
            O[:3, 3] += O[:3, :3] @ (axis * off)
        else:
            O[:3, :3] = O[:3, :3] @ axis_angle_matrix(axis, off)
        if k == 0 and not identity:
            if getattr(model, "_reversed", np.zeros(1, bool))[0]:
                raise ValueError(f"calibrated URDF: the chain of {model.name!r} starts from {model.base_link!r} "
                                 f"against its first joint's direction; a base correction cannot go into that "
                                 f"joint's origin (use the calibration file, which carries it)")
            F0 = model._fixed[0]
            O = np.linalg.inv(F0) @ B @ F0 @ O
        out[k] = np.r_[O[:3, 3], rpy_from_matrix(O[:3, :3])[0]]
    return out, changed
