"""One ingestion path for joint states and measured poses, live (duck-typed ROS messages) or recorded.

- ``stamp_seconds``: a ``builtin_interfaces/Time`` (sec, nanosec) as float seconds;
- ``JointOrder``: joint readings named in any order -> the model's joint order (extra joints ignored);
- ``pose_from_values``: a measured position (m) and quaternion (x, y, z, w) -> a validated 4x4 pose;
- ``StateBuffer`` and ``pair_by_stamp``: the joint state nearest in time to a measurement, within a slop.
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
