"""Logic of the ``compensate`` command of the error-model service, the choice of the nominal or calibrated
model for its Jacobian requests, and the calibrations it serves.

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

from ..core.accuracy.targets import AtTarget
from ..core.calibration.compensate import MATCHES, compensate
from ..core.calibration.writers import calibration_robot_name, load_calibration
from ..core.geometry import quat_to_matrices
from ..core.ingest import MAX_POSITION_M
from ..core.models.base import ModelError
from .contracts import ContractError, Limits

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


def jacobian_model(req: dict, robots, calibrations: dict):
    """(robot name, model) of a ``compute_error_jacobian`` request: the nominal model, or with
    ``"model": "calibrated"`` the robot's loaded calibration; refuses another command, the fields of
    ``compensate`` and a request without ``joints``."""
    command = req.get("command", "compute_error_jacobian")
    if command != "compute_error_jacobian":
        raise ContractError("invalid_request", f"command: expected 'compute_error_jacobian' or 'compensate', "
                                               f"got {command[:40]!r}")
    stray = [f for f in COMPENSATE_ONLY if f in req]
    if stray:
        raise ContractError("invalid_request", f"{stray[0]}: only with command 'compensate'")
    if "joints" not in req:
        raise ContractError("invalid_request", "joints: required")
    name, model = robots.select(req.get("robot"))
    which = req.get("model", "nominal")
    if which not in MODELS:
        raise ContractError("invalid_request", f"model: expected one of {list(MODELS)}, got {which[:40]!r}")
    if which == "calibrated":
        if name not in calibrations:
            raise ContractError("invalid_request", f"model: no calibration is loaded for robot {name!r} (node "
                                                   f"parameter 'calibration')")
        model = calibrations[name]
    return name, model


def parse_poses(value, limits: Limits) -> np.ndarray:
    """(n, 4, 4) tool poses from a list of 4x4 matrices or of [x, y, z, qx, qy, qz, qw] (m)."""
    if not isinstance(value, list) or not value:
        raise ContractError("invalid_request", "poses: expected a non-empty list of 4x4 matrices or of "
                                               "[x, y, z, qx, qy, qz, qw]")
    cap = min(limits.max_poses, limits.max_compensate_poses)
    if len(value) > cap:
        raise ContractError("too_large", f"poses: {len(value)} targets exceed the cap of {cap} (each tool pose is "
                                         f"solved from 9 starts first; give joint targets for more)")
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise ContractError("invalid_request", "poses: every pose must be numbers of one shape, 4x4 or 7") from None
    if not np.all(np.isfinite(arr)):
        raise ContractError("invalid_request", f"poses[{int(np.argwhere(~np.isfinite(arr))[0][0])}]: not finite")
    position = arr[:, :3] if arr.ndim == 2 else arr[:, :3, 3] if arr.ndim == 3 and arr.shape[1:] == (4, 4) else None
    if position is not None:
        far = np.flatnonzero(np.abs(position).max(axis=1) > MAX_POSITION_M)
        if far.size:
            raise ContractError("invalid_request", f"poses[{far[0]}]: a target {np.abs(position[far[0]]).max():.3g} m "
                                                   f"from the base is beyond {MAX_POSITION_M:g} m")
    if arr.ndim == 2 and arr.shape[1] == 7:
        try:
            R = quat_to_matrices(arr[:, 3:])
        except ValueError:
            raise ContractError("invalid_request", "poses: a quaternion has zero norm") from None
        T = np.tile(np.eye(4), (len(arr), 1, 1))
        T[:, :3, :3], T[:, :3, 3] = R, arr[:, :3]
        return T
    if arr.ndim != 3 or arr.shape[1:] != (4, 4):
        raise ContractError("invalid_request", f"poses: expected (n, 4, 4) matrices or (n, 7) position + "
                                               f"quaternion, got shape {list(arr.shape)}")
    R = arr[:, :3, :3]
    bad = np.flatnonzero((np.abs(np.einsum("nij,nkj->nik", R, R) - np.eye(3)).max(axis=(1, 2)) > 1e-6)
                         | (np.linalg.det(R) < 0) | (np.abs(arr[:, 3] - [0, 0, 0, 1]).max(axis=1) > 0))
    if bad.size:
        raise ContractError("invalid_request", f"poses[{bad[0]}]: not a rigid transform (rotation part not "
                                               f"orthonormal, or last row not [0, 0, 0, 1])")
    return arr


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
    if isinstance(model, AtTarget):  # the calibration's tool point: the nominal pose is taken there too
        nominal = AtTarget(nominal, model.X, model.target)
    match = req.get("match", "pose")
    if match not in MATCHES:
        raise ContractError("invalid_request", f"match: expected one of {list(MATCHES)}, got {match[:40]!r}")
    if ("joints" in req) == ("poses" in req):
        raise ContractError("invalid_request", "joints, poses: give exactly one (nominal joint configurations or "
                                               "tool poses)")
    from .error_model import parse_joints  # here: error_model imports this module
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
