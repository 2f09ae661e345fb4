"""rosbag2 recordings (sqlite3 or mcap) of measured poses (PoseStamped) and joint states, read and
written with the ``rosbags`` package (the real ROS 2 Jazzy message definitions; no ROS needed)."""
from __future__ import annotations

import struct
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from ...geometry import matrices_to_quat
from ...ingest import IngestError, JointOrder, pair_by_stamp, pose_from_values, stamp_seconds
from .measurements import MeasurementError, Measurements
from .text import _cut


def is_recording(path) -> bool:
    """Whether ``path`` names a rosbag2 recording (a folder, or a .db3 / .mcap file)."""
    p = Path(path)
    return p.is_dir() or p.suffix in (".db3", ".mcap")


def _decode(reader, raw, msgtype):
    """One message of a rosbags ``AnyReader``; IngestError when its bytes are not a ``msgtype``."""
    from rosbags.highlevel import AnyReaderError
    try:
        return reader.deserialize(raw, msgtype)
    except (AnyReaderError, struct.error, ValueError) as exc:  # rosbags 0.10 does not wrap the last two
        raise IngestError(f"cannot be decoded as {msgtype} ({_cut(str(exc), 80)})") from None


@contextmanager
def _recording(path):
    """A rosbags ``AnyReader`` on the recording ``path`` (ROS 2 Jazzy types); MeasurementError when there is none
    or it cannot be read."""
    from rosbags.highlevel import AnyReader, AnyReaderError
    from rosbags.rosbag2 import ReaderError
    from rosbags.typesys import Stores, get_typestore
    if not path.exists():
        raise MeasurementError(f"{path}: no such bag")
    try:
        with AnyReader([path], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
            yield reader
    except (AnyReaderError, ReaderError, FileNotFoundError) as exc:
        raise MeasurementError(f"{path}: not a readable rosbag2 recording ({exc})") from None


def _connections(reader, path, types):
    """The reader's connections on the topics of ``types`` ({topic: message type}); MeasurementError naming a
    topic that carries another type."""
    conns = [c for c in reader.connections if c.topic in types]
    for c in conns:
        if c.msgtype != types[c.topic]:
            raise MeasurementError(f"{path}: topic {c.topic} carries {c.msgtype}, expected {types[c.topic]}")
    return conns


def read_rosbag(path, joint_names=None, pose_topic="/measured_pose", joint_topic="/joint_states",
                slop: float = 0.005, skip_bad: bool = False) -> Measurements:
    """Measurements from a rosbag2 recording (sqlite3 or mcap) of PoseStamped and JointState.

    Each measured pose is paired with the joint state nearest to its header stamp within ``slop`` s.
    Unpaired measurements are an error unless ``skip_bad`` (then listed in ``skipped``).
    """
    path = Path(path)
    poses, pstamps, jstates, jstamps = [], [], [], []
    order = None
    skipped = []
    types = {pose_topic: "geometry_msgs/msg/PoseStamped", joint_topic: "sensor_msgs/msg/JointState"}
    with _recording(path) as reader:
        conns = _connections(reader, path, types)
        if not any(c.topic == pose_topic for c in conns):
            raise MeasurementError(f"{path}: no topic {pose_topic} "
                                   f"(topics: {sorted({c.topic for c in reader.connections})})")
        for k, (conn, _, raw) in enumerate(reader.messages(connections=conns)):
            try:
                msg = _decode(reader, raw, conn.msgtype)
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
        raise MeasurementError(f"{path}: no messages on {pose_topic}"
                               + (f" ({len(skipped)} skipped, the first: {skipped[0]['reason']})" if skipped else ""))
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


def _stamp(Time, t):
    """(builtin_interfaces/Time, nanoseconds) of ``t`` s."""
    ns = int(round(t * 1e9))
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000), ns


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
    with Writer(Path(path), version=9, storage_plugin=plugin) as w:
        cp = w.add_connection(pose_topic, PoseStamped.__msgtype__, typestore=ts)
        cj = w.add_connection(joint_topic, JointState.__msgtype__, typestore=ts) if m.joints is not None else None
        for i in range(len(m)):
            if cj is not None:
                tj, ns = _stamp(Time, m.stamps[i] + joint_offset_s)
                js = JointState(header=Header(stamp=tj, frame_id=""), name=list(m.joint_names),
                                position=np.asarray(m.joints[i], float), velocity=np.zeros(0), effort=np.zeros(0))
                w.write(cj, ns, ts.serialize_cdr(js, JointState.__msgtype__))
            tp, ns = _stamp(Time, m.stamps[i])
            p = m.T[i, :3, 3]
            q = quats[i]
            msg = PoseStamped(header=Header(stamp=tp, frame_id=frame_id),
                              pose=Pose(position=Point(x=p[0], y=p[1], z=p[2]),
                                        orientation=Quaternion(x=q[0], y=q[1], z=q[2], w=q[3])))
            w.write(cp, ns + 1, ts.serialize_cdr(msg, PoseStamped.__msgtype__))
    return Path(path)


def _topic(path, topics, suffixes):
    """The one topic of ``topics`` ending in one of ``suffixes`` (None if none; MeasurementError if several)."""
    found = sorted(t for t in topics if any(t == s or t.endswith("/" + s.lstrip("/")) for s in suffixes))
    if len(found) > 1:
        raise MeasurementError(f"{path}: several topics could be the stream ({', '.join(found)}); record one")
    return found[0] if found else None


def read_rosbag_streams(path, joint_names=None):
    """The two streams of a recording as they came (in the order recorded: stamps repeated, out of order or
    jumping are the path report's to put in order and say), unpaired: (point stamps (n,) s, points (n, 3) m, joint stamps
    (k,) s, joints (k, dof) in the order of ``joint_names``; both None when no joint states were recorded, or
    when ``joint_names`` is None: the points alone are read). Points
    from ``measured_point`` (PointStamped) or ``measured_pose`` (PoseStamped, its position), joints from
    ``joint_states`` (any namespace). A message that cannot be used is an error naming it: nothing is dropped."""
    path = Path(path)
    pts, pst, js, jst = [], [], [], []
    order = JointOrder(joint_names) if joint_names is not None else None
    with _recording(path) as reader:
        topics = {c.topic for c in reader.connections}
        ptopic = _topic(path, topics, ("measured_point", "measured_pose"))
        jtopic = _topic(path, topics, ("joint_states",))
        if ptopic is None:
            raise MeasurementError(f"{path}: no measured_point or measured_pose topic (topics: {sorted(topics)})")
        want = {ptopic: ("geometry_msgs/msg/PointStamped" if ptopic.endswith("measured_point")
                         else "geometry_msgs/msg/PoseStamped")}
        if jtopic is not None and order is not None:
            want[jtopic] = "sensor_msgs/msg/JointState"
        for k, (conn, _, raw) in enumerate(reader.messages(connections=_connections(reader, path, want))):
            try:
                msg = _decode(reader, raw, conn.msgtype)
                st = stamp_seconds(msg.header.stamp)
                if conn.topic == ptopic:
                    p = msg.point if conn.msgtype.endswith("PointStamped") else msg.pose.position
                    xyz = (float(p.x), float(p.y), float(p.z))
                    if not all(np.isfinite(xyz)):
                        raise IngestError(f"position {xyz} is not finite")
                    pts.append(xyz)
                    pst.append(st)
                else:
                    js.append(order(msg.name, msg.position))
                    jst.append(st)
            except IngestError as exc:
                raise MeasurementError(f"{path}: message {k} on {conn.topic}: {exc}") from None
    if not pts:
        raise MeasurementError(f"{path}: no messages on {ptopic}")
    joints = np.asarray(js, float) if js else None
    return np.asarray(pst), np.asarray(pts, float), (np.asarray(jst) if js else None), joints


def write_rosbag_streams(path, stamps, points, joint_stamps, joints, joint_names, storage="sqlite3",
                         point_topic="/measured_point", joint_topic="/joint_states") -> Path:
    """Write a tracker's points (PointStamped, m) and joint states (JointState) as they streamed, ROS 2 Jazzy types."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_JAZZY)
    T = ts.types
    Header, Time = T["std_msgs/msg/Header"], T["builtin_interfaces/msg/Time"]
    Point, PointStamped, JointState = T["geometry_msgs/msg/Point"], T["geometry_msgs/msg/PointStamped"], \
        T["sensor_msgs/msg/JointState"]
    events = [(t, 0, k) for k, t in enumerate(stamps)] + [(t, 1, k) for k, t in enumerate(joint_stamps)]
    events.sort()
    path = Path(path)
    plugin = {"sqlite3": StoragePlugin.SQLITE3, "mcap": StoragePlugin.MCAP}[storage]
    with Writer(path, version=9, storage_plugin=plugin) as w:
        cp = w.add_connection(point_topic, PointStamped.__msgtype__, typestore=ts)
        cj = w.add_connection(joint_topic, JointState.__msgtype__, typestore=ts)
        for t, kind, k in events:
            st, ns = _stamp(Time, t)
            if kind == 0:
                x, y, z = (float(v) for v in points[k])
                msg = PointStamped(header=Header(stamp=st, frame_id="tracker"), point=Point(x=x, y=y, z=z))
                w.write(cp, ns, ts.serialize_cdr(msg, PointStamped.__msgtype__))
            else:
                msg = JointState(header=Header(stamp=st, frame_id=""), name=list(joint_names),
                                 position=np.asarray(joints[k], float), velocity=np.empty(0), effort=np.empty(0))
                w.write(cj, ns, ts.serialize_cdr(msg, JointState.__msgtype__))
    return path
