"""One ingestion path for joint states and measured poses, live (duck-typed ROS messages) or recorded.

- ``stamp_seconds``: a ``builtin_interfaces/Time`` (sec, nanosec) as float seconds;
- ``JointOrder``: joint readings named in any order -> the model's joint order (extra joints ignored);
- ``pose_from_values``: a measured position (m) and quaternion (x, y, z, w) -> a validated 4x4 pose;
- ``StateBuffer`` and ``pair_by_stamp``: the joint state nearest in time to a measurement, within a slop;
- ``StampGaps``: the gaps in a regular stream's stamps (messages lost on the way, or never sent), and
  ``describe_gaps``, their line for a person.
Every check raises ``IngestError`` with a message that says what is wrong; nothing is dropped here.
"""
from __future__ import annotations

import math

import numpy as np

from .geometry import quat_to_matrices


MAX_POSITION_M = 1e6  # no measured tool point is 1000 km away; squares of larger errors would overflow statistics


class IngestError(ValueError):
    """A joint state, pose or stamp that cannot be used; the message says why."""


def stamp_seconds(stamp) -> float:
    """Seconds of a ``builtin_interfaces/Time`` (``sec``, ``nanosec`` in [0, 1e9)), or of a plain number (s)."""
    if isinstance(stamp, (int, float)) and not isinstance(stamp, bool):
        t = float(stamp)
    else:
        try:
            nanosec = float(stamp.nanosec)
            t = float(stamp.sec) + nanosec * 1e-9
        except (AttributeError, TypeError, ValueError, OverflowError):
            raise IngestError(f"stamp: expected sec and nanosec, got {type(stamp).__name__}") from None
        if not 0 <= nanosec < 1e9:
            raise IngestError(f"stamp: nanosec {nanosec:.10g} is outside [0, 1e9)")
    if not math.isfinite(t):
        raise IngestError(f"stamp: not a finite time ({t})")
    return t


class JointOrder:
    """Maps joint readings named in any order to the model's order (``joint_names``); extra joints are
    ignored. The index of the last list of names is kept, so a steady stream costs one comparison."""

    def __init__(self, joint_names):
        self.joint_names = tuple(joint_names)
        self._names = None
        self._index = None

    def index(self, names) -> np.ndarray:
        """(dof,) positions in ``names`` of the model's joints; raises IngestError naming missing joints, and
        joints of the model named twice (which of the two values holds is unknown)."""
        try:
            names = tuple(names)
        except TypeError:
            raise IngestError(f"name: expected a list of joint names, got {type(names).__name__}") from None
        if names != self._names:
            try:
                lookup = {n: i for i, n in enumerate(names)}
            except TypeError:
                raise IngestError("name: expected joint names (text)") from None
            missing = [n for n in self.joint_names if n not in lookup]
            if missing:
                raise IngestError(f"no value for joint(s) {missing} (have {_shown(names)})")
            if len(lookup) < len(names):
                twice = [n for n in self.joint_names if names.count(n) > 1]
                if twice:
                    raise IngestError(f"joint(s) {twice[:10]} named more than once in one joint state")
            self._index = np.array([lookup[n] for n in self.joint_names], dtype=int)
            self._names = names
        return self._index

    def __call__(self, names, positions) -> np.ndarray:
        """(dof,) finite joint values (rad or m) in the model's order from one joint state."""
        idx = self.index(names)
        try:
            values = np.asarray(positions, dtype=float).reshape(-1)
        except (TypeError, ValueError, OverflowError):
            raise IngestError("positions: expected numbers") from None
        if values.size < len(self._names):
            raise IngestError(f"positions: {values.size} values for {len(self._names)} joint names")
        q = values[idx]
        bad = np.flatnonzero(~np.isfinite(q))
        if bad.size:
            raise IngestError(f"joint {self.joint_names[bad[0]]!r}: not a finite number ({q[bad[0]]})")
        return q

    def rows(self, names, values) -> np.ndarray:
        """(n, dof) joint values in the model's order from a table with one column per name in ``names``."""
        return np.asarray(values, dtype=float)[:, self.index(names)]


def _shown(names, count=10, chars=40) -> str:
    """The first names of a joint state, each cut short: a message says what it got in bounded space."""
    shown = [str(n)[:chars] + ("..." if len(str(n)) > chars else "") for n in list(names[:count])]
    return f"{shown}" + (f" and {len(names) - count} more" if len(names) > count else "")


def pose_from_values(position, quaternion) -> np.ndarray:
    """4x4 pose (m) from a position (3,) within ``MAX_POSITION_M`` of the origin and a quaternion (x, y, z, w),
    normalised; raises IngestError."""
    try:
        p = np.asarray(position, dtype=float).reshape(-1)
        o = np.asarray(quaternion, dtype=float).reshape(-1)
    except (TypeError, ValueError, OverflowError):
        raise IngestError("pose: expected numbers") from None
    if p.size != 3 or o.size != 4:
        raise IngestError(f"pose: expected 3 position and 4 quaternion values, got {p.size} and {o.size}")
    if not (np.isfinite(p).all() and np.isfinite(o).all()):
        raise IngestError("pose: non-finite position or quaternion")
    far = float(np.abs(p).max())
    if far > MAX_POSITION_M:
        raise IngestError(f"pose: position {far:.3g} m from the origin is beyond {MAX_POSITION_M:g} m")
    try:
        R = quat_to_matrices(o)[0]
    except ValueError:
        raise IngestError("quaternion: zero norm (a zero quaternion is no rotation)") from None
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, p
    return T


def nearest_indices(sorted_stamps, t, slop: float) -> np.ndarray:
    """Index into ``sorted_stamps`` (ascending) of the stamp nearest to each of ``t`` (s) within ``slop``,
    else -1; of two equally near stamps, the earlier."""
    s = np.asarray(sorted_stamps, dtype=float)
    t = np.asarray(t, dtype=float)
    if s.size == 0:
        return np.full(t.shape, -1)
    k = np.clip(np.searchsorted(s, t), 1, max(s.size - 1, 1)) if s.size > 1 else np.zeros(t.shape, int)
    if s.size > 1:
        left = k - 1
        k = np.where(np.abs(t - s[left]) <= np.abs(s[k] - t), left, k)
    return np.where(np.abs(s[k] - t) <= slop, k, -1)


def pair_by_stamp(meas_stamps, state_stamps, slop: float) -> np.ndarray:
    """(n,) index of the state (in any order) nearest in time to each measurement within ``slop`` s, else -1."""
    t = np.asarray(state_stamps, dtype=float)
    if t.size == 0:
        return np.full(np.shape(meas_stamps), -1)
    order = np.argsort(t, kind="stable")
    k = nearest_indices(t[order], meas_stamps, slop)
    return np.where(k >= 0, order[np.maximum(k, 0)], -1)


class StateBuffer:
    """The most recent ``capacity`` joint states (stamp s, joints (dof,)), kept sorted by stamp."""

    def __init__(self, dof: int, capacity: int = 2000):
        self.capacity = int(capacity)
        self.stamps = np.empty(2 * self.capacity)
        self.q = np.empty((2 * self.capacity, dof))
        self.n = 0

    def __len__(self):
        return self.n

    def add(self, stamp: float, q):
        if self.n == len(self.stamps):  # full twice over: keep the newest ``capacity``
            self.stamps[:self.capacity] = self.stamps[self.n - self.capacity:self.n]
            self.q[:self.capacity] = self.q[self.n - self.capacity:self.n]
            self.n = self.capacity
        k = self.n if self.n == 0 or stamp >= self.stamps[self.n - 1] else \
            int(np.searchsorted(self.stamps[:self.n], stamp, side="right"))
        self.stamps[k + 1:self.n + 1] = self.stamps[k:self.n].copy()
        self.q[k + 1:self.n + 1] = self.q[k:self.n].copy()
        self.stamps[k], self.q[k] = stamp, q
        self.n += 1

    @property
    def newest(self) -> float:
        return float(self.stamps[self.n - 1]) if self.n else -math.inf

    def nearest(self, t: float, slop: float):
        """(stamp, q) of the state nearest to ``t`` within ``slop`` s, else None."""
        k = int(nearest_indices(self.stamps[:self.n], t, slop))
        return None if k < 0 else (float(self.stamps[k]), self.q[k].copy())

    def distance(self, t: float) -> float:
        """Distance (s) from ``t`` to the nearest stored stamp (inf when empty)."""
        return float(np.min(np.abs(self.stamps[:self.n] - t))) if self.n else math.inf


class StampGaps:
    """The gaps in the stamps of a regular stream (joint states at 1 kHz, a tracker's points): messages lost on
    the way (a reader's queue that overflowed while its callbacks ran late, a network) or never sent (a late
    publisher, a tracker that lost its beam); what a reader cannot otherwise count, since it never got them.

    The period is the median of the latest ``window`` intervals (refreshed every ``refresh``); an interval longer
    than ``factor`` periods and than ``min_gap`` s is a gap, worth ``round(interval / period) - 1`` missing
    messages (``min_gap``: a publisher's timer that fires late stamps a gap too, of a few periods). Judged only once
    ``learn`` intervals are in and while the stream is regular (nine in ten of the latest intervals within twice
    the period): a stream of single measurements, sent when taken, has no gaps to find. A stamp earlier than
    the previous one (a restarted clock) starts the intervals again. ``add`` takes one stamp or an array (s).

    With ``received`` (the reader's clock when it took each message, s, in the stamps' time base: ROS time) a
    gap shorter than ``min_gap`` is a gap too when the message after it waited in the reader's queue: its lag
    (received - stamp) more than ``factor`` periods and ``BEHIND_S`` over the previous message's. That is how
    a queue that overflowed looks (DDS keeps the latest ``depth`` and drops the older ones, so the message
    after the hole is ``depth`` periods old when taken), and not how a late publisher looks; ``behind``
    counts such gaps."""

    BEHIND_S = 0.05
    """s: a lag this much above the previous message's (and ``factor`` periods) means the message waited."""

    def __init__(self, factor: float = 5.0, learn: int = 20, window: int = 256, refresh: int = 32,
                 min_gap: float = 0.0):
        self.factor, self.learn, self.window, self.refresh = float(factor), int(learn), int(window), int(refresh)
        self.min_gap = float(min_gap)
        self.intervals = np.zeros(0)    # the latest ``window`` intervals, s (but those of ``_recent``)
        self._recent = []               # intervals of single stamps taken since the last batch
        self.last = None                # the previous stamp, s
        self.seen = 0                   # intervals taken in
        self.unsorted = 0               # intervals taken in since the period was last computed
        self.period = None              # s, once learned
        self.regular = False
        self.gaps = 0
        self.missing = 0
        self.longest = 0.0              # s
        self.last_gap = None            # (stamp at the gap's end s, its length s)
        self.restarts = 0
        self.behind = 0                 # gaps found while the reader was behind (its queue overflowed)
        self.last_lag = None            # received - stamp of the previous message, s (with ``received``)
        self._learning = (np.zeros(0), np.zeros(0), np.zeros(0))  # (intervals, their end stamps, lag rises) before
        # the period is known

    def add(self, stamps, received=None) -> int:
        """Take the next stamp(s) in arrival order, with the reader's clock when it took each (``received``, s,
        optional); returns how many new gaps they show."""
        if isinstance(stamps, float) and (received is None or isinstance(received, float)) and self._one(stamps):
            return self._add_one(stamps, received)  # one message, the common live case: no array work
        t = np.asarray(stamps, dtype=float).reshape(-1)
        r = None if received is None else np.broadcast_to(np.asarray(received, dtype=float).reshape(-1), t.shape)
        keep = np.isfinite(t)
        t, r = t[keep], None if r is None else r[keep]   # a reader's clock that is not finite tells nothing
        if t.size == 0:
            return 0
        if t.size == 1 and self._one(float(t[0])):
            return self._add_one(float(t[0]), None if r is None else float(r[0]))
        d = np.diff(np.concatenate([[self.last], t])) if self.last is not None else np.diff(t)
        back = np.flatnonzero(d < 0)
        if back.size:                       # a clock that restarted: judge up to it, start again from it
            cut = back[0] + (0 if self.last is not None else 1)
            found = self.add(t[:cut], None if r is None else r[:cut]) if cut else 0
            self.restarts += 1
            self.last = self.last_lag = None
            return found + self.add(t[cut:], None if r is None else r[cut:])
        ends = t[t.size - d.size:]
        waited = np.full(d.size, -np.inf)  # how much each interval's end lag rose over its start's; unknown: -inf
        if r is not None:
            with np.errstate(invalid="ignore"):     # a reader's clock that is not finite: no evidence (nan)
                lags = r - t
                lags[~np.isfinite(lags)] = np.nan
                prev = np.nan if self.last_lag is None else self.last_lag
                at = np.where(np.isfinite(lags), np.arange(lags.size), -1)
                np.maximum.accumulate(at, out=at)   # each message's latest finite lag, carried forward
                latest = np.where(at >= 0, lags[at], prev)
                rise = lags - np.concatenate([[prev], latest[:-1]])   # over the latest finite lag before it
            waited[:] = rise[rise.size - d.size:]
            if np.isfinite(latest[-1]):
                self.last_lag = float(latest[-1])
        self.last = float(t[-1])
        self.intervals = np.concatenate([self.intervals, self._recent, d])[-self.window:]
        self._recent = []
        self.seen += d.size
        self.unsorted += d.size
        if self.period is None:
            d, ends, waited = (np.concatenate([a, b]) for a, b in zip(self._learning, (d, ends, waited)))
            if self.seen < self.learn:
                self._learning = (d, ends, waited)  # fewer than ``learn``
                return 0
            self._learning = (np.zeros(0), np.zeros(0), np.zeros(0))
            self._update()                  # the learning intervals are judged too
        elif self.unsorted >= self.refresh:
            self._update()
        return self._judge(d, ends, waited) if self.regular else 0

    def _one(self, stamp: float) -> bool:
        """Whether ``_add_one`` takes ``stamp``: finite, not before the previous one, the period known and not due
        for its refresh."""
        return (self.period is not None and self.last is not None and self.unsorted + 1 < self.refresh
                and stamp >= self.last and math.isfinite(stamp))

    def _add_one(self, stamp: float, received) -> int:
        """``add`` of one stamp that ``_one`` takes, with the reader's clock then (s; not finite: no evidence)."""
        d = stamp - self.last
        self.last = stamp
        self.seen += 1
        self.unsorted += 1
        self._recent.append(d)          # into ``intervals`` with the next batch, before the period is refreshed
        queued = False
        if received is not None and math.isfinite(received):
            lag = received - stamp
            queued = self.last_lag is not None
            rise = lag - self.last_lag if queued else 0.0
            self.last_lag = lag
        if self.regular and d > self.factor * self.period and (d > self.min_gap or queued):
            return self._judge(np.array([d]), np.array([stamp]), np.array([rise]) if queued else None)
        return 0

    def _update(self):
        self.period = float(np.median(self.intervals))
        self.regular = self.period > 0 and float(np.quantile(self.intervals, 0.9)) <= 2.0 * self.period
        self.unsorted = 0

    def _threshold(self) -> float:
        return max(self.factor * self.period, self.min_gap)

    def _judge(self, d, ends, waited=None) -> int:
        """Count the gaps among the intervals ``d`` ending at the stamps ``ends``; ``waited``: how much the lag of
        each interval's end rose over its start's (s; None without ``received``)."""
        big = d > self._threshold()
        if waited is not None:              # nan (no evidence) compares False
            queued = (waited > max(self.factor * self.period, self.BEHIND_S)) & (d > self.factor * self.period)
            if queued.any():
                self.behind += int(np.count_nonzero(queued))
                big |= queued
        if not big.any():
            return 0
        gap = d[big]
        self.gaps += int(gap.size)
        self.missing += int(np.maximum(np.rint(gap / self.period) - 1, 0).sum())
        self.longest = max(self.longest, float(gap.max()))
        self.last_gap = (float(ends[big][-1]), float(gap[-1]))
        return int(gap.size)

    def cut(self):
        """The stream was cut (its clock jumped): the next stamp starts the intervals again, with no gap
        across the cut."""
        self.last = self.last_lag = None

    def hole(self, stamps) -> float | None:
        """The longest interval (s) of ``stamps`` (a stretch of this stream) that is a gap by this stream's
        standard, or None (none, or the stream not judged)."""
        t = np.asarray(stamps, dtype=float).reshape(-1)
        if self.period is None or not self.regular or t.size < 2:
            return None
        longest = float(np.max(np.diff(t)))
        return longest if longest > self._threshold() else None

    def summary(self) -> dict:
        """JSON-ready: gaps, missing (about), longest_gap_s, period_s, regular, last_gap_end_s, restarts, behind."""
        return {"gaps": self.gaps, "missing": self.missing, "longest_gap_s": self.longest, "period_s": self.period,
                "regular": self.regular, "last_gap_end_s": None if self.last_gap is None else self.last_gap[0],
                "restarts": self.restarts, "behind": self.behind}

    def describe(self, stream: str) -> str | None:
        """One line for a status message, or None without gaps (``describe_gaps`` of the summary)."""
        return describe_gaps(stream, self.summary())


def describe_gaps(stream: str, summary: dict) -> str | None:
    """One line for a person of a stream's ``StampGaps.summary`` (also as read back from a JSON report), or None
    without gaps."""
    if not summary["gaps"]:
        return None
    behind = summary.get("behind", 0)
    where = (f"; {behind} while this reader was behind: its queue overflowed, raise its depth or lighten its "
             f"callbacks" if behind else "")
    return (f"{stream}: {summary['gaps']} gap(s) in the stamps, the longest {summary['longest_gap_s']:.3g} s (about "
            f"{summary['missing']:,} message(s) at {summary['period_s']:.3g} s each lost on the way, or never sent{where})")
