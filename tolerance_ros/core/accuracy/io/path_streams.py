"""The two streams of a path test, read in one place: the tracker's points (points CSV, campaign log, or a
rosbag2 recording of both streams) and the command (the joint states as a controller logs them, the joint
trajectory as sent, or the joints recorded beside the points). SI; every error is a ``MeasurementError``
naming the file."""
from __future__ import annotations

import numpy as np

from .measurements import MeasurementError

JOINT_RATE = 500.0   # Hz: a trajectory file's joints are sampled at this rate to make the command path


def read_command(model, measurements, joint_states=None, trajectory=None, recorded=None, ignored=None):
    """(joint stamps (k,) s, joints (k, dof), the trajectory or None, where from) of the command: from
    ``joint_states`` (CSV), ``trajectory`` (a joint trajectory file, sampled at ``JOINT_RATE``), ``recorded``
    (the (stamps, joints) of the recording ``measurements`` names), or else the joint columns of
    ``measurements``. The joint columns of ``joint_states`` the robot does not have are appended to
    ``ignored``."""
    from . import read_measurements
    if joint_states and trajectory:
        raise MeasurementError("--joint-states, --trajectory: give one of them (the command's joints)")
    if joint_states:
        from .joint_states import read_joint_states
        tj, qj = read_joint_states(joint_states, model.joint_names, model.joint_types, ignored)
        return tj, model.check_joints(qj, joint_states), None, joint_states
    if trajectory:
        from ..iso_paths import read_trajectory
        jp = read_trajectory(trajectory, model)
        tj = np.arange(int(jp.duration * JOINT_RATE) + 1) / JOINT_RATE
        return tj, jp.at(tj), jp, trajectory
    if recorded is not None:
        tj, qj = recorded
        if tj is None:
            raise MeasurementError(f"{measurements}: no joint states recorded; give the commanded joints with "
                                   f"--joint-states or --trajectory")
        return tj, model.check_joints(qj, measurements), None, measurements
    m = read_measurements(measurements, joint_names=model.joint_names)
    if m.joints is None:
        raise MeasurementError(f"{measurements}: no joint columns; give the commanded joints with --joint-states or "
                               f"--trajectory")
    if m.pose is not None and any(str(v) for v in m.pose):
        raise MeasurementError(f"{measurements}: not a path: its rows are named by test pose (a static campaign); "
                               f"judge it with `tolerance-ros report`, or give the joint states streamed along the "
                               f"path with --joint-states")
    return m.stamps, model.check_joints(m.joints, measurements), None, measurements


def read_streams(model, measurements, joint_states=None, trajectory=None, ignored=None):
    """(stamps (n,) s, points (n, 3) m, source, (joint stamps, joints, trajectory or None, its source)) of the
    tracker's points in ``measurements`` and of the command (``read_command``); a rosbag2 recording of both
    streams is read once."""
    from .joint_states import read_points
    from .rosbag import is_recording, read_rosbag_streams
    recorded = None
    if is_recording(measurements) and not (joint_states or trajectory):
        stamps, points, *recorded = read_rosbag_streams(measurements, model.joint_names)
        source = str(measurements)
    else:
        stamps, points, source = read_points(measurements)
    return stamps, points, source, read_command(model, measurements, joint_states, trajectory, recorded, ignored)
