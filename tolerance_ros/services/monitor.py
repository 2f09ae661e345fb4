"""Logic of the accuracy monitor (ROS-free, duck-typed messages).

Measured poses are paired with the joint state nearest to their stamp within ``slop`` seconds. A
measurement waits until a joint state at or after its stamp has arrived (so that both neighbours are
known), or until it is ``max_wait`` seconds old; then it is paired or counted as unpaired. Every
measurement is written to the campaign log the moment it arrives, and its pairing (joints, test pose,
verdict) when it is decided, so that a crash loses nothing and ``accuracy.io.read_log`` rebuilds the data.
Nothing is dropped silently: rejected messages and unpaired measurements are counted, logged and
reported, and what never arrived is seen in the stamps: each stream's gaps (``ingest.StampGaps``: the messages a
late reader's queue or a network lost, or a publisher never sent) are a warning on /diagnostics and in the report.
Each test pose's drift (ISO 9283 dAP: its mean error over each window of ``drift_window`` s against its first
window's, ``iso9283.DriftTracker``) is in the report, and a warning on /diagnostics beyond ``drift_limit`` m.
"""
from __future__ import annotations

import json
import re
import time
from collections import OrderedDict, deque
from pathlib import Path

import numpy as np

from ..core.geometry import matrices_to_quat
from ..core.ingest import IngestError, JointOrder, StampGaps, StateBuffer, pose_from_values, stamp_seconds
from ..core.jsonio import dumps_fast
from . import markers
from ..core.accuracy.accumulator import AccuracyAccumulator
from ..core.accuracy.checks import StreamCheck
from ..core.accuracy.iso9283 import DriftTracker
from ..core.targets import Targets
from .contracts import MAX_ID_CHARS, check_budget, valid_id
from .guards import summary

OK, WARN, ERROR = 0, 1, 2
MIN_GAP_S = 0.5
"""The shortest gap in a stream's stamps the monitor warns of: a publisher's timer late by a tenth of a second
(a node starting beside it) stamps a gap of a few periods though nothing was lost; the static measurements
this monitor judges lose nothing to it. (The path monitor holds every gap of 5 periods against a motion.)"""
MAX_FRAME_CHARS = 100  # of a measurement's frame_id in the campaign log
OTHERS_KEPT = 64       # joint states whose joints outside the chain are kept for the contacts to latch
MAX_OTHER_JOINTS = 256  # of those joints, a state's first; their names printable, at most 100 characters


class MonitorLogic:
    """See the module docstring. ``budget`` is a Budget or None; ``campaign`` a Campaign or None."""

    def __init__(self, model, budget=None, campaign=None, slop=0.02, max_wait=1.0, T_tracker_base=None,
                 targets=None, log_path=None, pose_tolerance=1e-3, state_buffer=2000, clock=time.monotonic,
                 name="tolerance_ros: accuracy monitor", recent=20, orientation=True, drift_window=600.0,
                 drift_limit=None):
        self.model = model
        self.reference = model        # what measurements are compared with: the nominal or the calibrated robot
        self.calibration = None
        self.before = None            # the summary the monitor had when a calibration came
        self.name = name
        self.recent = deque(maxlen=recent)  # the latest paired results, for the markers
        self.generation = 0                 # increases with each new budget
        self._drawn_generation = None
        self.campaign = campaign
        self.slop, self.max_wait = float(slop), float(max_wait)
        self.T_tracker_base = T_tracker_base
        self.orientation = bool(orientation)
        self.targets = targets if targets is not None else Targets.at_tool(frames=self.orientation)
        self.drift = DriftTracker(drift_window, drift_limit)   # ISO 9283 drift of each test pose, on line
        self._target_index = {n: k for k, n in enumerate(self.targets.names)}
        self.pose_tolerance = pose_tolerance
        # a chain from a link moved by joints (a camera on the wrist or a head): its measurements name that link
        self.sensor_link = model.base_link if getattr(model, "base_moves", False) else None
        self.clock = clock
        self.states = StateBuffer(model.dof, state_buffer)
        self.joint_order = JointOrder(model.joint_names)
        self.pending = deque()                    # (seq, stamp, T, arrival, target index)
        self.seq = 0
        self.counts = {"received": 0, "paired": 0, "unpaired": 0, "rejected": 0, "joint_states": 0,
                       "joint_states_rejected": 0, "not_judged": 0, "contacts": 0}
        self.contacts = 0                         # contact requests latched (the seq of their log events)
        self._state_arrival = -np.inf             # clock() when the newest joint state arrived
        self._others = OrderedDict()              # stamp: (names, positions) of the states naming other joints
        self.check = StreamCheck(model)
        topic = "measured_pose" if self.orientation else "measured_point"
        self.streams = ["joint_states"] + [f"{topic}/{n}" if n else topic for n in self.targets.names]
        self.gaps = {name: StampGaps(min_gap=MIN_GAP_S) for name in self.streams}   # what never arrived
        self.last = None
        self.last_reasons = deque(maxlen=20)
        self.log = None
        if log_path:
            path = Path(log_path)
            path.parent.mkdir(parents=True, exist_ok=True)
            self.log = path.open("a", buffering=1)
            self._write({"event": "start", "robot": model.name, "joint_names": list(model.joint_names),
                         "slop": self.slop, "wall_time": time.time(), "orientation": self.orientation,
                         "targets": [n for n in self.targets.names if n]})
        self.set_budget(budget)

    def set_budget(self, budget):
        """Use a new budget (Budget or None) from now on; statistics restart with it. A budget that does not
        fit the robot (``contracts.check_budget``: its robot, criterion, limits, tolerances) raises
        ContractError when it arrives, and the previous budget stays."""
        delta = check_budget(budget, self.model) if budget is not None else None
        self.acc = AccuracyAccumulator.from_budget(self.reference, budget, self.campaign, self.T_tracker_base,
                                                   self.targets, self.pose_tolerance, identify=False,
                                                   orientation=self.orientation)
        self.budget = budget
        self.delta = delta
        self.generation += 1
        self.recent.clear()
        if self.log:
            self._write({"event": "budget", "robot": budget.robot if budget else None,
                         "source": budget.source if budget else None})

    def set_calibration(self, calibration, source=""):
        """Compare measurements with the calibrated robot from now on (its registration and targets too):
        with compensated motion that is the pose the controller was asked for; without, what the calibration
        predicts. The statistics so far are kept as ``before`` in the report and restart; the report's
        ``calibration`` names the one in force (``guards.summary``: id, content hash, maker, time, log hash)."""
        names = [n for n in self.targets.names if n not in calibration.targets.names]
        if names:
            raise ValueError(f"calibration: no target(s) {names} (it has {list(calibration.targets.names)})")
        self.before = {"calibration": self.calibration, "summary": self.acc.summary()}
        self.reference = calibration.calibrated_chain(self.model)
        self.drift = DriftTracker(self.drift.window, self.drift.limit)   # errors against another robot from now
        self.T_tracker_base, self.targets = calibration.T_tracker_base, calibration.targets
        self._target_index = {n: k for k, n in enumerate(self.targets.names)}
        self.calibration = {**summary(calibration, source), "model": calibration.model.get("label"),
                            "held_out_rms_m": (calibration.validation or {}).get("after", {}).get("position_rms_m")}
        self.set_budget(self.budget)
        if self.log:
            self._write({"event": "calibration", "source": source, "id": self.calibration["id"],
                         "sha256": self.calibration["sha256"]})

    def _write(self, rec):
        """Append one event to the campaign log (strict JSON: non-finite numbers become null)."""
        if self.log:
            self.log.write(dumps_fast(rec) + "\n")

    def close(self):
        if self.log:
            self.log.close()
            self.log = None

    def on_joint_state(self, stamp, names, positions, received=None) -> list:
        """Store a joint state (names in any order; extra joints ignored); returns newly decided results.
        ``received``: the reader's ROS time when it took the message (s), which tells a queue that overflowed
        (``StampGaps``)."""
        try:
            t = stamp_seconds(stamp)
            q = self.joint_order(names, positions)
        except IngestError as exc:
            self.counts["joint_states_rejected"] += 1
            self.last_reasons.append(f"joint state rejected: {exc}")
            return []
        self.counts["joint_states"] += 1
        self.gaps["joint_states"].add(t, received)
        self.states.add(t, q)
        if isinstance(names, (list, tuple)) and len(names) > self.model.dof:   # joints outside the chain too: kept
            self._others[t] = (tuple(names), tuple(positions))                  # as given, read on contact
            while len(self._others) > OTHERS_KEPT:
                self._others.popitem(last=False)
        self._state_arrival = self.clock()
        return self.resolve()

    def _other_joints(self, t) -> tuple:
        """(names, readings) of the finite joints outside the chain of the state stamped ``t`` (the rest of a
        standing robot's posture, which loads the chain's joints; of the last ``OTHERS_KEPT`` states), or empty."""
        names, positions = self._others.get(t, ((), ()))
        chain = set(self.model.joint_names)
        try:
            pairs = [(str(n), float(v)) for n, v in zip(names, positions) if str(n) not in chain]
        except (TypeError, ValueError):
            return [], []
        pairs = [(n, v) for n, v in pairs if np.isfinite(v) and _printable_name(n)][:MAX_OTHER_JOINTS]
        return [n for n, _ in pairs], [v for _, v in pairs]

    def on_contact(self, text) -> dict:
        """A ``tolerance/contact`` request (JSON text, ``CONTACT_FIELDS``): the tool's targets touch a plane or a
        point now; the newest joint state (no older than ``max_wait`` s) is latched into the campaign log, one
        ``contact`` event per target. Returns the answer: ``{"ok": true, "rows", "stamp", "joints"}`` or ``{"ok":
        false, "error": code, "message"}``; never raises."""
        try:
            req = parse_contact(text)
        except ValueError as exc:
            return {"ok": False, "error": "invalid_request", "message": str(exc)}
        rid = req.get("id")
        if not len(self.states):
            return {"id": rid, "ok": False, "error": "no_joint_state",
                    "message": "no joint state received yet: nothing to latch"}
        age = self.clock() - self._state_arrival
        if age > self.max_wait:
            return {"id": rid, "ok": False, "error": "stale_joint_state",
                    "message": f"the newest joint state arrived {age:.3g} s ago (more than max_wait {self.max_wait:g} "
                               f"s): the joint states stopped, nothing latched"}
        k = len(self.states) - 1
        stamp, q = float(self.states.stamps[k]), np.array(self.states.q[k], float)   # the newest stamp
        beyond = self.check.joint_problem(q)
        if beyond:
            return {"id": rid, "ok": False, "error": "invalid_joint_state",
                    "message": f"the joint state cannot be this robot's: {beyond}"}
        offsets = req["targets"]
        for name, off in offsets.items():
            if off is None and name in self._target_index:
                X = self.targets.X[self._target_index[name]]
                offsets[name] = [float(v) for v in X[:3, 3]]
        other_names, others = self._other_joints(stamp)
        for name, off in offsets.items():
            self._write({"event": "contact", "seq": self.contacts, "stamp": stamp, "contact": req["contact"],
                         "session": req["session"], "target": name, "offset_m": off, "pose": req.get("pose"),
                         "joint_names": list(self.model.joint_names), "joints": [float(v) for v in q],
                         "other_joint_names": other_names, "other_joints": others})
        self.contacts += 1
        self.counts["contacts"] += len(offsets)
        return {"id": rid, "ok": True, "rows": len(offsets), "stamp": stamp, "joints": [float(v) for v in q],
                "contact": req["contact"], "session": req["session"], "logged": self.log is not None}

    def on_pose(self, stamp, frame_id, position, quaternion=None, target="", received=None) -> list:
        """A measured pose (position m, quaternion x y z w; None for a measured point, and ignored when the
        monitor measures points) of the target named ``target``, taken at ``received`` (as for joint states);
        returns the results decided by it."""
        self.counts["received"] += 1
        seq = self.seq
        self.seq += 1
        quaternion = quaternion if self.orientation else None
        frame, frame_ok = _frame(frame_id)
        rec = {"event": "measurement", "seq": seq, "stamp": None, "frame": frame,
               "position": _numbers(position), "quaternion": None if quaternion is None else _numbers(quaternion)}
        if target:
            rec["target"] = _frame(target)[0]
        try:
            k = self._target_index.get(str(target))
            if k is None:
                raise IngestError(f"target {str(target)[:MAX_FRAME_CHARS]!r} is not one of the monitor's targets "
                                  f"{[n for n in self.targets.names]}")
            rec["stamp"] = t = stamp_seconds(stamp)
            if not frame_ok:
                raise IngestError("frame_id: not UTF-8 text (a lone surrogate); written to the log escaped")
            if self.sensor_link is not None and frame != self.sensor_link:
                raise IngestError(f"frame_id: {frame!r}; the sensor is on the robot link {self.sensor_link!r} (the "
                                  f"chain's base, moved by joints) and measures in its frame")
            if quaternion is None and self.orientation:
                raise IngestError("orientation: missing (the monitor measures poses)")
            T = pose_from_values(position, quaternion if quaternion is not None else (0.0, 0.0, 0.0, 1.0))
        except IngestError as exc:
            self.counts["rejected"] += 1
            self.last_reasons.append(f"measurement {seq} rejected: {exc}")
            self._write({**rec, "rejected": str(exc)})
            return []
        self._write(rec)
        self.gaps[self.streams[k + 1]].add(t, received)
        self.pending.append((seq, t, T, self.clock(), k))
        return self.resolve()

    def on_pose_msg(self, msg, target="", received=None) -> list:
        """Duck-typed geometry_msgs/PoseStamped of the target ``target``."""
        p, o = msg.pose.position, msg.pose.orientation
        return self.on_pose(msg.header.stamp, msg.header.frame_id, (p.x, p.y, p.z), (o.x, o.y, o.z, o.w), target,
                            received)

    def on_point_msg(self, msg, target="", received=None) -> list:
        """Duck-typed geometry_msgs/PointStamped of the target ``target`` (a measured point)."""
        p = msg.point
        return self.on_pose(msg.header.stamp, msg.header.frame_id, (p.x, p.y, p.z), None, target, received)

    def on_joint_state_msg(self, msg, received=None) -> list:
        """Duck-typed sensor_msgs/JointState."""
        return self.on_joint_state(msg.header.stamp, msg.name, msg.position, received)

    def resolve(self, now=None) -> list:
        """Decide pending measurements whose neighbours are known or whose wait is over."""
        now = self.clock() if now is None else now
        newest = self.states.newest
        decided = []
        keep = deque()
        while self.pending:
            item = self.pending.popleft()
            seq, t, T, arrival, k = item
            if newest >= t or newest >= t + self.slop or now - arrival >= self.max_wait:
                decided.append(self._pair(seq, t, T, k))
            else:
                keep.append(item)
        self.pending = keep
        return [d for d in decided if d is not None]

    def _pair(self, seq, t, T, k=0):
        found = self.states.nearest(t, self.slop)
        if found is None:
            self.counts["unpaired"] += 1
            reason = (f"no joint state within {self.slop} s of stamp {t:.6f}"
                      + (f" (nearest {self.states.distance(t):.4f} s away)" if len(self.states) else " (none received)"))
            self.last_reasons.append(f"measurement {seq} unpaired: {reason}")
            self._write({"event": "unpaired", "seq": seq, "reason": reason})
            return None
        joint_stamp, q = found
        beyond = self.check.joint_problem(q)
        if beyond:
            self.counts["unpaired"] += 1
            reason = f"the joint state at {joint_stamp:.6f} s cannot be this robot's: {beyond}"
            self.last_reasons.append(f"measurement {seq} unpaired: {reason}")
            self._write({"event": "unpaired", "seq": seq, "reason": reason})
            return None
        r = self.acc.add(T[None], q[None], target=[k])
        self.counts["paired"] += 1
        problem = self.check.add(T[:3, 3], r["nominal"][0], r["position_error"][0])
        if problem:
            self.counts["not_judged"] += 1
        e_ori = r["orientation_error"]
        res = {"seq": seq, "stamp": t, "joints": q, "target": self.targets.names[k], "label": str(r["label"][0]),
               "verdict": str(r["verdict"][0]), "position_error": float(r["position_error"][0]),
               "orientation_error": None if e_ori is None else float(e_ori[0]),
               "bound": float(r["bound"][0]), "margin": float(r["margin"][0]), "dp": r["dp"][0],
               "nominal": r["nominal"][0]}
        self.last = res
        self.recent.append(res)
        if res["label"]:
            self.drift.add(res["label"], t, res["dp"])
        self._write({"event": "paired", "seq": seq, "joint_stamp": joint_stamp, "joint_names": list(self.model.joint_names),
                     "joints": [float(v) for v in q], "pose": res["label"] or None, "verdict": res["verdict"],
                     "position_error": res["position_error"],
                     "bound": res["bound"] if np.isfinite(res["bound"]) else None})
        return res

    def diagnostic(self) -> dict:
        """DiagnosticStatus content: level (0 OK, 1 WARN, 2 ERROR), name, message, key values (strings)."""
        c, v = self.counts, self.acc.counts
        level, msg = OK, "measurements within the predicted bound"
        if self.check.problem:
            return {"level": ERROR, "name": self.name, "message": self.check.problem, "hardware_id": self.model.name,
                    "values": {k: _fmt(val) for k, val in {"received": c["received"], "paired": c["paired"],
                                                           "not_judged": c["not_judged"]}.items()}}
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
        over = self.drift.over
        if over:
            words = ("drift: " + ", ".join(f"{p} moved {d * 1e3:.4f} mm since its first {self.drift.window:g} s"
                                           for p, d in over) + f" (limit {self.drift.limit * 1e3:.4f} mm)")
            msg = words if level == OK else f"{msg}; {words}"
            level = max(level, WARN)
        lost = [line for line in (g.describe(name) for name, g in self.gaps.items()) if line]
        if lost:
            msg = "; ".join(lost) if level == OK else "; ".join([msg] + lost)
            level = max(level, WARN)
        pe = self.acc.position.to_dict()
        values = {"received": c["received"], "paired": c["paired"], "unpaired": c["unpaired"],
                  "rejected": c["rejected"], "pending": len(self.pending), "within": v.get("within", 0),
                  "over_bound": v.get("over bound", 0), "over_limit": v.get("over limit", 0),
                  "position_error_mean_m": pe.get("mean"), "position_error_max_m": pe.get("max"),
                  "last_position_error_m": self.last["position_error"] if self.last else None,
                  "last_bound_m": self.last["bound"] if self.last else None,
                  "budget": (self.budget.source or self.budget.robot) if self.budget else "none",
                  "drift_max_m": self.drift.largest}
        for name, g in self.gaps.items():
            values[f"{name}_gaps"], values[f"{name}_missing"] = g.gaps, g.missing
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
        problem = self.check.problem
        return {"robot": self.model.name, "calibration": self.calibration, "before": self.before,
                "counts": dict(self.counts), "pending": len(self.pending), "problems": [problem] if problem else [],
                "stream_gaps": {name: g.summary() for name, g in self.gaps.items()},
                "recent_issues": list(self.last_reasons), "summary": None if problem else self.acc.summary(),
                "drift": self.drift.summary(),
                "last": None if problem else last,
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


_TARGET_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]{0,62}$")


def monitor_targets(measurement: str, names: str, offsets) -> Targets:
    """The monitor's Targets from its parameters: ``measurement`` 'pose' or 'point', ``names`` comma-separated
    (each a ROS name token: its topic is ``measured_pose/<name>``; empty: one unnamed target), ``offsets``
    3 per target (m, tool frame) or three zeros for all; ValueError naming the parameter."""
    if measurement not in ("pose", "point"):
        raise ValueError(f"measurement: expected 'pose' or 'point', got {measurement!r}")
    listed = [n.strip() for n in str(names).split(",") if n.strip()]
    bad = [n for n in listed if not _TARGET_NAME.match(n)]
    if bad:
        raise ValueError(f"targets: {bad[0]!r} is not a ROS name token (a letter, then letters, digits, _)")
    if len(set(listed)) != len(listed):
        raise ValueError(f"targets: a name appears twice in {listed}")
    listed = listed or [""]
    off = np.asarray(offsets, float).reshape(-1)
    if not np.all(np.isfinite(off)):
        raise ValueError("target_offsets: not finite")
    if off.size == 3 and not np.any(off):
        off = np.zeros(3 * len(listed))
    if off.size != 3 * len(listed):
        raise ValueError(f"target_offsets: expected {3 * len(listed)} values (x y z of each of {len(listed)} "
                         f"target(s)), got {off.size}")
    if np.abs(off).max(initial=0.0) > 5.0:
        raise ValueError("target_offsets: a target more than 5 m from the tool frame (metres expected)")
    return Targets.from_offsets(listed, off.reshape(-1, 3), frames=measurement == "pose")


CONTACT = re.compile(r"^(plane|point):[A-Za-z0-9_.\-]{1,100}$")
_PRINTABLE = re.compile(r"^[^\x00-\x1f\x7f]{1,100}$")


def _printable_name(name) -> bool:
    """True for a joint name the campaign log can hold: 1-100 printable characters, valid UTF-8."""
    try:
        name.encode("utf-8")
    except UnicodeEncodeError:
        return False
    return bool(_PRINTABLE.match(name))
MAX_CONTACT_TARGETS = 20


def parse_contact(text) -> dict:
    """The fields of a ``tolerance/contact`` request: ``{"contact": "plane:table1", "targets": ["A", "B"] or {"A":
    [x, y, z] (m, tool frame)}, "session": "s1", "pose": optional name, "id": optional}``; targets as
    {name: offset or None}. ValueError naming the field."""
    if not isinstance(text, str) or len(text) > 10_000:
        raise ValueError("request: expected JSON text of at most 10000 characters")
    def constant(c):
        raise ValueError(f"{c} is not a number")
    try:
        req = json.loads(text, parse_constant=constant)
    except ValueError as exc:
        raise ValueError(f"request: not valid JSON ({str(exc)[:80]})") from None
    if not isinstance(req, dict):
        raise ValueError("request: expected a JSON object")
    unknown = sorted(set(req) - {"contact", "targets", "session", "pose", "id"})
    if unknown:
        raise ValueError(f"request: unknown field(s) {unknown[:5]}; a contact has contact, targets, session, pose, id")
    contact = req.get("contact")
    if not isinstance(contact, str) or not CONTACT.match(contact):
        raise ValueError("contact: expected 'plane:ID' or 'point:ID' (ID of letters, digits, _ . -)")
    session = req.get("session", "")
    pose = req.get("pose")
    for field, v in (("session", session), ("pose", pose)):
        if v is not None and not _log_name(v, blank=True):
            raise ValueError(f"{field}: expected a name of at most 100 printable characters (UTF-8 text) without commas "
                             f"or surrounding blanks")
    targets = req.get("targets")
    if isinstance(targets, list):
        names_only = all(isinstance(t, str) for t in targets) and len(set(targets)) == len(targets)
        targets = {t: None for t in targets} if names_only else None
    if not isinstance(targets, dict) or not 1 <= len(targets) <= MAX_CONTACT_TARGETS:
        raise ValueError(f"targets: expected 1 to {MAX_CONTACT_TARGETS} distinct names, or {{name: [x, y, z]}} (m, "
                         f"tool frame)")
    out = {}
    for name, off in targets.items():
        if not _log_name(name):
            raise ValueError("targets: a name of 1 to 100 printable characters (UTF-8 text) without commas or "
                             "surrounding blanks")
        if off is not None:
            if not isinstance(off, list) or len(off) != 3 or not all(
                    isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v) for v in off):
                raise ValueError(f"targets.{name}: expected [x, y, z] (three finite numbers, m)")
            if max(abs(v) for v in off) > 5.0:
                raise ValueError(f"targets.{name}: more than 5 m from the tool frame (metres expected)")
            off = [float(v) for v in off]
        out[name] = off
    rid = req.get("id")
    if rid is not None and not valid_id(rid):
        raise ValueError(f"id: expected a string of UTF-8 text of at most {MAX_ID_CHARS} characters, or a 64-bit "
                         f"integer")
    return {"contact": contact, "targets": out, "session": session, "pose": pose, "id": rid}


def _log_name(v, blank=False) -> bool:
    """True for a name the campaign log keeps and the contact reader gives back as it is: a str of at most 100
    printable characters, UTF-8 text (no lone surrogate), no comma, no blank at either end (the reader strips
    them), not empty unless ``blank``."""
    if not isinstance(v, str) or len(v) > 100 or v != v.strip() or (not v and not blank):
        return False
    if any(ord(c) < 32 or c == "," for c in v):
        return False
    try:
        v.encode("utf-8")
    except UnicodeEncodeError:
        return False
    return True


def tracker_frame(T_tracker_base) -> tuple:
    """(translation (3,) m, quaternion x y z w) of the tracker frame in the robot's base frame: the static
    transform base -> tracker that ``T_tracker_base`` (base -> tracker coordinates) implies."""
    T = np.linalg.inv(np.asarray(T_tracker_base, float))
    return T[:3, 3].copy(), matrices_to_quat(T[None, :3, :3])[0]
