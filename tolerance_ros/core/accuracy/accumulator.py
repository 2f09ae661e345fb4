"""Streaming evaluation of measurements: one code path for the live accuracy monitor and offline reports.

``AccuracyAccumulator.add`` takes a batch of measurements (tracker-frame poses or points with the joint
readings at their stamps and the target each one measured), expresses them in the base frame through the
registration, compares them with the nominal model at their target (its point on the tool, not the
flange) and with the budget's predicted bound there, and updates fixed-size aggregates: verdict
counts, error statistics, per-test-pose samples (bounded by the campaign's cycles) and the normal
equations of a linearised identification. Memory does not grow with the number of measurements.
"""
from __future__ import annotations

import numpy as np

from ..errors import criterion_bound
from ..conformity import DEFAULT_RULE, DecisionRule
from ..identification import base_jacobian, identify_from_normal_equations
from .iso9283 import pose_characteristics
from .registration import to_base_frame
from ..targets import Targets, shift_jacobian
from .verdicts import EXCEEDED, VERDICTS, budget_check, pose_errors


class _Running:
    """Count, mean, M2 (Welford) and max of a scalar stream."""

    def __init__(self):
        self.n, self.mean, self.m2, self.max = 0, 0.0, 0.0, -np.inf

    def update(self, x):
        x = np.asarray(x, float).reshape(-1)
        if x.size == 0:
            return
        n_b = x.size
        if n_b == 1:  # one value (the live monitor): no array arithmetic
            mean_b, m2_b, top = float(x[0]), 0.0, float(x[0])
        else:
            mean_b = float(x.sum()) / n_b
            d_b = x - mean_b
            m2_b, top = float(d_b @ d_b), float(x.max())
        n = self.n + n_b
        d = mean_b - self.mean
        self.mean += d * n_b / n
        self.m2 += m2_b + d * d * self.n * n_b / n
        self.n = n
        self.max = max(self.max, top)

    def to_dict(self):
        if not self.n:
            return {"n": 0}
        return {"n": self.n, "mean": self.mean, "std": float(np.sqrt(self.m2 / self.n)), "max": self.max}


class AccuracyAccumulator:
    """Accumulates accuracy statistics of a robot against its nominal model and tolerance budget.

    model : Mechanism.  delta : (p,) budget tolerances (SI) or None.  criterion : 'paper' |
    'worst-case' | 'rss' for the predicted bound.  limit / limit_orientation : design limits (m, rad).
    T_tracker_base : 4x4 registration (identity: measurements already in the base frame).
    targets : the measured targets' frames in the tool frame (``targets.Targets``; default: the tool
    frame itself); every error and bound is taken at a measurement's target.  orientation : whether the
    measurements carry orientation (False for points: no orientation figure is computed or reported).
    campaign_joints : (k, dof) test-pose joints with ``campaign_names``; a measurement belongs to a test
    pose when all its joints are within ``pose_tolerance`` (rad or m) of it (or when labelled).
    """

    def __init__(self, model, delta=None, criterion="paper", limit=None, limit_orientation=None,
                 T_tracker_base=None, targets: Targets | None = None, campaign_joints=None, campaign_names=(),
                 cycles=30, pose_tolerance=1e-3, k_sigma=3.0, identify=True, orientation=True):
        self.model = model
        self.delta = None if delta is None else np.asarray(delta, float)
        self.criterion = criterion
        self.k_sigma = k_sigma
        self.limit, self.limit_orientation = limit, limit_orientation
        self.T_base_tracker = np.linalg.inv(np.eye(4) if T_tracker_base is None else np.asarray(T_tracker_base, float))
        self.targets = targets if targets is not None else Targets.at_tool(frames=orientation)
        self._offset = bool(np.any(self.targets.X != np.eye(4)))
        self.orientation = bool(orientation)
        self.campaign_joints = None if campaign_joints is None else np.atleast_2d(np.asarray(campaign_joints, float))
        self.campaign_names = list(campaign_names)
        self.max_per_pose = 10 * cycles
        self.pose_tolerance = pose_tolerance
        keys = [self._key(n, k) for n in self.campaign_names for k in range(len(self.targets))]
        self.per_pose = {key: [] for key in keys}
        self.per_pose_dropped = dict.fromkeys(keys, 0)
        self.position = _Running()
        self.orientation_stats = _Running()
        self.margin = _Running()
        self.counts = dict.fromkeys(VERDICTS, 0)
        self.exceeded = dict.fromkeys(EXCEEDED, 0)
        self.worst = None
        self.n = 0
        p = model.n_params + 6
        self.identify = identify
        self.JtJ = np.zeros((p, p))
        self.Jtr = np.zeros(p)
        self.rtr = 0.0
        self.rows = 0

    @classmethod
    def from_budget(cls, model, budget=None, campaign=None, T_tracker_base=None, targets=None,
                    pose_tolerance=1e-3, identify=True, orientation=True) -> "AccuracyAccumulator":
        """Accumulator checking against a Budget (or none) with a Campaign's test poses (or none)."""
        return cls(model, budget.vector_for(model) if budget is not None else None,
                   budget.criterion if budget is not None else "paper",
                   budget.limit_position if budget is not None else None,
                   budget.limit_orientation if budget is not None and orientation else None, T_tracker_base,
                   targets, campaign.joints_for(model) if campaign is not None else None,
                   campaign.names if campaign is not None else (), campaign.cycles if campaign is not None else 30,
                   pose_tolerance, identify=identify, orientation=orientation)

    def _key(self, name, k) -> str:
        """The test-pose key of a pose name and target index: the name, or ``name@target`` with targets."""
        target = self.targets.names[k]
        return f"{name}@{target}" if len(self.targets) > 1 or target else str(name)

    def to_base(self, T_tracker) -> np.ndarray:
        """(n, 4, 4) tracker-frame readings in the base frame."""
        return to_base_frame(T_tracker, self.T_base_tracker)

    def nominal(self, q, target=None, jacobian=True):
        """(T (n, 4, 4) nominal target frames, J (n, 6, p) at the targets or None) at joints q."""
        T_tool, EJ = self.model.fk_and_jacobian(q, jacobian=jacobian)
        if not self._offset:
            return T_tool, (EJ.J if jacobian else None)
        idx = self.targets.rows(target if target is not None else [], len(T_tool))
        T = self.targets.poses(T_tool, idx)
        return T, (shift_jacobian(EJ.J, self.targets.arms(T_tool, idx)) if jacobian else None)

    def label(self, q) -> np.ndarray:
        """(n,) campaign test-pose name of each configuration, or '' when none is close enough."""
        q = np.atleast_2d(q)
        if self.campaign_joints is None or not len(self.campaign_joints):
            return np.array([""] * len(q), dtype=object)
        d = np.abs(q[:, None, :] - self.campaign_joints[None]).max(axis=2)
        k = np.argmin(d, axis=1)
        return np.where(d[np.arange(len(q)), k] <= self.pose_tolerance, np.array(self.campaign_names, dtype=object)[k], "")

    def add(self, T_tracker, q, labels=None, target=None) -> dict:
        """Evaluate a batch: (n, 4, 4) tracker readings, (n, dof) joints and (n,) target indices (None:
        the one target); returns per-measurement arrays."""
        q = self.model.check_joints(q)
        T_meas = self.to_base(np.asarray(T_tracker, float).reshape(-1, 4, 4))
        idx = self.targets.rows(target if target is not None else [], len(q))
        T_nom, J = self.nominal(q, idx)
        dp = T_meas[:, :3, 3] - T_nom[:, :3, 3]
        e_pos = np.sqrt(np.einsum("ni,ni->n", dp, dp))
        dphi = e_ori = None
        if self.orientation:
            _, dphi = pose_errors(T_nom, T_meas)
            e_ori = np.sqrt(np.einsum("ni,ni->n", dphi, dphi))
        b_pos = b_ori = None
        if self.delta is not None:
            b_pos = criterion_bound(J[:, :3], self.delta, self.criterion, self.k_sigma)
            if self.orientation:
                b_ori = criterion_bound(J[:, 3:], self.delta, self.criterion, self.k_sigma)
        check = budget_check(e_pos, b_pos, self.limit, e_ori, b_ori if self.limit_orientation else None,
                             self.limit_orientation)
        labels = self.label(q) if labels is None else np.asarray(labels, dtype=object)
        self.n += len(q)
        self.position.update(e_pos)
        if e_ori is not None:
            self.orientation_stats.update(e_ori)
        if self.delta is not None:
            self.margin.update(check["margin"])
        for v in check["verdict"]:
            self.counts[v] += 1
        for what, count in zip(EXCEEDED, check["over"].sum(axis=0)):
            self.exceeded[what] += int(count)
        k = int(np.argmax(e_pos))
        if self.worst is None or e_pos[k] > self.worst["error"]:
            self.worst = {"error": float(e_pos[k]), "joints": q[k].tolist(), "label": str(labels[k]),
                          "target": self.targets.names[idx[k]]}
        if self.per_pose:
            for i, name in enumerate(labels):
                key = self._key(name, idx[i]) if name else None
                if key in self.per_pose:
                    if len(self.per_pose[key]) < self.max_per_pose:
                        self.per_pose[key].append(T_meas[i])
                    else:
                        self.per_pose_dropped[key] += 1
        if self.identify:
            self._normal_equations(T_nom, J, dp)
        return {"position_error": e_pos, "orientation_error": e_ori, "dp": dp, "dphi": dphi, "label": labels,
                "target": idx, "nominal": T_nom[:, :3, 3], **check}

    def _normal_equations(self, T_nom, J, dp):
        Jb = base_jacobian(T_nom[:, :3, 3])[:, :3]
        A = np.concatenate([J[:, :3], Jb], axis=2).reshape(-1, self.JtJ.shape[0])
        r = dp.reshape(-1)
        self.JtJ += A.T @ A
        self.Jtr += A.T @ r
        self.rtr += float(r @ r)
        self.rows += len(r)

    def commanded(self) -> dict:
        """Nominal frames of the campaign test poses at each target, by test-pose key."""
        if self.campaign_joints is None:
            return {}
        T_tool = self.model.fk(self.campaign_joints)
        out = {}
        for k in range(len(self.targets)):
            T = self.targets.poses(T_tool, np.full(len(T_tool), k))
            out.update({self._key(n, k): T[i] for i, n in enumerate(self.campaign_names)})
        return out

    def summary(self, sigma_position=1e-5, rule: DecisionRule = DEFAULT_RULE) -> dict:
        """The figures so far (SI); the linearised identification's parts decided by ``rule``."""
        out = {"measurements": self.n, "verdicts": dict(self.counts), "exceeded": dict(self.exceeded),
               "position_error_m": self.position.to_dict(),
               "orientation_error_rad": self.orientation_stats.to_dict() if self.orientation else None,
               "margin_m": self.margin.to_dict() if self.delta is not None else None, "worst": self.worst}
        if not self.orientation:
            out["exceeded"] = {k: v for k, v in out["exceeded"].items() if not k.startswith("orientation")}
        cmd = self.commanded()
        out["test_poses"] = {}
        for name, samples in self.per_pose.items():
            entry = {"n": len(samples), "beyond_storage": self.per_pose_dropped[name]}
            if len(samples) >= 2:
                entry.update(pose_characteristics(cmd[name], np.array(samples), self.orientation).to_dict())
            out["test_poses"][name] = entry
        if self.identify and self.rows:
            out["identification"] = self.linear_identification(sigma_position, rule).to_dict()
        return out

    def linear_identification(self, sigma_position=1e-5, rule: DecisionRule = DEFAULT_RULE):
        """Identification from the accumulated normal equations (see ``identification``)."""
        return identify_from_normal_equations(self.model, self.JtJ, self.Jtr, self.rtr, self.rows, self.delta,
                                              sigma_position, rule=rule)
