"""Measurements in and out: CSV files, the accuracy monitor's campaign log (JSON Lines) and rosbag2
recordings (sqlite3 or mcap, read with the ``rosbags`` package).

CSV format: optional ``#`` comment lines, then a header naming each column with its unit in brackets::

    stamp[s],pose,cycle,x[mm],y[mm],z[mm],roll[deg],pitch[deg],yaw[deg],joint:joint1[rad],...

``x y z`` is the measured tool position, ``roll pitch yaw`` its orientation (``R = Rz(yaw) Ry(pitch)
Rx(roll)``; optional, or ``qx qy qz qw`` quaternion columns instead), ``pose`` the test pose name and
``cycle`` its 0-based cycle (both optional), ``joint:<name>`` the joint reading at the measurement
(rad or deg for revolute, m or mm for prismatic). Lengths: m, mm, um; angles: rad, deg, mrad.
Stamps must not decrease. A malformed row stops the read with its line number, unless the caller
asks to skip bad rows; skipped rows are then listed, never dropped silently.

Campaign log of the accuracy monitor (JSON Lines of events, SI)::

    {"event": "measurement", "seq": 7, "stamp": 12.5, "frame": "tracker", "position": [x, y, z],
     "quaternion": [qx, qy, qz, qw]}                        # written the moment it arrives
    {"event": "paired", "seq": 7, "joint_stamp": 12.49, "joint_names": [...], "joints": [...],
     "pose": "P1" | null, "verdict": "within", ...}           # written when its joint state is known
    {"event": "unpaired", "seq": 8, "reason": "..."}
"""
from __future__ import annotations

import csv
import json
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..geometry import matrices_to_quat, quat_to_matrices, rpy_from_matrix, rpy_to_matrices
from ..ingest import IngestError, JointOrder, pair_by_stamp, pose_from_values, stamp_seconds
from ..units import ANGLE_UNITS, LENGTH_UNITS

_COL = re.compile(r"^\s*([A-Za-z_][\w:.\-/]*)\s*(?:\[\s*([^\]]*)\s*\])?\s*$")


class MeasurementError(ValueError):
    """A measurement file or message that cannot be read; the message gives its position."""


@dataclass
class Measurements:
    """Measured tool poses (SI) with their stamps, optional joints and test-pose labels."""

    stamps: np.ndarray
    T: np.ndarray
    joints: np.ndarray | None = None
    joint_names: tuple = ()
    pose: np.ndarray | None = None
    cycle: np.ndarray | None = None
    has_orientation: bool = True
    source: str = ""
    skipped: list = field(default_factory=list)

    def __len__(self):
        return len(self.stamps)


def _parse_header(header, source):
    cols = {}
    for i, h in enumerate(header):
        m = _COL.match(h)
        if not m:
            raise MeasurementError(f"{source}: header column {i + 1} {h!r} is not 'name[unit]'")
        name, unit = m.group(1), (m.group(2) or "").strip()
        if name in cols:
            raise MeasurementError(f"{source}: column {name!r} appears twice")
        cols[name] = (i, unit)
    return cols


def _scale(name, unit, kinds, source):
    if kinds == "length":
        if unit not in LENGTH_UNITS:
            raise MeasurementError(f"{source}: column {name!r} needs a length unit in brackets "
                                   f"({', '.join(sorted(LENGTH_UNITS))}), got {unit!r}")
        return LENGTH_UNITS[unit]
    if kinds == "angle":
        if unit not in ANGLE_UNITS:
            raise MeasurementError(f"{source}: column {name!r} needs an angle unit in brackets "
                                   f"({', '.join(sorted(ANGLE_UNITS))}), got {unit!r}")
        return ANGLE_UNITS[unit]
    raise MeasurementError(f"{source}: column {name!r}: unknown quantity")


def read_csv(path, skip_bad: bool = False, chunk_rows: int | None = None):
    """Measurements from a CSV file (see the module docstring).

    With ``chunk_rows`` it yields ``Measurements`` of at most that many rows (constant memory);
    otherwise it returns one ``Measurements``.
    """
    gen = _read_csv_chunks(Path(path), skip_bad, chunk_rows or 0)
    if chunk_rows:
        return gen
    parts = list(gen)
    if not parts:
        raise MeasurementError(f"{path}: no measurements")
    return concat(parts)


_TIME_UNITS = {"": 1.0, "s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}


def _read_csv_chunks(path, skip_bad, chunk_rows):
    source = str(path)
    if not path.is_file():
        raise MeasurementError(f"{source}: file not found")
    with path.open(newline="") as fh:
        header, cols, spec = None, None, None
        raw, skipped, last = [], [], -np.inf
        for lineno, line in enumerate(fh, start=1):
            if not line.strip() or line.lstrip().startswith("#"):
                continue
            row = next(csv.reader([line]))
            if header is None:
                header = row
                cols = _parse_header(header, source)
                missing = [c for c in ("stamp", "x", "y", "z") if c not in cols]
                if missing:
                    raise MeasurementError(f"{source}: missing column(s) {missing}; header is {header}")
                has_rpy = all(c in cols for c in ("roll", "pitch", "yaw"))
                has_quat = all(c in cols for c in ("qx", "qy", "qz", "qw"))
                if any(c in cols for c in ("roll", "pitch", "yaw")) and not has_rpy:
                    raise MeasurementError(f"{source}: orientation needs all of roll, pitch, yaw")
                if cols["stamp"][1] not in _TIME_UNITS:
                    raise MeasurementError(f"{source}: column 'stamp' needs a time unit (s, ms, us, ns), "
                                           f"got {cols['stamp'][1]!r}")
                s_stamp = _TIME_UNITS[cols["stamp"][1]]
                s_pos = [_scale(c, cols[c][1], "length", source) for c in ("x", "y", "z")]
                s_ang = [_scale(c, cols[c][1], "angle", source) for c in ("roll", "pitch", "yaw")] if has_rpy else None
                joint_cols = [(c[len("joint:"):], cols[c]) for c in cols if c.startswith("joint:")]
                s_joint = []
                for name, (_, unit) in joint_cols:
                    kind = "angle" if unit in ANGLE_UNITS else "length" if unit in LENGTH_UNITS else None
                    if kind is None:
                        raise MeasurementError(f"{source}: column 'joint:{name}' needs a unit (rad, deg, m, mm), "
                                               f"got {unit!r}")
                    s_joint.append(_scale(f"joint:{name}", unit, kind, source))
                spec = (s_stamp, s_pos, s_ang, has_quat, joint_cols, s_joint)
                continue
            raw.append((lineno, row))
            if chunk_rows and len(raw) >= chunk_rows:
                recs, bad, last = _convert(raw, header, cols, spec, last, skip_bad, source)
                skipped += bad
                yield _pack(recs, joint_cols, has_rpy or has_quat, source, skipped)
                raw, skipped = [], []
        if header is None:
            raise MeasurementError(f"{source}: empty file (no header)")
        if raw:
            recs, bad, last = _convert(raw, header, cols, spec, last, skip_bad, source)
            skipped += bad
            yield _pack(recs, joint_cols, has_rpy or has_quat, source, skipped)


def _convert(raw, header, cols, spec, last, skip_bad, source):
    """Rows -> records. Fast path: numeric columns converted by numpy in one go; any problem falls back
    to row-by-row parsing, which names the line (or skips and lists it)."""
    s_stamp, s_pos, s_ang, has_quat, joint_cols, s_joint = spec
    try:
        if any(len(r) != len(header) for _, r in raw):
            raise ValueError
        num_cols = [cols["stamp"][0]] + [cols[c][0] for c in ("x", "y", "z")]
        if s_ang is not None:
            num_cols += [cols[c][0] for c in ("roll", "pitch", "yaw")]
        elif has_quat:
            num_cols += [cols[c][0] for c in ("qx", "qy", "qz", "qw")]
        num_cols += [i for _, (i, _) in joint_cols]
        A = np.array([[r[i] for i in num_cols] for _, r in raw], dtype=float)
        if not np.all(np.isfinite(A)):
            raise ValueError
        stamps = A[:, 0] * s_stamp
        if stamps[0] < last or np.any(np.diff(stamps) < 0):
            raise ValueError
        cyc = [r[cols["cycle"][0]].strip() for _, r in raw] if "cycle" in cols else None
        cycles = np.array([int(c) if c else -1 for c in cyc]) if cyc is not None else np.full(len(raw), -1)
        if cyc is not None and any(c and (not c.isdigit()) for c in cyc):
            raise ValueError
    except ValueError:
        return _convert_slow(raw, header, cols, spec, last, skip_bad, source)
    k = 4
    pos = A[:, 1:4] * s_pos
    if s_ang is not None:
        orient, k = ("rpy", A[:, 4:7] * s_ang), 7
    elif has_quat:
        orient, k = ("quat", A[:, 4:8]), 8
    else:
        orient = None
    joints = A[:, k:] * np.array(s_joint) if joint_cols else np.zeros((len(raw), 0))
    poses = [r[cols["pose"][0]].strip() if "pose" in cols else "" for _, r in raw]
    recs = _Block(stamps, pos, orient, poses, cycles, joints)
    return recs, [], float(stamps[-1])


def _convert_slow(raw, header, cols, spec, last, skip_bad, source):
    s_stamp, s_pos, s_ang, has_quat, joint_cols, s_joint = spec
    buf, skipped = [], []
    for lineno, row in raw:
        try:
            if len(row) != len(header):
                raise MeasurementError(f"expected {len(header)} columns, got {len(row)}")
            rec = _parse_row(row, cols, s_stamp, s_pos, s_ang, has_quat, joint_cols, s_joint)
            if rec[0] < last:
                raise MeasurementError(f"stamp {rec[0]:.9g} s is earlier than the previous row's {last:.9g} s "
                                       f"(stamps must not decrease)")
        except MeasurementError as exc:
            if not skip_bad:
                raise MeasurementError(f"{source}, line {lineno}: {exc}") from None
            skipped.append({"line": lineno, "reason": str(exc)})
            continue
        last = rec[0]
        buf.append(rec)
    n = len(buf)
    orient = None
    if s_ang is not None or has_quat:
        orient = ("rpy" if s_ang is not None else "quat", np.array([r[2][1] for r in buf]).reshape(n, -1))
    block = _Block(np.array([r[0] for r in buf], float), np.array([r[1] for r in buf], float).reshape(n, 3), orient,
                   [r[3] for r in buf], np.array([r[4] for r in buf], int),
                   np.array([r[5] for r in buf], float).reshape(n, len(joint_cols)))
    return block, skipped, last


class _Block:
    """Parsed rows of one chunk, column-wise (SI)."""

    def __init__(self, stamps, pos, orient, poses, cycles, joints):
        self.stamps, self.pos, self.orient, self.poses, self.cycles, self.joints = \
            stamps, pos, orient, poses, cycles, joints


def _num(text, what):
    try:
        v = float(text)
    except ValueError:
        raise MeasurementError(f"{what}: {text!r} is not a number") from None
    if not np.isfinite(v):
        raise MeasurementError(f"{what}: {text!r} is not finite")
    return v


def _parse_row(row, cols, s_stamp, s_pos, s_ang, has_quat, joint_cols, s_joint):
    stamp = _num(row[cols["stamp"][0]], "stamp") * s_stamp
    p = [_num(row[cols[c][0]], c) * s for c, s in zip(("x", "y", "z"), s_pos)]
    if s_ang is not None:
        o = ("rpy", [_num(row[cols[c][0]], c) * s for c, s in zip(("roll", "pitch", "yaw"), s_ang)])
    elif has_quat:
        o = ("quat", [_num(row[cols[c][0]], c) for c in ("qx", "qy", "qz", "qw")])
    else:
        o = None
    pose = row[cols["pose"][0]].strip() if "pose" in cols else ""
    cycle = -1
    if "cycle" in cols and row[cols["cycle"][0]].strip():
        c = _num(row[cols["cycle"][0]], "cycle")
        if c != int(c) or c < 0:
            raise MeasurementError(f"cycle: expected a non-negative integer, got {row[cols['cycle'][0]]!r}")
        cycle = int(c)
    joints = [_num(row[i], f"joint:{n}") * s for (n, (i, _)), s in zip(joint_cols, s_joint)]
    return stamp, p, o, pose, cycle, joints


def _pack(block, joint_cols, has_orientation, source, skipped):
    n = len(block.stamps)
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, :3, 3] = block.pos
    if has_orientation and n:
        kind, vals = block.orient
        if kind == "rpy":
            T[:, :3, :3] = rpy_to_matrices(vals)
        else:
            try:
                T[:, :3, :3] = quat_to_matrices(vals)
            except ValueError as exc:
                raise MeasurementError(f"{source}: {exc}") from None
    joints = block.joints if joint_cols else None
    return Measurements(block.stamps, T, joints, tuple(n for n, _ in joint_cols),
                        np.array(block.poses, dtype=object), np.asarray(block.cycles, dtype=int), has_orientation,
                        source, list(skipped))


def concat(parts) -> Measurements:
    """One Measurements from several chunks of the same source."""
    parts = list(parts)
    first = parts[0]
    return Measurements(np.concatenate([p.stamps for p in parts]), np.concatenate([p.T for p in parts]),
                        None if first.joints is None else np.concatenate([p.joints for p in parts]),
                        first.joint_names,
                        np.concatenate([p.pose for p in parts]) if first.pose is not None else None,
                        np.concatenate([p.cycle for p in parts]) if first.cycle is not None else None,
                        first.has_orientation, first.source, [s for p in parts for s in p.skipped])


def write_csv(path, m: Measurements, comments=(), length_unit="mm", angle_unit="deg") -> Path:
    """Write measurements in the CSV format above (positions and angles in the given units)."""
    path = Path(path)
    ls, as_ = LENGTH_UNITS[length_unit], ANGLE_UNITS[angle_unit]
    rpy = rpy_from_matrix(m.T[:, :3, :3]) / as_
    pos = m.T[:, :3, 3] / ls
    header = ["stamp[s]", "pose", "cycle"] + [f"{c}[{length_unit}]" for c in "xyz"] + \
        [f"{c}[{angle_unit}]" for c in ("roll", "pitch", "yaw")] + \
        [f"joint:{n}[rad]" for n in m.joint_names]
    with path.open("w", newline="") as fh:
        for c in comments:
            fh.write(f"# {c}\n")
        w = csv.writer(fh)
        w.writerow(header)
        for i in range(len(m)):
            row = [f"{m.stamps[i]:.6f}", m.pose[i] if m.pose is not None else "",
                   int(m.cycle[i]) if m.cycle is not None and m.cycle[i] >= 0 else ""]
            row += [f"{v:.6f}" for v in pos[i]] + [f"{v:.7f}" for v in rpy[i]]
            if m.joints is not None:
                row += [f"{v:.9f}" for v in m.joints[i]]
            w.writerow(row)
    return path


def read_log(path, skip_bad=False) -> Measurements:
    """Measurements (with joints) rebuilt from the accuracy monitor's campaign log (JSON Lines of events:
    ``measurement`` as it arrived, then ``paired`` or ``unpaired``); unpaired, rejected and undecided
    measurements are listed in ``skipped`` with their reason."""
    path = Path(path)
    if not path.is_file():
        raise MeasurementError(f"{path}: file not found")
    meas, pairs, skipped, names = {}, {}, [], None
    with path.open() as fh:
        for lineno, line in enumerate(fh, start=1):
            if not line.strip():
                continue
            try:
                rec = json.loads(line)
                ev = rec.get("event")
                if ev == "measurement":
                    if "rejected" in rec:
                        skipped.append({"seq": rec["seq"], "reason": rec["rejected"]})
                    else:
                        meas[rec["seq"]] = (float(rec["stamp"]), rec["position"], rec["quaternion"])
                elif ev == "paired":
                    pairs[rec["seq"]] = (rec["joints"], rec.get("pose") or "")
                    names = names or tuple(rec["joint_names"])
                elif ev == "unpaired":
                    skipped.append({"seq": rec["seq"], "reason": rec["reason"]})
            except (ValueError, KeyError, TypeError) as exc:
                if not skip_bad:
                    raise MeasurementError(f"{path}, line {lineno}: {exc}") from None
                skipped.append({"line": lineno, "reason": str(exc)})
    for seq in sorted(set(meas) - set(pairs) - {s.get("seq") for s in skipped}):
        skipped.append({"seq": seq, "reason": "pairing not decided before the log ended"})
    seqs = sorted(set(meas) & set(pairs))
    if not seqs:
        raise MeasurementError(f"{path}: no paired measurements")
    T = np.tile(np.eye(4), (len(seqs), 1, 1))
    T[:, :3, :3] = quat_to_matrices(np.array([meas[s][2] for s in seqs]))
    T[:, :3, 3] = [meas[s][1] for s in seqs]
    return Measurements(np.array([meas[s][0] for s in seqs]), T, np.array([pairs[s][0] for s in seqs], float),
                        names or (), np.array([pairs[s][1] for s in seqs], dtype=object), np.full(len(seqs), -1),
                        True, str(path), skipped)


def read_rosbag(path, joint_names=None, pose_topic="/measured_pose", joint_topic="/joint_states",
                slop: float = 0.005, skip_bad: bool = False) -> Measurements:
    """Measurements from a rosbag2 recording (sqlite3 or mcap) of PoseStamped and JointState.

    Each measured pose is paired with the joint state nearest to its header stamp within ``slop`` s.
    Unpaired measurements are an error unless ``skip_bad`` (then listed in ``skipped``).
    """
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    path = Path(path)
    if not path.exists():
        raise MeasurementError(f"{path}: no such bag")
    poses, pstamps, jstates, jstamps = [], [], [], []
    order = None
    skipped = []
    with AnyReader([path], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        conns = [c for c in reader.connections if c.topic in (pose_topic, joint_topic)]
        if not any(c.topic == pose_topic for c in conns):
            raise MeasurementError(f"{path}: no topic {pose_topic} (topics: {sorted({c.topic for c in reader.connections})})")
        for k, (conn, _, raw) in enumerate(reader.messages(connections=conns)):
            msg = reader.deserialize(raw, conn.msgtype)
            try:
                st = stamp_seconds(msg.header.stamp)
                if conn.topic == pose_topic:
                    p, o = msg.pose.position, msg.pose.orientation
                    poses.append(pose_from_values((p.x, p.y, p.z), (o.x, o.y, o.z, o.w)))
                    pstamps.append(st)
                else:
                    if order is None:
                        order = JointOrder(joint_names or msg.name)
                    jstates.append(order(msg.name, msg.position))
                    jstamps.append(st)
            except IngestError as exc:
                err = f"message {k} on {conn.topic}: {exc}"
                if not skip_bad:
                    raise MeasurementError(f"{path}: {err}") from None
                skipped.append({"message": k, "reason": err})
    if not poses:
        raise MeasurementError(f"{path}: no messages on {pose_topic}")
    by_time = np.argsort(pstamps, kind="stable")
    pst = np.array(pstamps)[by_time]
    T = np.array(poses)[by_time]
    joints = None
    if jstates:
        pair = pair_by_stamp(pst, jstamps, slop)
        if np.any(pair < 0):
            bad = np.flatnonzero(pair < 0)
            err = (f"{len(bad)} measured pose(s) have no joint state within {slop} s "
                   f"(first at stamp {pst[bad[0]]:.9f} s)")
            if not skip_bad:
                raise MeasurementError(f"{path}: {err}")
            skipped += [{"measurement": int(i), "reason": f"unpaired measurement at stamp {pst[i]:.9f} s"} for i in bad]
            keep = pair >= 0
            pst, T, pair = pst[keep], T[keep], pair[keep]
        joints = np.array(jstates)[pair]
    return Measurements(pst, T, joints, order.joint_names if order else (), np.array([""] * len(pst), dtype=object),
                        np.full(len(pst), -1), True, str(path), skipped)


def write_rosbag(path, m: Measurements, storage="sqlite3", pose_topic="/measured_pose", joint_topic="/joint_states",
                 frame_id="tracker", joint_offset_s=0.0) -> Path:
    """Write measurements as a rosbag2 recording (PoseStamped + JointState, ROS 2 Jazzy types)."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_JAZZY)
    T = ts.types
    Header, Time = T["std_msgs/msg/Header"], T["builtin_interfaces/msg/Time"]
    PoseStamped, Pose = T["geometry_msgs/msg/PoseStamped"], T["geometry_msgs/msg/Pose"]
    Point, Quaternion = T["geometry_msgs/msg/Point"], T["geometry_msgs/msg/Quaternion"]
    JointState = T["sensor_msgs/msg/JointState"]
    plugin = {"sqlite3": StoragePlugin.SQLITE3, "mcap": StoragePlugin.MCAP}[storage]
    quats = matrices_to_quat(m.T[:, :3, :3])

    def stamp(t):
        ns = int(round(t * 1e9))
        return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000), ns

    with Writer(Path(path), version=9, storage_plugin=plugin) as w:
        cp = w.add_connection(pose_topic, PoseStamped.__msgtype__, typestore=ts)
        cj = w.add_connection(joint_topic, JointState.__msgtype__, typestore=ts) if m.joints is not None else None
        for i in range(len(m)):
            if cj is not None:
                tj, ns = stamp(m.stamps[i] + joint_offset_s)
                js = JointState(header=Header(stamp=tj, frame_id=""), name=list(m.joint_names),
                                position=np.asarray(m.joints[i], float), velocity=np.zeros(0), effort=np.zeros(0))
                w.write(cj, ns, ts.serialize_cdr(js, JointState.__msgtype__))
            tp, ns = stamp(m.stamps[i])
            p = m.T[i, :3, 3]
            q = quats[i]
            msg = PoseStamped(header=Header(stamp=tp, frame_id=frame_id),
                              pose=Pose(position=Point(x=p[0], y=p[1], z=p[2]),
                                        orientation=Quaternion(x=q[0], y=q[1], z=q[2], w=q[3])))
            w.write(cp, ns + 1, ts.serialize_cdr(msg, PoseStamped.__msgtype__))
    return Path(path)


def read_measurements(path, joint_names=None, skip_bad=False, slop=0.005):
    """Measurements from a CSV file, a campaign log (.jsonl) or a rosbag2 directory / .db3 / .mcap."""
    p = Path(path)
    if p.is_dir() or p.suffix in (".db3", ".mcap"):
        return read_rosbag(p, joint_names=joint_names, skip_bad=skip_bad, slop=slop)
    if p.suffix in (".jsonl", ".log"):
        return read_log(p, skip_bad=skip_bad)
    return read_csv(p, skip_bad=skip_bad)
