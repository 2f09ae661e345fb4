"""Compensation in the services: the calibrated models a node serves (``load_calibrations``, ``calibrated_pair``:
the calibrated robot and the nominal one at the calibration's tool point), and the ``compensate`` command of
the error-model service. The error model and the trajectory compensator call it; it parses with
``requests``, below it.

Request (on ``compute_error_jacobian``, SI)::

    {"id": "c1", "command": "compensate", "robot": "gao2023_7dof",
     "joints": [[...], ...]            # nominal joint configurations (rad, m), or
     "poses": [[[4x4]], ...] | [[x, y, z, qx, qy, qz, qw], ...],   # tool poses in the base frame (m)
     "seed": [...],                    # optional, with poses: start joints, one or one per pose
     "model": "calibrated",            # default; "nominal" solves on the nominal model (inverse kinematics)
     "match": "pose",                  # or "position"
     "allow_out_of_limits": false}     # nominal joints outside their limits are refused unless true

Response: ``{"id", "ok": true, "command": "compensate", "robot", "model", "n", "match", "joint_names",
"joints", "nominal_joints", "correction", "residual_position_m", "residual_orientation_rad",
"out_of_reach", "near_singularity", "out_of_limits", "iterations"}`` (flags as lists of target
indices; see ``core.calibration.compensate``). Errors: ``invalid_request`` (a field, or
``"model": "calibrated"`` for a robot without a loaded calibration), ``unknown_robot``,
``out_of_limits``, ``too_large`` (more targets than ``Limits.max_compensate_joints`` given as joints or
``max_compensate_poses`` given as poses, within ``max_poses``). Pose targets lie within
``ingest.MAX_POSITION_M`` of the base; an unreachable one is flagged in ``out_of_reach`` with its finite
residual.
"""
from __future__ import annotations

import numpy as np

from ..core.targets import AtTarget
from ..core.calibration.calibration_file import (CalibrationError, calibration_from_text, calibration_robot_name,
                                                 load_calibration)
from ..core.calibration.compensate import compensate
from ..core.models.ik import MATCHES
from ..core.ingest import MAX_POSITION_M
from ..core.models.base import ModelError
from .contracts import ContractError, Limits
from .requests import parse_joints, parse_poses

COMPENSATE_ONLY = ("poses", "seed", "match")
JACOBIAN_ONLY = ("outputs", "tolerances", "criteria", "include_jacobian")
MODELS = ("calibrated", "nominal")


def load_calibrations(paths, models: dict) -> dict:
    """{robot: calibrated Mechanism} from calibration files, each checked against the served model of
    its robot (a file for a robot that is not served raises ValueError)."""
    out = {}
    for path in paths:
        robot = calibration_robot_name(path)
        if robot not in models:
            raise ValueError(f"calibration {path}: robot {robot!r} is not served ({sorted(models)})")
        out[robot] = load_calibration(path, models[robot]).mechanism(models[robot])
    return out


def calibration_from_graph(text, models: dict) -> tuple:
    """(robot name, Calibration) of a calibration received as text (``tolerance_calibration``) for one of the
    served ``models``; ValueError (CalibrationError) naming why it does not fit."""
    from ..core.yamlio import loads_yaml
    doc = loads_yaml(text, "tolerance_calibration", CalibrationError) if isinstance(text, str) else None
    robot = doc.get("robot") if isinstance(doc, dict) else None
    if not isinstance(robot, str) or robot not in models:
        raise CalibrationError(f"tolerance_calibration: robot {str(robot)[:80]!r} is not served ({sorted(models)})")
    return robot, calibration_from_text(text, models[robot])


def calibrated_pair(calibration, model, target=None) -> tuple:
    """(calibrated robot, nominal robot), both with their tool at the calibration's tool point (``target`` by
    name, or its first): what a compensation compares."""
    return calibration.mechanism(model, target), calibration.nominal_at_tool_point(model, target)


def nominal_at(calibrated, nominal):
    """The nominal robot with its tool where the calibrated robot's is (a calibration's tool point)."""
    return AtTarget(nominal, calibrated.X, calibrated.target) if isinstance(calibrated, AtTarget) else nominal


def compensate_request(req: dict, robots, calibrations: dict, limits: Limits) -> dict:
    """Response dict of a parsed ``compensate`` request (see the module docstring); raises ContractError.

    robots : the RobotSet of the service; calibrations : {robot name: calibrated Mechanism}."""
    name, nominal = robots.select(req.get("robot"))
    stray = [f for f in JACOBIAN_ONLY if f in req]
    if stray:
        raise ContractError("invalid_request", f"{stray[0]}: not a field of command 'compensate'")
    which = req.get("model", "calibrated")
    if which not in MODELS:
        raise ContractError("invalid_request", f"model: expected one of {list(MODELS)}, got {which[:40]!r}")
    if which == "calibrated" and name not in calibrations:
        raise ContractError("invalid_request", f"model: no calibration is loaded for robot {name!r} (node parameter "
                                               f"'calibration'); ask for \"model\": \"nominal\" to solve on the "
                                               f"nominal model")
    model = calibrations[name] if which == "calibrated" else nominal
    nominal = nominal_at(model, nominal)
    match = req.get("match", "pose")
    if match not in MATCHES:
        raise ContractError("invalid_request", f"match: expected one of {list(MATCHES)}, got {match[:40]!r}")
    if ("joints" in req) == ("poses" in req):
        raise ContractError("invalid_request", "joints, poses: give exactly one (nominal joint configurations or "
                                               "tool poses)")
    allow = req.get("allow_out_of_limits", False)
    try:
        if "joints" in req:
            if "seed" in req:
                raise ContractError("invalid_request", "seed: only with poses (joint targets start from themselves)")
            cap = min(limits.max_poses, limits.max_compensate_joints)
            joints = req["joints"]
            count = len(joints) if isinstance(joints, list) and joints and isinstance(joints[0], list) else 1
            if count > cap:
                raise ContractError("too_large", f"joints: {count} targets exceed the cap of {cap} of command "
                                                 f"'compensate'")
            q = parse_joints(joints, nominal, limits, allow)
            reach = np.abs(nominal.fk(q)[:, :3, 3]).max(axis=1)
            far = np.flatnonzero(~(reach <= MAX_POSITION_M))
            if far.size:
                raise ContractError("invalid_request", f"joints[{far[0]}]: the target's tool point is "
                                                       f"{reach[far[0]]:.3g} m from the base, beyond "
                                                       f"{MAX_POSITION_M:g} m")
            comp = compensate(model, nominal, joints=q, match=match)
        else:
            poses = parse_poses(req["poses"], limits)
            seed = None
            if "seed" in req:
                seed = parse_joints(req["seed"], nominal, limits, True)
                if len(seed) not in (1, len(poses)):
                    raise ContractError("invalid_request", f"seed: expected one configuration or {len(poses)}, "
                                                           f"got {len(seed)}")
            comp = compensate(model, nominal, poses=poses, seed=seed, match=match)
    except ModelError as exc:
        raise ContractError("invalid_request", str(exc)[:300]) from None
    return {"id": req["id"], "ok": True, "command": "compensate", "robot": name, "model": which, **comp.to_dict()}
