"""The on-line path monitor (ROS-free): fed the joint states and the tracker's points as they arrive, it reports
the ISO 9283 path figures each time a motion of the robot ends, the same figures ``path-report`` computes
offline from the same log (``core/accuracy/path_report.py``, ``core/accuracy/path.py``).

Each stream is put in order as it arrives (``streams.LiveOrder``): a repeated stamp or a row later than rows
already used is left out and counted; a clock that jumps starts the stream again (what was buffered is not
judged, and an estimated latency is estimated again). Incremental, in bounded memory: the command path is
computed per batch of joint states; a motion is taken when the command has rested ``min_rest`` s after it (so
that no later sample can extend it), or, in a program that loops without a stop, when a repetition of it or
a stroke before a cusp is complete (``repeats.split_runs``), and the tracker's points have reached its end;
its stations (``path.cycle_stations``) are kept, its samples dropped. The latency and the tracker's
placement are given, or estimated on the data up to the first motions that determine them (the latency of
any size: ``latency.coarse_offset`` then ``latency.estimate_latency``; the placement by Kabsch on the
buffered data); the latency is then held, the placement refined by a Kabsch over every point paired since
(``registration.KabschAccumulator``, constant memory), as offline; the stations' attained points are kept
in the tracker's frame and put in the base frame by the placement of each report (CR and CO keep the
placement of their cycle). Motions are grouped as offline (``path.cycles_of``): start, end and length;
each group keeps its last ``max_cycles`` cycles; the report of a path is its group's. Nothing is dropped
silently: the points are counted as on a path, at rest, during other motions, or outside the joint states'
time span, and samples no motion could use within ``max_buffer`` s (the robot never rests, the other stream
never comes) are counted as not judged. What never arrived is seen in the stamps (``ingest.StampGaps``):
each stream's gaps are a warning, and a motion with a gap in its joint states or in the tracker's points
across it is not judged (interpolated across lost messages, its figures would be wrong). A motion not
judged has a report too (``judged`` false, its ``reason``). Nothing raises out of the monitor: an error no
check foresaw drops its buffers, is counted (``errors``) and said, and the next motions are judged.
"""
from __future__ import annotations

from collections import deque

import numpy as np

from ..core.accuracy import path as P
from ..core.ingest import IngestError, JointOrder, StampGaps, stamp_seconds
from ..core.accuracy.latency import FINE_WINDOW_S, coarse_offset, estimate_latency
from ..core.accuracy.repeats import split_runs
from ..core.accuracy.streams import LiveOrder
from ..core.accuracy.path_report import LATENCY_SHARE, command_points, error_columns
from ..core.accuracy.registration import KabschAccumulator, kabsch
from ..core.accuracy.settling import at_rest, judge_stop, motion, summary
from .monitor import MIN_GAP_S

OK, WARN, ERROR = 0, 1, 2
MAX_QUEUED = 100_000     # messages of one stream queued between two flushes, at most
GAPS = {"joints": "joint_states", "points": "points"}   # each stream's key in ``gaps`` and in the diagnostics


class _Group:
    """The cycles of one path: its reference command (start, end, length), segment bounds and stations."""

    def __init__(self, p, bounds):
        self.start, self.end, self.length = p[0].copy(), p[-1].copy(), float(P.arc_length(p)[-1])
        self.bounds = bounds
        self.per = []
        self.cycles = 0

    def matches(self, p) -> bool:
        L = float(P.arc_length(p)[-1])
        return (np.linalg.norm(p[0] - self.start) <= P.SAME and np.linalg.norm(p[-1] - self.end) <= P.SAME
                and abs(L - self.length) <= 0.01 * self.length)


class PathMonitor:
    """See the module docstring. ``latency`` (s) and ``T_tracker_base`` (4, 4): given, else estimated from at
    least ``estimate_after`` s of motion (the latency of any size, a coarse search first; within ``+-window`` s
    when a window is given). ``step``: the motions' speed step (default the
    first batch's median joint-state interval). ``offset`` (3,) m: the measured target's point in the tool
    frame (default the tool point). Messages (duck-typed ROS ones) are queued by ``on_*_msg`` and judged by
    ``flush``."""

    def __init__(self, model, budget=None, latency=None, T_tracker_base=None, stations: int = 100,
                 speed_window: float = 0.01, rest_speed: float = 1e-3, min_rest: float = 0.05,
                 window: float | None = None,
                 max_cycles: int = 1000, max_buffer: float = 120.0, max_groups: int = 10, step: float | None = None,
                 estimate_after: float = 8.0, offset=None, name: str = "tolerance_ros: path monitor",
                 band: float = 1e-4, max_stops: int = 1000):
        self.model, self.budget = model, budget
        self.latency = None if latency is None else float(latency)
        self.latency_doc = None if latency is None else {"latency_s": self.latency, "std_s": 0.0, "given": True}
        self.A = None if T_tracker_base is None else np.asarray(T_tracker_base, float)
        self.given_A = T_tracker_base is not None
        self.pairs = KabschAccumulator()
        self.registration = "given" if T_tracker_base is not None else "base"
        self.stations, self.speed_window, self.rest_speed, self.min_rest = stations, speed_window, rest_speed, min_rest
        self.window, self.max_cycles, self.max_buffer, self.max_groups = window, max_cycles, max_buffer, max_groups
        self.step, self.estimate_after = step, estimate_after
        self.offset = None if offset is None else np.asarray(offset, float)
        self.name = name
        self.order = JointOrder(model.joint_names)
        self.queued = {"joints": ([], []), "points": ([], [])}
        self.reasons = []
        self.tj = np.zeros(0)
        self.qj = np.zeros((0, model.dof))
        self.pc = np.zeros((0, 3))
        self.tm = np.zeros(0)
        self.pm = np.zeros((0, 3))
        self.first_joint = None
        self.groups = []
        self.counts = {"points": 0, "joint_states": 0, "on_path": 0, "at_rest": 0, "other_motions": 0,
                       "outside_joint_states": 0, "not_judged": 0, "motions": 0, "rejected": 0, "errors": 0}
        self.live = {"joints": LiveOrder("joint states"), "points": LiveOrder("tracker points")}
        self.given_latency = latency is not None
        self._tried = None                           # the motions' end the latency was last tried on
        self.last = None
        self.gaps = {"joint_states": StampGaps(), "points": StampGaps()}  # what never arrived, seen in the stamps
        self.holes = []                              # why the latest motions were not judged
        self.band = float(band)                      # the stabilisation band of the stops (m)
        self.pending = None                          # the motion whose stop is judged when its rest ends
        self.stop_list = deque(maxlen=max_stops)     # the latest stops' figures (``settling.judge_stop``)

    # -- input ---------------------------------------------------------------------------------------------
    def add_joint_states(self, stamps, joints) -> list:
        """Joint states (k,) s, (k, dof) rad or m, as they arrived (``streams.LiveOrder`` puts them in order);
        returns the reports of the motions that ended. Never raises: what cannot be used is counted."""
        return self._add("joints", stamps, joints, self.model.dof)

    def add_points(self, stamps, points) -> list:
        """Tracker points (n,) s, (n, 3) m in the tracker frame, as they arrived; returns the reports of the
        motions that ended. Never raises: what cannot be used is counted."""
        return self._add("points", stamps, points, 3)

    def _add(self, kind, stamps, values, width) -> list:
        try:
            t = np.asarray(stamps, float).reshape(-1)
            v = np.asarray(values, float)
            if v.size != t.size * width:
                raise ValueError(f"{t.size} stamps for {v.size} values ({width} a row expected)")
            v = v.reshape(t.size, width)
        except (TypeError, ValueError, OverflowError) as exc:
            n = int(np.size(stamps)) if np.ndim(stamps) else 1
            self._reject(kind, n, f"{kind}: {exc}")
            return []
        out = []
        try:
            for restart, te, ve in self.live[kind].take(t, v):
                if restart:
                    out += self._restart(kind)
                out += self._append(kind, te, ve)
        except Exception as exc:   # the last resort: a monitor never stops reporting
            out += self._recover(kind, exc)
        return out

    def _append(self, kind, t, v) -> list:
        """Rows in order, after the latest taken: into the buffers, then the motions that ended judged."""
        if kind == "joints":
            if self.first_joint is None:
                self.first_joint = float(t[0])
            self.counts["joint_states"] += len(t)
            self.gaps["joint_states"].add(t)
            self.tj = np.concatenate([self.tj, t])
            self.qj = np.vstack([self.qj, v])
            self.pc = np.vstack([self.pc, command_points(self.model, v, offset=self.offset)])
        else:
            self.counts["points"] += len(t)
            self.gaps["points"].add(t)
            self.tm = np.concatenate([self.tm, t])
            self.pm = np.vstack([self.pm, v])
        if self.step is None and len(self.tj) > 2:
            self.step = float(np.median(np.diff(self.tj)))
        return self._process() if self.step is not None else []

    def _reject(self, kind, n, why):
        self.counts["rejected"] += n
        self.reasons = (self.reasons + [why])[-10:]

    def _not_judged(self, why, points, start=None, end=None) -> list:
        """Count ``points`` as not judged for ``why``; its report (``judged`` false) for tolerance/path_report."""
        self.counts["not_judged"] += int(points)
        self.holes = (self.holes + [why])[-10:]
        return [{"robot": self.model.name, "judged": False, "reason": why, "motion_s": [start, end],
                 "points": int(points), "counts": dict(self.counts),
                 "stream_gaps": {s: g.summary() for s, g in self.gaps.items()}}]

    def _drop_buffers(self, kind=None):
        """Forget the buffered tracker points, and the joint states too unless ``kind`` is 'points'; how many
        points were dropped."""
        dropped = len(self.tm)
        self.tm, self.pm = self.tm[:0], self.pm[:0]
        self.pending = None                          # its rest is gone with the buffer
        if kind in (None, "joints"):
            self.tj, self.qj, self.pc = self.tj[:0], self.qj[:0], self.pc[:0]
            self.first_joint = None
        self._tried = None
        return dropped

    def _restart(self, kind) -> list:
        """A stream's clock jumped: what is buffered cannot be paired across it. Its points are counted as not
        judged; an estimated latency is estimated again (the clocks' offset may have changed)."""
        stream = self.live[kind].name
        j = self.live[kind].jumps[-1]
        self.gaps[GAPS[kind]].cut()
        if not self.given_latency:
            self.latency, self.latency_doc = None, None
        n = self._drop_buffers(kind)
        return self._not_judged(f"the {stream}' clock jumped from {j['from_s']:.6g} s to {j['to_s']:.6g} s: the "
                                f"motion under way and {n} buffered point(s) were not judged", n)

    def _recover(self, kind, exc) -> list:
        """An error no check foresaw: its buffers are dropped (so that it cannot recur on them) and counted,
        the error said; the monitor goes on with the next messages."""
        self.counts["errors"] += 1
        n = self._drop_buffers(None)
        return self._not_judged(f"{kind}: {type(exc).__name__}: {str(exc)[:200]}: the buffered streams were dropped "
                                f"and {n} point(s) not judged", n)

    def on_joint_state_msg(self, msg):
        """Queue a duck-typed sensor_msgs/JointState (its joints put in the model's order)."""
        self._queue("joints", msg, lambda: self.order(msg.name, msg.position))

    def on_point_msg(self, msg):
        """Queue a duck-typed geometry_msgs/PointStamped (the tracker frame)."""
        self._queue("points", msg, lambda: (msg.point.x, msg.point.y, msg.point.z))

    def on_pose_msg(self, msg):
        """Queue the position of a duck-typed geometry_msgs/PoseStamped (the tracker frame)."""
        self._queue("points", msg, lambda: (msg.pose.position.x, msg.pose.position.y, msg.pose.position.z))

    def _queue(self, kind, msg, value):
        """Queue one message's stamp and values, or count it rejected with why (never raises)."""
        stamps, values = self.queued[kind]
        try:
            t = stamp_seconds(msg.header.stamp)
            v = np.asarray(value(), float).reshape(-1)
            if not np.all(np.isfinite(v)):
                raise IngestError("not a finite number")
        except Exception as exc:   # a message of any shape: counted, never raised
            self._reject(kind, 1, f"{kind}: {exc}")
            return
        if len(stamps) >= MAX_QUEUED:
            self._reject(kind, 1, f"{kind}: more than {MAX_QUEUED} messages queued between two flushes")
            return
        stamps.append(t)
        values.append(v)

    def flush(self) -> list:
        """Judge what was queued; the reports of the motions that ended (judged or not, with why)."""
        out = []
        for kind, add in (("joints", self.add_joint_states), ("points", self.add_points)):
            stamps, values = self.queued[kind]
            if stamps:
                self.queued[kind] = ([], [])
                out += add(stamps, values)
        return out

    def diagnostic(self) -> dict:
        """The /diagnostics status (level, name, message, values) of the path monitor."""
        level, message = self.status()
        values = {k: str(v) for k, v in self.counts.items()}
        if self.latency is not None:
            values["latency_s"] = f"{self.latency:.6f}"
        if self.last is not None:
            values.update({k: "" if v is None else f"{v:.9g}" for k, v in self.last["overall"].items()})
        if self.reasons:
            values["last_rejected"] = self.reasons[-1]
        if self.holes:
            values["last_not_judged"] = self.holes[-1]
        for stream, g in self.gaps.items():
            values[f"{stream}_gaps"], values[f"{stream}_missing"] = str(g.gaps), str(g.missing)
        for kind, o in self.live.items():
            values.update({f"{GAPS[kind]}_{k}": str(v) for k, v in o.counts.items() if v})
        return {"level": level, "name": self.name, "hardware_id": "", "message": message, "values": values}

    def finish(self) -> list:
        """The end of the streams: the last stop is judged, the points left are counted (at rest, or outside the
        joint states' span)."""
        if self.pending is not None and len(self.tj) and len(self.tm) and self.latency is not None:
            self._judge_stop(min(float(self.tj[-1]), float(self.tm[-1] - self.latency)))
        if self.latency is not None and len(self.tm):
            ta = self.tm - self.latency
            out = (ta < (self.first_joint if self.first_joint is not None else np.inf)) | \
                (ta > (self.tj[-1] if len(self.tj) else -np.inf))
            self.counts["outside_joint_states"] += int(out.sum())
            self.counts["at_rest"] += int((~out).sum())
        else:
            self.counts["not_judged"] += len(self.tm)
        self.tm, self.pm = self.tm[:0], self.pm[:0]
        return []

    # -- processing ----------------------------------------------------------------------------------------
    def _complete_runs(self):
        """The motions in the buffer that no later sample can change: those the command rested after, cut into
        their repetitions and at their cusps (``repeats.split_runs``), and the repetitions of the motion under
        way but its last (a program that loops without a stop)."""
        if len(self.tj) < 3:
            return []
        runs = P.motions(self.tj, self.pc, self.rest_speed, self.min_rest, step=self.step)
        done = self.tj[-1] - self.min_rest - 2 * self.step
        out = []
        for a, b in runs:
            pieces, _ = split_runs(self.tj, self.pc, [(a, b)], self.step)
            out += pieces if self.tj[b] < done else pieces[:-1]
        return out

    def _process(self) -> list:
        out = []
        runs = self._complete_runs()
        if self.latency is None or self.A is None:
            if not runs or not self._estimate(runs):
                self._bound_memory()
                return out
            runs = self._complete_runs()
        while runs:
            i0, i1 = runs[0]
            if not len(self.tm) or self.tm[-1] - self.latency < self.tj[i1]:
                break                                  # the tracker has not reached the motion's end yet
            out += self._take(i0, i1)                  # drops the buffer up to the motion's end
            runs = self._complete_runs()
        self._bound_memory()
        return out

    def _estimate(self, runs) -> bool:
        """Latency and placement from the buffered data once ``estimate_after`` s of motion are in it and the
        tracker's points reach past the last of them; tried once per motion that ends (not on every batch)."""
        moving = sum(self.tj[b] - self.tj[a] for a, b in runs)
        end = float(self.tj[runs[-1][1]])
        if moving < self.estimate_after or not len(self.tm) or self._tried == end:
            return False
        keep = self.tj <= end + self.min_rest
        tj, pc = self.tj[keep], self.pc[keep]
        tau, lat_doc, A = self.latency, self.latency_doc, self.A
        try:
            if tau is None:
                if self.window is None:                # of any size: the coarse search first
                    center, window = coarse_offset(self.tm, self.pm, tj, pc), FINE_WINDOW_S
                else:
                    center, window = 0.0, self.window
                if self.tm[-1] - center - window < end:
                    return False                       # the tracker has not reached the motions' end yet
                self._tried = end
                sel = self.tm - center - window <= tj[-1]
                tm, pm = self.tm[sel], self.pm[sel]
                groups = [np.arange(*np.searchsorted(tm - center, [tj[a], tj[b]])) for a, b in runs]
                lat = estimate_latency(tm, pm, tj, pc, window, center, True, groups if len(groups) >= 3 else None,
                                       np.array_split(np.concatenate(groups), 4),
                                       geometry=error_columns(self.model, tj, self.qj[keep], self.offset))
                tau, lat_doc = lat.latency_s, lat.to_dict()
            else:
                self._tried = end
                tm, pm = self.tm, self.pm
            if A is None:
                ta = tm - tau
                inside = (ta >= tj[0]) & (ta <= tj[-1])
                P_ = P.interp_columns(ta[inside], tj, pc)
                R, t, S = kabsch(P_, pm[inside])
                if S[1] < 1e-6 * S[0]:
                    return False                       # a straight line does not fix the rotation: wait
                A = np.eye(4)
                A[:3, :3], A[:3, 3] = R, t
        except ValueError as exc:
            self.reasons = (self.reasons + [f"latency and placement not found yet: {exc}"])[-10:]
            return False
        self.latency, self.latency_doc, self.A = tau, lat_doc, A
        return True

    def _judge_stop(self, t_end: float):
        """The figures of the stop after the pending motion, its rest lasting to ``t_end`` (``settling``)."""
        mv, self.pending = self.pending, None
        if mv is None or self.A is None or self.latency is None:
            return
        k = int(np.searchsorted(self.tj, t_end, side="right"))   # the buffer starts at the motion's last sample
        mv = at_rest(mv, self.tj[:k], self.pc[:k])
        ta = self.tm - self.latency
        j0, j1 = np.searchsorted(ta, [mv["stop_s"], t_end], side="left")
        R, t = self.A[:3, :3], self.A[:3, 3]
        self.stop_list.append(judge_stop(ta[j0:j1 + 1], (self.pm[j0:j1 + 1] - t) @ R, mv, t_end, self.band))

    def _take(self, i0, i1) -> list:
        """Judge the motion [i0, i1] of the buffer, unless a gap in its streams leaves it not judged; count the
        points before it, drop the buffer up to its end. The stop before it is judged first (its rest ends
        where this motion starts), and this motion's stop waits for the next motion or the end."""
        self._judge_stop(float(self.tj[i0]))
        ta = self.tm - self.latency
        j0, j1 = np.searchsorted(ta, [self.tj[i0], self.tj[i1]])
        hole = P.hole_in_motion(self.gaps, self.tj, i0, i1, self.tm, j0, j1)
        if hole is None and j1 - j0 < 2:
            hole = (f"the motion from {self.tj[i0]:.3f} s to {self.tj[i1]:.3f} s was not judged: {j1 - j0} tracker "
                    f"point(s) along it (the tracker was not recording, or the latency is not its own)")
        if hole is None:                               # the placement learns from the motions judged only
            sel = slice(int(np.searchsorted(ta, self.first_joint)), j1)
            self.pairs.add(P.interp_columns(ta[sel], self.tj, self.pc), self.pm[sel])
            if not self.given_A and self.pairs.n >= 3:
                try:
                    self.A = self.pairs.result()
                except ValueError:
                    pass
        early = ta[:j0] < self.first_joint
        self.counts["outside_joint_states"] += int(early.sum())
        self.counts["at_rest"] += int((~early).sum())
        self.counts["motions"] += 1
        if hole is None:
            report = self._judge(i0, i1, j0, j1, ta)
        else:                                          # interpolated across lost messages: not judged
            report = self._not_judged(hole, j1 - j0, float(self.tj[i0]), float(self.tj[i1]))
        self.pending = motion(self.tj, self.pc, i0, i1, 0) if hole is None else None
        self.tm, self.pm = self.tm[j1:], self.pm[j1:]
        self.tj, self.qj, self.pc = self.tj[i1:], self.qj[i1:], self.pc[i1:]
        return report

    def _judge(self, i0, i1, j0, j1, ta) -> list:
        """The stations of the motion [i0, i1] (its points [j0, j1), ``ta`` their aligned stamps) added to its
        path's group; the group's report, or the report of a motion not judged (no group left for a new path,
        or no stations), with why."""
        tc, pc = self.tj[i0:i1 + 1], self.pc[i0:i1 + 1]
        span = (float(tc[0]), float(tc[-1]))
        group = next((g for g in self.groups if g.matches(pc)), None)
        if group is None and len(self.groups) < self.max_groups:
            group = _Group(pc, P.segment_bounds(P.arc_length(pc)[-1], P.corners(pc)))
            self.groups.append(group)
        if group is None:
            return self._not_judged(f"the motion from {span[0]:.3f} s to {span[1]:.3f} s was not judged: it follows "
                                    f"none of the {self.max_groups} paths kept", j1 - j0, *span)
        R, t = self.A[:3, :3], self.A[:3, 3]
        a = (self.pm[j0:j1] - t) @ R
        cyc = P.Cycle(tc, pc, P.arc_length(pc), ta[j0:j1], a)
        try:
            st = P.cycle_stations(cyc, group.bounds, self.stations, self.speed_window)
        except ValueError as exc:
            return self._not_judged(f"the motion from {span[0]:.3f} s to {span[1]:.3f} s was not judged: {exc}",
                                    j1 - j0, *span)
        st["x"] = st["x"] @ R.T + t                # kept in the tracker's frame
        group.per.append(st)
        group.cycles += 1
        group.per = group.per[-self.max_cycles:]
        self.counts["on_path" if group is self.best() else "other_motions"] += int(j1 - j0)
        self.last = self._report(group)
        return [self.last]

    def _bound_memory(self):
        """Samples older than ``max_buffer`` s that no motion took (the robot never rested, or the other stream
        never came) are dropped and counted as not judged."""
        if len(self.tj) and self.tj[-1] - self.tj[0] > self.max_buffer:
            cut = np.searchsorted(self.tj, self.tj[-1] - self.max_buffer)
            self.tj, self.qj, self.pc = self.tj[cut:], self.qj[cut:], self.pc[cut:]
            k = np.searchsorted(self.tm - (self.latency or 0.0), self.tj[0])
            self.counts["not_judged"] += int(k)
            self.tm, self.pm = self.tm[k:], self.pm[k:]
        reach = self.max_buffer + abs(self.latency or 0.0) + 1.0
        if len(self.tm) and self.tm[-1] - self.tm[0] > reach:
            k = int(np.searchsorted(self.tm, self.tm[-1] - reach))
            self.counts["not_judged"] += k
            self.tm, self.pm = self.tm[k:], self.pm[k:]

    # -- output --------------------------------------------------------------------------------------------
    def best(self):
        """The group with the most cycles (the test path), or None."""
        return max(self.groups, key=lambda g: g.cycles) if self.groups else None

    def _report(self, group) -> dict:
        R, t = self.A[:3, :3], self.A[:3, 3]
        per = [dict(st, x=(st["x"] - t) @ R) for st in group.per]
        segs = P.figures(per, group.bounds, self.stations, self.speed_window)
        doc = {"robot": self.model.name, "judged": True, "latency_s": self.latency,
               "latency_std_s": self.latency_doc.get("std_s") if self.latency_doc else None,
               "registration": {"method": self.registration, "T_tracker_base": self.A.tolist()},
               "path": self.groups.index(group), "cycles": len(group.per), "cycles_seen": group.cycles,
               "path_length_m": group.length, "speed_m_s": max(s["v_c_m_s"] for s in segs), "segments": segs,
               "overall": P.overall(segs), "counts": dict(self.counts), "refused": None, "missed": [],
               "stream_gaps": {s: g.summary() for s, g in self.gaps.items()}, "not_judged": list(self.holes),
               "stops": summary(list(self.stop_list), self.band)}
        if self.budget is not None and self.budget.limit_position is not None:
            limit = self.budget.limit_position
            shift = 2.0 * (doc["latency_std_s"] or 0.0) * doc["speed_m_s"]
            if shift > LATENCY_SHARE * limit:
                doc["refused"] = (f"the latency {self.latency * 1e3:.2f} ms is too uncertain for the budget: it moves "
                                  f"the path by {shift * 1e3:.3f} mm, more than {LATENCY_SHARE:.0%} of the "
                                  f"{limit * 1e3:.3f} mm limit")
                doc["missed"].append(doc["refused"])
            elif doc["overall"]["AT_p_m"] > limit:
                doc["missed"].append(f"path accuracy AT_p {doc['overall']['AT_p_m'] * 1e3:.4f} mm exceeds the design "
                                     f"limit {limit * 1e3:.4f} mm")
        return doc

    def status(self) -> tuple:
        """(level OK/WARN/ERROR, message) for /diagnostics; a motion not judged, a gap of ``MIN_GAP_S`` in a
        stream, or a clock that jumped makes an OK a WARN (a timer late once, away from the motions, does
        not); rows left out as repeated, late or not finite are said."""
        level, message = self._status()
        lost = [g.describe(s) for s, g in self.gaps.items() if g.gaps and (self.holes or g.longest > MIN_GAP_S)]
        order = [d for d in (o.describe() for o in self.live.values()) if d]
        jumped = any(o.counts["jumps"] for o in self.live.values())
        if lost or self.holes or jumped:
            level = max(level, WARN)
        if lost or self.holes or order:
            message = "; ".join([message] + lost + order + self.holes[-1:])
        return level, message

    def _status(self) -> tuple:
        if self.last is None:
            return WARN, (f"no path judged yet ({self.counts['motions']} motions, {self.counts['points']} points)")
        if self.last["refused"]:
            return ERROR, self.last["refused"]
        o = self.last["overall"]
        words = (f"path {self.last['path']}: {self.last['cycles']} cycles, AT_p {o['AT_p_m'] * 1e3:.4f} mm"
                 + (f", RT_p {o['RT_p_m'] * 1e3:.4f} mm" if o["RT_p_m"] is not None else "")
                 + f", latency {self.latency * 1e3:.2f} ms")
        return (ERROR, "; ".join(self.last["missed"]) + f" ({words})") if self.last["missed"] else (OK, words)
