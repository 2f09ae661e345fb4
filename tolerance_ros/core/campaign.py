"""Measurement campaigns: named test poses visited for a number of cycles (ISO 9283: P1-P5 x 30).

File format (YAML; ``units`` applies to every value)::

    name: iso_cube_gao
    robot: gao2023_7dof             # optional, checked against the robot it is used with
    units: {length: mm, angle: deg}
    cycles: 30                      # visits per test pose
    dwell: 2.0                      # s at each pose (joint-state publisher)
    order: cycle                    # cycle: P1..Pk, P1..Pk, ...; pose: P1 x cycles, P2 x cycles, ...
    restrictions:                   # optional (``core/workspace.py``): checked when loaded for a robot
      joint_range: [shoulder_lift_joint=-180deg:0deg]
      above_plane: [0,0,1@0m]       # the tool and the moving links stay above z = 0 m
      inside_box: 0.2m:1.2m,-0.6m:0.6m,0m:1m
      collision: true               # no self-collision or link through a plane (URDF collision geometry)
    poses:
      - {name: P1, joints: [0, 30, -45, 0, 60, 0, 0]}          # joint configuration, or
      - {name: PE1, pose: {xyz: [0, 0, 1300], rpy: [0, 0, 0]}}  # an end-effector pose (needs IK)
      # P1 approached along +x (ISO 9283 multi-directional pose accuracy variation): the robot goes to the
      # pre-pose ``via`` (joints, the same units) first, then to the pose; ``of`` names the test pose
      - {name: P1+x, joints: [0, 30, -45, 0, 60, 0, 0], of: P1, approach: +x, via: [2, 31, -44, 0, 59, 1, 0]}

A pose given as ``pose`` is turned into joints by the model's ``inverse_kinematics`` (parallel
mechanisms have it; serial chains take ``joints``).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .geometry import transform
from .ingest import MAX_POSITION_M
from .models.base import ModelError
from .resources import resolve
from .units import UnitError, angle_scale, length_scale, parse_number
from .yamlio import read_yaml

MAX_CYCLES = 100_000  # visits of each test pose: ISO 9283 asks 30; more than this is a slip
_KEYS = {"name", "robot", "units", "cycles", "dwell", "order", "poses", "description", "source", "notes",
         "restrictions"}


class CampaignError(ValueError):
    """An invalid campaign file; the message names the field."""


@dataclass
class TestPose:
    """One test pose: joints (dof,) SI and/or the commanded end-effector pose (4x4, m)."""

    __test__ = False  # not a pytest class

    name: str
    joints: np.ndarray | None = None
    pose: np.ndarray | None = None
    of: str | None = None          # the test pose this visit approaches (ISO 9283 vAP); None: itself
    approach: str | None = None    # how it is approached (a label, e.g. +x)
    via: np.ndarray | None = None  # (dof,) joints of the pre-pose driven to first, SI


@dataclass
class Campaign:
    name: str
    poses: list
    cycles: int = 30
    dwell_s: float = 2.0
    order: str = "cycle"
    robot: str | None = None
    meta: dict = field(default_factory=dict)

    @property
    def names(self) -> list:
        return [p.name for p in self.poses]

    def steps(self, model) -> tuple:
        """Every configuration the robot is driven to, in visiting order (``sequence``), a pose's pre-pose
        (``via``) just before it: (q (m, dof) SI, pose (m,) index into ``poses``, cycle (m,), via (m,) bool)."""
        joints = self.joints_for(model)
        q, pose, cycle, via = [], [], [], []
        for i, c in self.sequence():
            for qk, is_via in ([(self.poses[i].via, True)] if self.poses[i].via is not None else []) + \
                    [(joints[i], False)]:
                q.append(qk)
                pose.append(i)
                cycle.append(c)
                via.append(is_via)
        return np.array(q), np.array(pose), np.array(cycle), np.array(via)

    def approaches(self) -> dict:
        """{test pose: [names of the campaign poses that approach it (``of``)]} for the test poses approached
        in more than one way (ISO 9283 multi-directional pose accuracy variation)."""
        groups = {}
        for p in self.poses:
            if p.of is not None:
                groups.setdefault(p.of, []).append(p.name)
        return {k: v for k, v in groups.items() if len(v) > 1}

    def joints_for(self, model) -> np.ndarray:
        """(k, dof) joints of the test poses for ``model`` (IK for poses given as end-effector poses)."""
        if self.robot and self.robot != model.name:
            raise CampaignError(f"campaign {self.name!r} is for robot {self.robot!r}, not {model.name!r}")
        out = []
        for i, tp in enumerate(self.poses):
            if tp.joints is not None:
                try:
                    out.append(model.check_joints(tp.joints, f"poses[{i}].joints", allow_out_of_limits=False)[0])
                except ModelError as exc:
                    raise CampaignError(f"campaign {self.name!r}: {exc}") from None
            elif hasattr(model, "inverse_kinematics"):
                out.append(np.asarray(model.inverse_kinematics(tp.pose[None]), dtype=float)[0])
            else:
                raise CampaignError(f"poses[{i}] ({tp.name}) is given as a pose, and robot {model.name!r} has no "
                                    f"inverse kinematics: give its joints")
        return np.array(out)

    def sequence(self) -> list:
        """[(pose index, cycle)] in visiting order."""
        k = len(self.poses)
        if self.order == "pose":
            return [(i, c) for i in range(k) for c in range(self.cycles)]
        return [(i, c) for c in range(self.cycles) for i in range(k)]


def campaign_from_dict(data, dof=None, model=None) -> Campaign:
    """Campaign from a parsed file (see the module docstring). With ``model``, the joints must fit it:
    ``dof`` values each, within the joint limits."""
    if not isinstance(data, dict):
        raise CampaignError("campaign: expected a mapping")
    extra = sorted(set(data) - _KEYS)
    if extra:
        raise CampaignError(f"campaign: unknown key(s) {extra}; allowed: {sorted(_KEYS)}")
    if model is not None:
        dof = model.dof
    units = data.get("units") or {}
    if not isinstance(units, dict):
        raise CampaignError(f"units: expected a mapping like {{length: mm, angle: deg}}, got {units!r:.40}")
    bad = sorted(set(units) - {"length", "angle"})
    if bad:
        raise CampaignError(f"units: unknown key(s) {bad}; allowed: angle, length")
    try:
        ls, as_ = length_scale(units.get("length", "m")), angle_scale(units.get("angle", "rad"))
    except UnitError as exc:
        raise CampaignError(str(exc)) from None
    cycles = data.get("cycles", 30)
    if not isinstance(cycles, int) or isinstance(cycles, bool) or cycles < 1:
        raise CampaignError(f"cycles: expected a positive integer, got {cycles!r}")
    if cycles > MAX_CYCLES:
        raise CampaignError(f"cycles: {cycles} visits of each pose; a campaign has at most {MAX_CYCLES}")
    dwell = data.get("dwell", 2.0)
    try:
        dwell = parse_number(dwell, "dwell")
    except UnitError as exc:
        raise CampaignError(str(exc)) from None
    if dwell <= 0:
        raise CampaignError("dwell: must be > 0 s")
    order = data.get("order", "cycle")
    if order not in ("cycle", "pose"):
        raise CampaignError(f"order: expected 'cycle' or 'pose', got {order!r}")
    raw = data.get("poses")
    if not isinstance(raw, list) or not raw:
        raise CampaignError("poses: expected a non-empty list")
    poses, seen = [], set()
    for i, p in enumerate(raw):
        f = f"poses[{i}]"
        if not isinstance(p, dict):
            raise CampaignError(f"{f}: expected a mapping")
        bad = sorted(set(p) - {"name", "joints", "pose", "joint_units", "of", "approach", "via"})
        if bad:
            raise CampaignError(f"{f}: unknown key(s) {bad}")
        name = str(p.get("name", f"P{i + 1}"))
        if name in seen:
            raise CampaignError(f"{f}.name: duplicate test pose name {name!r}")
        seen.add(name)
        if ("joints" in p) == ("pose" in p):
            raise CampaignError(f"{f}: give exactly one of 'joints' or 'pose'")
        tp = TestPose(name)
        for key in ("of", "approach"):
            if key in p and not (isinstance(p[key], (str, int)) and 0 < len(str(p[key])) <= 200):
                raise CampaignError(f"{f}.{key}: expected a name of 1 to 200 characters")
        tp.of = str(p["of"]) if "of" in p else None
        tp.approach = str(p["approach"]) if "approach" in p else None
        try:
            if "via" in p:
                if "joints" not in p:
                    raise CampaignError(f"{f}.via: a pre-pose goes with a pose given as joints")
                tp.via = _joint_list(p["via"], p.get("joint_units"), dof, ls, as_, f"{f}.via")
            if "joints" in p:
                tp.joints = _joint_list(p["joints"], p.get("joint_units"), dof, ls, as_, f"{f}.joints")
            else:
                q = p["pose"]
                if not isinstance(q, dict) or set(q) - {"xyz", "rpy"}:
                    raise CampaignError(f"{f}.pose: expected {{xyz: [...], rpy: [...]}}")
                xyz = [parse_number(v, f"{f}.pose.xyz[{k}]") * ls for k, v in enumerate(q.get("xyz", [0, 0, 0]))]
                rpy = [parse_number(v, f"{f}.pose.rpy[{k}]") * as_ for k, v in enumerate(q.get("rpy", [0, 0, 0]))]
                if len(xyz) != 3 or len(rpy) != 3:
                    raise CampaignError(f"{f}.pose: xyz and rpy need three numbers each")
                far = next((k for k, v in enumerate(xyz) if not abs(v) <= MAX_POSITION_M), None)
                if far is not None:
                    raise CampaignError(f"{f}.pose.xyz[{far}]: {q['xyz'][far]} lies beyond {MAX_POSITION_M:g} m of the "
                                        f"base: no pose of a robot's cell")
                tp.pose = transform(xyz, rpy)
        except UnitError as exc:
            raise CampaignError(str(exc)) from None
        poses.append(tp)
    names = {tp.name: tp for tp in poses}
    for i, tp in enumerate(poses):
        if tp.of is not None and tp.of in names and names[tp.of].of not in (None, tp.of):
            raise CampaignError(f"poses[{i}].of: {tp.of!r} approaches {names[tp.of].of!r} itself; name the test pose")
    if model is not None:
        _within_limits(model, raw, poses, units)
        for i, tp in enumerate(poses):
            if tp.via is not None:
                try:
                    model.check_joints(tp.via, f"poses[{i}].via", allow_out_of_limits=False)
                except ModelError as exc:
                    raise CampaignError(str(exc)) from None
        if data.get("restrictions") is not None:
            _within_restrictions(model, data["restrictions"], poses)
    return Campaign(str(data.get("name", "campaign")), poses, cycles, float(dwell), order, data.get("robot"),
                    {k: data[k] for k in ("description", "source", "notes", "restrictions") if k in data})


def _joint_list(j, kinds, dof, ls, as_, field) -> np.ndarray:
    """(dof,) SI joints of a list in the file's units (``joint_units``: 'angle' or 'length' per joint)."""
    if not isinstance(j, list) or (dof is not None and len(j) != dof):
        raise CampaignError(f"{field}: expected a list of {dof or 'n'} numbers")
    vals = _numbers(j, field)
    if kinds is None:
        return vals * as_  # revolute joints by default
    if not isinstance(kinds, list) or len(kinds) != len(vals) or not all(k in ("angle", "length") for k in kinds):
        raise CampaignError(f"{field.rsplit('.', 1)[0]}.joint_units: expected one of 'angle'/'length' per joint")
    return np.array([v * (ls if k == "length" else as_) for v, k in zip(vals, kinds)])


def _numbers(values, field) -> np.ndarray:
    """(n,) floats of a list of numbers or number strings (``parse_number``); plain finite numbers take a
    fast path."""
    if all(type(v) is float or type(v) is int for v in values):
        try:
            arr = np.array(values, dtype=float)
        except OverflowError:
            arr = None
        if arr is not None and np.isfinite(arr).all():
            return arr
    return np.array([parse_number(v, f"{field}[{k}]") for k, v in enumerate(values)], dtype=float)


def _within_limits(model, raw, poses, units):
    """CampaignError naming the first joint (of the poses given as joints) outside the model's limits, in the
    file's units."""
    given = [i for i, tp in enumerate(poses) if tp.joints is not None]
    if not given:
        return
    q = np.array([poses[i].joints for i in given])
    lo, hi = model.joint_limits[:, 0], model.joint_limits[:, 1]
    wrapped = model.within_turn(q)
    out = np.argwhere((wrapped < lo - 1e-12) | (wrapped > hi + 1e-12))
    if out.size:
        r, k = out[0]
        i = given[r]
        length = (raw[i].get("joint_units") or ["angle"] * model.dof)[k] == "length"
        unit = units.get("length", "m") if length else units.get("angle", "rad")
        scale = length_scale(unit) if length else angle_scale(unit)
        raise CampaignError(f"poses[{i}].joints[{k}] ({model.joint_names[k]}) = {q[r, k] / scale:.6g} {unit} is "
                            f"outside the joint's limits [{lo[k] / scale:.6g}, {hi[k] / scale:.6g}] {unit} on robot "
                            f"{model.name!r}")


def _within_restrictions(model, data, poses):
    """CampaignError listing the poses (given as joints) that break the file's ``restrictions`` (joint
    ranges, tool workspace, collisions: ``core.workspace``)."""
    from .workspace import Workspace, WorkspaceError, listed, restrictions_from_dict
    given = [tp for tp in poses if tp.joints is not None]
    try:
        ws = Workspace(model, restrictions_from_dict(model, data), off="set restrictions.collision to false")
        bad = ws.violations(np.array([tp.joints for tp in given]), [tp.name for tp in given]) if given else []
    except WorkspaceError as exc:
        raise CampaignError(str(exc)) from None
    if bad:
        raise CampaignError(f"{len(bad)} of {len(given)} poses break the restrictions the campaign was planned "
                            f"under ({ws.describe()}): {listed(bad)}")


def load_campaign(spec, model=None) -> Campaign:
    """Campaign from a YAML path or a shipped name (``config/campaigns``); with ``model``, its joints are
    checked against the model's joint count and limits."""
    path = resolve("campaigns", spec)
    data = read_yaml(path, CampaignError)
    robot = data.get("robot") if isinstance(data, dict) else None
    if model is not None and robot and str(robot) != model.name:  # before its poses: they are another robot's
        raise CampaignError(f"{path}: this campaign is for robot {str(robot)[:80]!r}, not {model.name!r}")
    try:
        camp = campaign_from_dict(data, model=model)
    except CampaignError as exc:
        raise CampaignError(f"{path}: {exc}") from None
    return camp
