"""``trajectory_msgs/msg/JointTrajectory`` as its serialized bytes (little-endian CDR, the form rmw hands a
raw subscription), read into and written from arrays without building a Python object per point: a
100-point trajectory takes a fraction of a millisecond each way instead of the 2 ms of rclpy's message
conversion. Checked against the real Jazzy definitions and serialization of the ``rosbags`` package.

Layout (XCDR1, 4-byte encapsulation header, alignment from the end of that header): Header (stamp:
int32 sec, uint32 nanosec; string frame_id), string[] joint_names, JointTrajectoryPoint[] points (each
float64[] positions, velocities, accelerations, effort; Duration time_from_start: int32, uint32).
"""
from __future__ import annotations

import struct
from dataclasses import dataclass

import numpy as np

CDR_LE = b"\x00\x01\x00\x00"
MAX_ITEMS = 1_000_000


class CdrError(ValueError):
    """Bytes that are not a JointTrajectory; the message says where."""


@dataclass
class Trajectory:
    """A JointTrajectory's content: stamp (sec, nanosec), frame_id, joint_names, and per point (m of them)
    the four float64 arrays (each an (m, k) array when all points have k of them, else a list of (k_i,)
    arrays, as given) and time_from_start (m, 2) int64."""

    stamp: tuple
    frame_id: str
    joint_names: list
    positions: list
    velocities: list
    accelerations: list
    effort: list
    time_from_start: np.ndarray


_U32 = struct.Struct("<I").unpack_from
_I32 = struct.Struct("<i").unpack_from


def decode(raw) -> Trajectory:
    """The content of a serialized JointTrajectory; CdrError for bytes that are not one.
    ``Trajectory.slots`` (m, 4) gives each float64 array's index in the float64 view of the payload (-1 for
    an empty one), for ``replaced``. Points of one shape are read at once, not one by one."""
    b = bytes(raw)
    if len(b) < 4 or b[:2] != CDR_LE[:2]:
        raise CdrError("not little-endian CDR (encapsulation header 00 01)")
    end = len(b)
    doubles = np.frombuffer(b, "<f8", (end - 4) // 8, 4)

    def u32(o):
        o += (-(o - 4)) % 4
        if o + 4 > end:
            raise CdrError(f"truncated at byte {o}")
        return _U32(b, o)[0], o + 4

    def i32(o):
        o += (-(o - 4)) % 4
        if o + 4 > end:
            raise CdrError(f"truncated at byte {o}")
        return _I32(b, o)[0], o + 4

    def string(o):
        n, o = u32(o)
        if n == 0 or o + n > end:
            raise CdrError(f"a string of {n} bytes at byte {o} does not fit")
        return b[o:o + n - 1].decode("utf-8", errors="replace"), o + n

    def count(o, what):
        n, o = u32(o)
        if n > MAX_ITEMS:
            raise CdrError(f"{what}: {n} items")
        return n, o

    sec, o = i32(4)
    nsec, o = u32(o)
    frame, o = string(o)
    k, o = count(o, "joint_names")
    names = []
    for _ in range(k):
        name, o = string(o)
        names.append(name)
    m, o = count(o, "points")

    def point(o):
        """One point from byte ``o``: (sizes (4,), double offsets (4,) or -1, count offsets (4,), time
        offset, the end)."""
        sizes, slots, counts = [0] * 4, [-1] * 4, [0] * 4
        for j in range(4):
            o += (-(o - 4)) % 4
            counts[j] = o
            n, o = count(o, "float64[]")
            if n:
                o += (-(o - 4)) % 8
                if o + 8 * n > end:
                    raise CdrError(f"float64[{n}] at byte {o} does not fit")
                sizes[j], slots[j] = n, o
                o += 8 * n
        o += (-(o - 4)) % 4
        if o + 8 > end:
            raise CdrError(f"truncated at byte {o}")
        return sizes, slots, counts, o, o + 8

    parsed = []
    for _ in range(min(m, 3)):
        parsed.append(point(o))
        o = parsed[-1][4]
    layout = _uniform(b, parsed, m, end) if m > 3 else None
    if layout is None:
        for _ in range(m - len(parsed)):
            parsed.append(point(o))
            o = parsed[-1][4]
        sizes = np.array([p[0] for p in parsed], np.int64).reshape(m, 4)
        byte_slots = np.array([p[1] for p in parsed], np.int64).reshape(m, 4)
        times = np.array([p[3] for p in parsed], np.int64)
    else:
        sizes, byte_slots, times = layout
    slots = np.where(byte_slots >= 0, (byte_slots - 4) // 8, -1)
    tfs = np.empty((m, 2), np.int64)
    if m:
        words = (times - 4) // 4
        tfs[:, 0] = np.frombuffer(b, "<i4", (end - 4) // 4, 4)[words]
        tfs[:, 1] = np.frombuffer(b, "<u4", (end - 4) // 4, 4)[words + 1]
    arrays = [_rows(doubles, slots[:, j], sizes[:, j]) for j in range(4)]
    out = Trajectory((sec, nsec), frame, names, *arrays, tfs)
    out.slots = slots
    return out


def _uniform(b, parsed, m, end):
    """(sizes (m, 4), double byte offsets (m, 4), time byte offsets (m,)) when every point after the first
    has the sizes of the second: the layout then repeats every two points (alignment depends only on the
    offset modulo 8), so it is computed at once and every count in the bytes checked against it; None when
    the points differ (the caller reads them one by one)."""
    (_, _, _, _, s1), (n1, sl1, c1, t1, s2), (n2, sl2, c2, t2, s3) = parsed
    if n1 != n2:
        return None
    d1, d2 = s2 - s1, s3 - s2
    i = np.arange(m - 1)
    odd = i % 2
    start = s1 + (i // 2) * (d1 + d2) + odd * d1
    last_end = start[-1] + (d2 if odd[-1] else d1)
    if last_end > end:
        return None
    rel = np.array([[c - s1 for c in c1], [c - s2 for c in c2]])
    counts = start[:, None] + rel[odd]
    n = np.array(n1, np.int64)
    words = np.frombuffer(b, "<u4", (end - 4) // 4, 4)
    if not np.array_equal(words[(counts - 4) // 4], np.broadcast_to(n, counts.shape)):
        return None
    rel_slots = np.array([[x - s1 if x >= 0 else -1 for x in sl1], [x - s2 if x >= 0 else -1 for x in sl2]])
    slots = np.where(n > 0, start[:, None] + rel_slots[odd], -1)
    times = start + np.array([t1 - s1, t2 - s2])[odd]
    n0, sl0, _, t0, _ = parsed[0]
    return (np.vstack([n0, np.broadcast_to(n, (m - 1, 4))]), np.vstack([sl0, slots]),
            np.concatenate([[t0], times]))


def _rows(doubles, slots, sizes):
    """The float64 arrays at ``slots`` (index into ``doubles``, -1 for empty) of ``sizes``: one (m, n)
    array when all have the same size n, else a list of (n_i,) arrays."""
    m = len(slots)
    if m and np.all(sizes == sizes[0]):
        n = int(sizes[0])
        if n == 0:
            return np.zeros((m, 0))
        return doubles[slots[:, None] + np.arange(n)]
    return [doubles[s:s + n] if n else np.zeros(0) for s, n in zip(slots.tolist(), sizes.tolist())]


def replaced(raw, t: Trajectory, positions, velocities=None, accelerations=None) -> bytes:
    """``raw`` with the float64 arrays of ``t`` (decoded from it) replaced: (m, k) positions and, where given,
    velocities and accelerations of the same shapes as those read; everything else byte for byte."""
    out = bytearray(raw)
    view = np.frombuffer(out, "<f8", (len(out) - 4) // 8, 4)
    for j, values in ((0, positions), (1, velocities), (2, accelerations)):
        if values is None:
            continue
        values = np.asarray(values, float)
        rows = np.flatnonzero(t.slots[:, j] >= 0)
        view[t.slots[rows, j][:, None] + np.arange(values.shape[1])] = values[rows]
    return bytes(out)


class _Writer:
    def __init__(self):
        self.parts = [CDR_LE]
        self.o = 4

    def _put(self, data):
        self.parts.append(data)
        self.o += len(data)

    def align(self, n):
        pad = (-(self.o - 4)) % n
        if pad:
            self._put(b"\x00" * pad)

    def u32(self, v):
        self.align(4)
        self._put(struct.pack("<I", v))

    def i32(self, v):
        self.align(4)
        self._put(struct.pack("<i", v))

    def string(self, s):
        data = s.encode("utf-8") + b"\x00"
        self.u32(len(data))
        self._put(data)

    def doubles(self, a):
        a = np.ascontiguousarray(a, "<f8").reshape(-1)
        self.u32(len(a))
        if len(a):
            self.align(8)
            self._put(a.tobytes())


def encode(t: Trajectory) -> bytes:
    """The serialized JointTrajectory of ``t``."""
    w = _Writer()
    w.i32(int(t.stamp[0]))
    w.u32(int(t.stamp[1]))
    w.string(t.frame_id)
    w.u32(len(t.joint_names))
    for n in t.joint_names:
        w.string(n)
    m = len(t.positions)
    w.u32(m)
    for i in range(m):
        for arrays in (t.positions, t.velocities, t.accelerations, t.effort):
            w.doubles(arrays[i])
        w.i32(int(t.time_from_start[i, 0]))
        w.u32(int(t.time_from_start[i, 1]))
    return b"".join(w.parts)
