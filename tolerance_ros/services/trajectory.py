"""Logic of the trajectory compensator (ROS-free, duck-typed ``trajectory_msgs/JointTrajectory``).

A trajectory in, the compensated trajectory out: each point's positions are the joints that put the
calibrated robot's tool where the nominal model puts it, its velocities and accelerations mapped so that
the tool moves as planned (``core.calibration.trajectory``). Joint names come in any order; joints the
robot model does not have pass through untouched; time stamps and efforts are kept. A point out of
reach, near a singularity, out of the joint limits, or whose compensation would change a joint by more than
the ``envelope`` allows (``core.calibration.envelope``: ``max_joint_correction`` rad, ``max_tool_correction`` m
for a prismatic joint) is never sent silently: ``on_flag`` 'reject' refuses the whole trajectory, 'nominal'
sends that point as planned; either way the reasons are reported. Without a calibration trajectories pass
through, and the report says so. SI: rad, m, s.
"""
from __future__ import annotations

import numpy as np

from ..core.calibration.trajectory import compensate_trajectory
from ..core.models.base import ModelError
from .compensation import calibrated_pair
from .trajectory_cdr import CdrError, decode, replaced

ON_FLAG = ("reject", "nominal")
MAX_POINTS = 10_000


class TrajectoryError(ValueError):
    """A trajectory that cannot be compensated (wrong joints, shapes, numbers); the message says why."""


class TrajectoryLogic:
    """See the module docstring. ``model`` is the nominal robot; ``calibration`` a Calibration or None."""

    def __init__(self, model, calibration=None, on_flag="reject", match="pose", target=None, envelope=None):
        if on_flag not in ON_FLAG:
            raise ValueError(f"on_flag: expected one of {list(ON_FLAG)}, got {on_flag!r}")
        self.model, self.on_flag, self.match, self.target = model, on_flag, match, target
        self.envelope = envelope
        self.counts = {"received": 0, "compensated": 0, "passed_through": 0, "rejected": 0, "flagged_points": 0,
                       "points_over_envelope": 0}
        self.last = None
        self.set_calibration(calibration)

    def set_calibration(self, calibration, source=""):
        """Compensate with ``calibration`` (None: pass through) from now on."""
        pair = (None, None) if calibration is None else calibrated_pair(calibration, self.model, self.target)
        self.calibration, self.source = calibration, source
        self.calibrated, self.nominal = pair

    def compensate(self, joint_names, positions, velocities=None, accelerations=None) -> dict:
        """{"ok", "positions", "velocities", "accelerations" (m, k) in the given joint order (None where the
        input had none), "flagged" [point indices], "reasons" {point: text}, "message"}; ``ok`` False means
        the trajectory must not be sent. TrajectoryError for malformed input."""
        self.counts["received"] += 1
        names = [str(n) for n in joint_names]
        if len(set(names)) != len(names):
            raise TrajectoryError(f"joint_names: a joint is named twice in {names}")
        missing = [j for j in self.model.joint_names if j not in names]
        if missing:
            raise TrajectoryError(f"joint_names: no {missing} (robot {self.model.name!r} has "
                                  f"{list(self.model.joint_names)})")
        P = _matrix(positions, len(names), "positions")
        if len(P) > MAX_POINTS:
            raise TrajectoryError(f"points: {len(P)} exceed the cap of {MAX_POINTS}")
        V = None if velocities is None else _matrix(velocities, len(names), "velocities", len(P))
        A = None if accelerations is None else _matrix(accelerations, len(names), "accelerations", len(P))
        cols = np.array([names.index(j) for j in self.model.joint_names])
        out = {"ok": True, "positions": P.copy(), "velocities": None if V is None else V.copy(),
               "accelerations": None if A is None else A.copy(), "flagged": [], "reasons": {}}
        if self.calibrated is None:
            self.counts["passed_through"] += 1
            out["message"] = "no calibration: the trajectory is passed through as planned"
            self.last = out
            return out
        try:
            tr = compensate_trajectory(self.calibrated, self.nominal, P[:, cols], None if V is None else V[:, cols],
                                       None if A is None else A[:, cols], self.match)
        except ModelError as exc:
            raise TrajectoryError(str(exc)) from None
        keep = tr.flagged.copy()
        reasons = dict(tr.reasons)
        if self.envelope is not None:
            over = self.envelope.point_changes(self.model, tr.compensation.correction)
            for i, why in over.items():
                keep[i] = True
                reasons[i] = f"{reasons[i]}; {why}" if i in reasons else why
            self.counts["points_over_envelope"] += len(over)
        out["positions"][:, cols] = np.where(keep[:, None], P[:, cols], tr.positions)
        if V is not None:
            out["velocities"][:, cols] = np.where(keep[:, None], V[:, cols], tr.velocities)
        if A is not None:
            out["accelerations"][:, cols] = np.where(keep[:, None], A[:, cols], tr.accelerations)
        out["flagged"] = [int(i) for i in np.flatnonzero(keep)]
        out["reasons"] = {int(i): r for i, r in sorted(reasons.items())}
        out["correction_max"] = float(np.abs(tr.compensation.correction).max()) if len(P) else 0.0
        self.counts["flagged_points"] += len(out["flagged"])
        if out["flagged"] and self.on_flag == "reject":
            out["ok"] = False
            self.counts["rejected"] += 1
            out["message"] = (f"trajectory rejected: {len(out['flagged'])} of {len(P)} point(s) flagged, point "
                              f"{out['flagged'][0]}: {out['reasons'][out['flagged'][0]]}")
        else:
            self.counts["compensated"] += 1
            out["message"] = (f"compensated {len(P)} point(s)" + (f"; {len(out['flagged'])} flagged point(s) sent as "
                                                                 f"planned" if out["flagged"] else ""))
        self.last = out
        return out

    def compensate_msg(self, msg) -> dict:
        """``compensate`` of a duck-typed JointTrajectory: points with empty velocities or accelerations
        keep them empty (all points must agree)."""
        pts = list(msg.points)
        P = [p.positions for p in pts]
        V = _rates([p.velocities for p in pts], "velocities")
        A = _rates([p.accelerations for p in pts], "accelerations")
        return self.compensate(list(msg.joint_names), P, V, A)

    def compensate_raw(self, raw):
        """(serialized compensated JointTrajectory or None when refused, the ``compensate`` result) of a
        serialized JointTrajectory (``trajectory_cdr``); header, effort and time stamps kept."""
        try:
            t = decode(raw)
        except CdrError as exc:
            raise TrajectoryError(f"not a JointTrajectory: {exc}") from None
        k = len(t.joint_names)
        bad = [i for i, p in enumerate(t.positions) if len(p) != k]
        if bad:
            raise TrajectoryError(f"points[{bad[0]}].positions: expected {k} numbers (one per joint name), got "
                                  f"{len(t.positions[bad[0]])}")
        P = _matrix(np.array(t.positions, float) if len(t.positions) else np.zeros((0, k)), k, "positions")
        V = _rates(t.velocities, "velocities")
        A = _rates(t.accelerations, "accelerations")
        res = self.compensate(t.joint_names, P, V, A)
        if not res["ok"]:
            return None, res
        return replaced(raw, t, res["positions"], res["velocities"], res["accelerations"]), res

    def diagnostic(self) -> dict:
        level = 0 if self.calibrated is not None else 1
        msg = (f"compensating with {self.source or 'a calibration'}" if self.calibrated is not None
               else "no calibration: trajectories pass through as planned")
        if self.last is not None and not self.last["ok"]:
            level, msg = 1, self.last["message"]
        return {"level": level, "message": msg, "values": {k: str(v) for k, v in self.counts.items()}}


def _matrix(values, k, field, m=None) -> np.ndarray:
    try:
        arr = np.asarray(values, float)
    except (TypeError, ValueError):
        raise TrajectoryError(f"{field}: expected numbers, {k} per point") from None
    if arr.size == 0 and m is None:
        return arr.reshape(0, k)
    if arr.ndim != 2 or arr.shape[1] != k or (m is not None and arr.shape[0] != m):
        raise TrajectoryError(f"{field}: expected {k} values per point (one per joint name)"
                              + (f" for each of {m} points" if m is not None else "") + f", got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise TrajectoryError(f"{field}: point {int(np.argwhere(~np.isfinite(arr))[0][0])}: not finite")
    return arr


def _rates(rows, field):
    """None when every point leaves the rates empty; else the rows as one array (all must be given)."""
    if isinstance(rows, np.ndarray) and rows.ndim == 2:
        return rows if rows.shape[1] else None
    sizes = {len(r) for r in rows}
    if sizes <= {0}:
        return None
    if 0 in sizes:
        raise TrajectoryError(f"{field}: given for some points and not for others")
    if len(sizes) > 1:
        raise TrajectoryError(f"{field}: points with different numbers of values {sorted(sizes)}")
    return np.array(rows, float)
