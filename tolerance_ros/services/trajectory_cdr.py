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
    the four float64 arrays (lists of (k_i,) arrays, as given) and time_from_start (m, 2) int64."""

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
    """The content of a serialized JointTrajectory; CdrError for bytes that are not one. The float64 arrays
    are read-only views into ``raw``; ``Trajectory.slots`` (m, 4) gives each one's index in the float64 view
    of the payload (-1 for an empty one), for ``replaced``."""
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
    arrays = ([], [], [], [])
    slots = np.full((m, 4), -1, np.int64)
    tfs = np.empty((m, 2), np.int64)
    empty = np.zeros(0)
    for i in range(m):
        for j in range(4):
            n, o = count(o, "float64[]")
            if n:
                o += (-(o - 4)) % 8
                if o + 8 * n > end:
                    raise CdrError(f"float64[{n}] at byte {o} does not fit")
                s = (o - 4) // 8
                arrays[j].append(doubles[s:s + n])
                slots[i, j] = s
                o += 8 * n
            else:
                arrays[j].append(empty)
        tfs[i, 0], o = i32(o)
        tfs[i, 1], o = u32(o)
    out = Trajectory((sec, nsec), frame, names, *arrays, tfs)
    out.slots = slots
    return out


def replaced(raw, t: Trajectory, positions, velocities=None, accelerations=None) -> bytes:
    """``raw`` with the float64 arrays of ``t`` (decoded from it) replaced: (m, k) positions and, where given,
    velocities and accelerations of the same shapes as those read; everything else byte for byte."""
    out = bytearray(raw)
    view = np.frombuffer(out, "<f8", (len(out) - 4) // 8, 4)
    for j, values in ((0, positions), (1, velocities), (2, accelerations)):
        if values is None:
            continue
        values = np.asarray(values, float)
        for i, s in enumerate(t.slots[:, j]):
            if s >= 0:
                view[s:s + values.shape[1]] = values[i]
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
