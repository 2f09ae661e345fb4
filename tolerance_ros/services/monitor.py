"""Logic of the accuracy monitor (ROS-free, duck-typed messages).

Measured poses are paired with the joint state nearest to their stamp within ``slop`` seconds. A
measurement waits until a joint state at or after its stamp has arrived (so that both neighbours are
known), or until it is ``max_wait`` seconds old; then it is paired or counted as unpaired. Every
measurement is written to the campaign log the moment it arrives, and its pairing (joints, test pose,
verdict) when it is decided, so that a crash loses nothing and ``accuracy.io.read_log`` rebuilds the data.
Nothing is dropped silently: rejected messages and unpaired measurements are counted, logged and
reported.
"""
from __future__ import annotations

import time
from collections import deque
from pathlib import Path

import numpy as np

from ..core.ingest import IngestError, JointOrder, StateBuffer, pose_from_values, stamp_seconds
from ..core.jsonio import dumps_fast
from . import markers
from ..core.accuracy.accumulator import AccuracyAccumulator
from .contracts import check_budget

OK, WARN, ERROR = 0, 1, 2
MAX_FRAME_CHARS = 100  # of a measurement's frame_id in the campaign log


class MonitorLogic:
    """See the module docstring. ``budget`` is a Budget or None; ``campaign`` a Campaign or None."""

    def __init__(self, model, budget=None, campaign=None, slop=0.02, max_wait=1.0, T_tracker_base=None,
                 tool_offset=None, log_path=None, pose_tolerance=1e-3, state_buffer=2000, clock=time.monotonic,
                 name="tolerance_ros: accuracy monitor", recent=20):
        self.model = model
        self.name = name
        self.recent = deque(maxlen=recent)  # the latest paired results, for the markers
        self.generation = 0                 # increases with each new budget
        self._drawn_generation = None
        self.campaign = campaign
        self.slop, self.max_wait = float(slop), float(max_wait)
        self.T_tracker_base, self.tool_offset = T_tracker_base, tool_offset
        self.pose_tolerance = pose_tolerance
        self.clock = clock
        self.states = StateBuffer(model.dof, state_buffer)
        self.joint_order = JointOrder(model.joint_names)
        self.pending = deque()                    # (seq, stamp, T, arrival)
        self.seq = 0
        self.counts = {"received": 0, "paired": 0, "unpaired": 0, "rejected": 0, "joint_states": 0,
                       "joint_states_rejected": 0}
        self.last = None
        self.last_reasons = deque(maxlen=20)
        self.log = None
        if log_path:
            path = Path(log_path)
            path.parent.mkdir(parents=True, exist_ok=True)
            self.log = path.open("a", buffering=1)
            self._write({"event": "start", "robot": model.name, "joint_names": list(model.joint_names),
                         "slop": self.slop, "wall_time": time.time()})
        self.set_budget(budget)

    def set_budget(self, budget):
        """Use a new budget (Budget or None) from now on; statistics restart with it. A budget that does not
        fit the robot (``contracts.check_budget``: its robot, criterion, limits, tolerances) raises
        ContractError when it arrives, and the previous budget stays."""
        delta = check_budget(budget, self.model) if budget is not None else None
        self.acc = AccuracyAccumulator.from_budget(self.model, budget, self.campaign, self.T_tracker_base,
                                                   self.tool_offset, self.pose_tolerance, identify=False)
        self.budget = budget
        self.delta = delta
        self.generation += 1
        self.recent.clear()
        if self.log:
            self._write({"event": "budget", "robot": budget.robot if budget else None,
                         "source": budget.source if budget else None})

    def _write(self, rec):
        """Append one event to the campaign log (strict JSON: non-finite numbers become null)."""
        if self.log:
            self.log.write(dumps_fast(rec) + "\n")

    def close(self):
        if self.log:
            self.log.close()
            self.log = None

    def on_joint_state(self, stamp, names, positions) -> list:
        """Store a joint state (names in any order; extra joints ignored); returns newly decided results."""
        try:
            t = stamp_seconds(stamp)
            q = self.joint_order(names, positions)
        except IngestError as exc:
            self.counts["joint_states_rejected"] += 1
            self.last_reasons.append(f"joint state rejected: {exc}")
            return []
        self.counts["joint_states"] += 1
        self.states.add(t, q)
        return self.resolve()

    def on_pose(self, stamp, frame_id, position, quaternion) -> list:
        """A measured pose (position m, quaternion x y z w); returns the results decided by it."""
        self.counts["received"] += 1
        seq = self.seq
        self.seq += 1
        frame, frame_ok = _frame(frame_id)
        rec = {"event": "measurement", "seq": seq, "stamp": None, "frame": frame,
               "position": _numbers(position), "quaternion": _numbers(quaternion)}
        try:
            rec["stamp"] = t = stamp_seconds(stamp)
            if not frame_ok:
                raise IngestError("frame_id: not UTF-8 text (a lone surrogate); written to the log escaped")
            T = pose_from_values(position, quaternion)
        except IngestError as exc:
            self.counts["rejected"] += 1
            self.last_reasons.append(f"measurement {seq} rejected: {exc}")
            self._write({**rec, "rejected": str(exc)})
            return []
        self._write(rec)
        self.pending.append((seq, t, T, self.clock()))
        return self.resolve()

    def on_pose_msg(self, msg) -> list:
        """Duck-typed geometry_msgs/PoseStamped."""
        p, o = msg.pose.position, msg.pose.orientation
        return self.on_pose(msg.header.stamp, msg.header.frame_id, (p.x, p.y, p.z), (o.x, o.y, o.z, o.w))

    def on_joint_state_msg(self, msg) -> list:
        """Duck-typed sensor_msgs/JointState."""
        return self.on_joint_state(msg.header.stamp, msg.name, msg.position)

    def resolve(self, now=None) -> list:
        """Decide pending measurements whose neighbours are known or whose wait is over."""
        now = self.clock() if now is None else now
        newest = self.states.newest
        decided = []
        keep = deque()
        while self.pending:
            item = self.pending.popleft()
            seq, t, T, arrival = item
            if newest >= t or newest >= t + self.slop or now - arrival >= self.max_wait:
                decided.append(self._pair(seq, t, T))
            else:
                keep.append(item)
        self.pending = keep
        return [d for d in decided if d is not None]

    def _pair(self, seq, t, T):
        found = self.states.nearest(t, self.slop)
        if found is None:
            self.counts["unpaired"] += 1
            reason = (f"no joint state within {self.slop} s of stamp {t:.6f}"
                      + (f" (nearest {self.states.distance(t):.4f} s away)" if len(self.states) else " (none received)"))
            self.last_reasons.append(f"measurement {seq} unpaired: {reason}")
            self._write({"event": "unpaired", "seq": seq, "reason": reason})
            return None
        joint_stamp, q = found
        r = self.acc.add(T[None], q[None])
        self.counts["paired"] += 1
        res = {"seq": seq, "stamp": t, "joints": q, "label": str(r["label"][0]), "verdict": str(r["verdict"][0]),
               "position_error": float(r["position_error"][0]), "orientation_error": float(r["orientation_error"][0]),
               "bound": float(r["bound"][0]), "margin": float(r["margin"][0]), "dp": r["dp"][0]}
        self.last = res
        self.recent.append(res)
        self._write({"event": "paired", "seq": seq, "joint_stamp": joint_stamp, "joint_names": list(self.model.joint_names),
                     "joints": [float(v) for v in q], "pose": res["label"] or None, "verdict": res["verdict"],
                     "position_error": res["position_error"],
                     "bound": res["bound"] if np.isfinite(res["bound"]) else None})
        return res

    def diagnostic(self) -> dict:
        """DiagnosticStatus content: level (0 OK, 1 WARN, 2 ERROR), name, message, key values (strings)."""
        c, v = self.counts, self.acc.counts
        level, msg = OK, "measurements within the predicted bound"
        if self.budget is None:
            level, msg = WARN, "no tolerance budget yet"
        if c["unpaired"] or c["rejected"]:
            level, msg = WARN, f"{c['unpaired']} unpaired and {c['rejected']} rejected measurement(s)"
        if v.get("over bound"):
            level, msg = WARN, f"{v['over bound']} measurement(s) above the predicted bound"
        if v.get("over limit"):
            level, msg = ERROR, f"{v['over limit']} measurement(s) above the design limit"
        if c["received"] == 0:
            msg = "waiting for measured poses" if level == OK else msg
        pe = self.acc.position.to_dict()
        values = {"received": c["received"], "paired": c["paired"], "unpaired": c["unpaired"],
                  "rejected": c["rejected"], "pending": len(self.pending), "within": v.get("within", 0),
                  "over_bound": v.get("over bound", 0), "over_limit": v.get("over limit", 0),
                  "position_error_mean_m": pe.get("mean"), "position_error_max_m": pe.get("max"),
                  "last_position_error_m": self.last["position_error"] if self.last else None,
                  "last_bound_m": self.last["bound"] if self.last else None,
                  "budget": (self.budget.source or self.budget.robot) if self.budget else "none"}
        return {"level": level, "name": self.name, "message": msg,
                "hardware_id": self.model.name, "values": {k: _fmt(val) for k, val in values.items()}}

    def markers(self, scale: float = 100.0, slots: int = 20) -> list:
        """RViz markers (``services.markers`` dicts): DELETE_ALL after a budget change, the predicted bound
        at the latest joint state (with a budget), and the recent measurements."""
        out = []
        if self._drawn_generation != self.generation:
            out.append(markers.delete_all())
            self._drawn_generation = self.generation
        if self.delta is not None and len(self.states):
            out += markers.bound_markers(self.model, self.states.q[len(self.states) - 1], self.delta, scale)
        out += markers.measurement_markers(self.model, list(self.recent), scale, slots)
        return out

    def report(self) -> dict:
        """JSON-ready report: counts, the accumulator summary (per test pose ISO 9283), the last result."""
        last = None if self.last is None else {k: v for k, v in self.last.items() if k != "dp"}
        return {"robot": self.model.name, "counts": dict(self.counts), "pending": len(self.pending),
                "recent_issues": list(self.last_reasons), "summary": self.acc.summary(), "last": last,
                "budget": None if self.budget is None else {"source": self.budget.source,
                                                             "criterion": self.budget.criterion,
                                                             "limit_position_m": self.budget.limit_position}}


def _frame(frame_id) -> tuple:
    """(text for the log, whether it is valid UTF-8): the frame_id cut to ``MAX_FRAME_CHARS``, lone surrogates
    escaped."""
    text = str(frame_id)[:MAX_FRAME_CHARS]
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        return text.encode("utf-8", "backslashreplace").decode("utf-8"), False
    return text, True


def _numbers(values):
    """The values as a plain list of floats for the log (None where not finite), or None if not numbers."""
    try:
        arr = np.asarray(values, dtype=float).reshape(-1)
    except (TypeError, ValueError, OverflowError):
        return None
    return [float(v) if np.isfinite(v) else None for v in arr]


def _fmt(v):
    if v is None:
        return "-"
    if isinstance(v, float):
        return f"{v:.6g}"
    return str(v)
