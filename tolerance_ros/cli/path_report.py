"""`tolerance-ros path-report`: ISO 9283 path characteristics of a tracker's stream along a commanded path,
with the tracker's latency measured."""
from __future__ import annotations

import numpy as np

from ..core.budget import load_budget
from ..render.text import table
from .common import CLIError, limit_option, load_model, missed, point_option, quantity

NAME = "path-report"
HELP = "ISO 9283 path accuracy of a tracker's stream along a commanded path (AT, RT, CR, CO, AV, RV, FV, latency)"
ROBOT = True
MAX_STATIONS = 10_000
JOINT_RATE = 500.0   # Hz: a trajectory file's joints are sampled at this rate to make the command path


def add_arguments(p):
    p.add_argument("--measurements", required=True,
                   help="the tracker's points: CSV (stamp[s] and x,y,z), campaign log (.jsonl) or rosbag2")
    p.add_argument("--joint-states", metavar="JOINTS",
                   help="CSV of stamp[s] and joint:NAME[rad] columns, as a controller logs them (default: the joints "
                        "of the measurement rows)")
    p.add_argument("--trajectory", metavar="FILE",
                   help="the joint trajectory as sent (plan-campaign --path, or a compensated one): its start on the "
                        "tracker's clock is found by the speeds' cross-correlation")
    p.add_argument("--registration", choices=["base", "none"], default="base",
                   help="fit the tracker's placement (base, default) or take the points as base-frame (none)")
    p.add_argument("--target-offset", metavar="X,Y,Z",
                   help="the tracked target's position on the tool frame, a unit on each (e.g. 0mm,0mm,120mm; default: "
                        "the tool frame's origin). Along a path of constant orientation (the standard's test paths) an "
                        "offset is a translation the base registration absorbs, so it is not fitted: give it when the "
                        "orientation changes")
    p.add_argument("--budget", help="tolerance budget: the bound tube along the path and the verdicts")
    p.add_argument("--reverse", action="store_true",
                   help="judge the return strokes (the test path driven backwards, as a line driven back and forth "
                        "does) as the cycles, instead of the forward ones")
    p.add_argument("--latency", help="the tracker's latency, given (e.g. 8ms) instead of estimated")
    p.add_argument("--latency-window",
                   help="look for the latency within +- this about zero only (e.g. 100ms; default: of any size, a "
                        "coarse search over the two streams' whole overlap, then a fine one about it)")
    p.add_argument("--stations", type=int, default=100, help="calculation points per segment (default 100)")
    p.add_argument("--speed-window", default="10ms",
                   help="speeds are central differences over +- this (default 10ms)")
    p.add_argument("--band", default="0.1mm",
                   help="the stabilisation band about the pose attained at each stop (default 0.1mm): the pose "
                        "stabilisation time and overshoot (docs/path-accuracy.md)")
    p.add_argument("--out", metavar="DIR", help="write path_report.json, path_report.md and plots into DIR")


def _command(args, model, recorded=None, ignored=None):
    """(joint stamps, joints, the trajectory or None, where from) of the command; ``recorded``: the (joint
    stamps, joints) of the recording ``--measurements`` names (None for another file); the joint columns of
    ``--joint-states`` the robot does not have are appended to ``ignored``."""
    from ..core.accuracy.io import read_measurements
    if args.joint_states and args.trajectory:
        raise CLIError("--joint-states, --trajectory: give one of them (the command's joints)")
    if args.joint_states:
        from ..core.accuracy.io.joint_states import read_joint_states
        tj, qj = read_joint_states(args.joint_states, model.joint_names, model.joint_types, ignored)
        return tj, model.check_joints(qj, args.joint_states), None, args.joint_states
    if args.trajectory:
        from ..core.accuracy.iso_paths import read_trajectory
        try:
            jp = read_trajectory(args.trajectory, model)
        except ValueError as exc:
            raise CLIError(str(exc)) from None
        tj = np.arange(int(jp.duration * JOINT_RATE) + 1) / JOINT_RATE
        return tj, jp.at(tj), jp, args.trajectory
    if recorded is not None:  # a recording: its joint states as they streamed
        tj, qj = recorded
        if tj is None:
            raise CLIError(f"{args.measurements}: no joint states recorded; give the commanded joints with "
                           f"--joint-states or --trajectory")
        return tj, model.check_joints(qj, args.measurements), None, args.measurements
    m = read_measurements(args.measurements, joint_names=model.joint_names)
    if m.joints is None:
        raise CLIError(f"{args.measurements}: no joint columns; give the commanded joints with --joint-states or "
                       f"--trajectory")
    if m.pose is not None and any(str(v) for v in m.pose):
        raise CLIError(f"{args.measurements}: not a path: its rows are named by test pose (a static campaign); "
                       f"judge it with `tolerance-ros report`, or give the joint states streamed along the path with "
                       f"--joint-states")
    return m.stamps, model.check_joints(m.joints, args.measurements), None, args.measurements


def read_streams(args, model, ignored=None):
    """(stamps, points, source, (joint stamps, joints, trajectory, its source)) of ``args.measurements`` (points
    CSV, campaign log, or a rosbag2 recording of both streams) and the command (``_command``)."""
    from ..core.accuracy.io.joint_states import read_points
    from ..core.accuracy.io.rosbag import is_recording, read_rosbag_streams
    recorded = None
    if is_recording(args.measurements) and not (args.joint_states or args.trajectory):  # both streams, one read
        stamps, points, *recorded = read_rosbag_streams(args.measurements, model.joint_names)
        source = str(args.measurements)
    else:
        stamps, points, source = read_points(args.measurements)
    return stamps, points, source, _command(args, model, recorded, ignored)


def run(args):
    from ..core.accuracy.path_report import PathOptions, path_report
    from ..render.path_report import HEADS, segment_rows, summary_lines, write_path_report
    model = load_model(args)
    if not 2 <= args.stations <= MAX_STATIONS:
        raise CLIError(f"--stations: expected 2 to {MAX_STATIONS}, got {args.stations}")
    budget = load_budget(args.budget, model) if args.budget else None
    latency = quantity(args.latency, "time", "--latency", positive=False)
    window = quantity(args.latency_window, "time", "--latency-window") if args.latency_window else None
    speed_window = quantity(args.speed_window, "time", "--speed-window")
    offset = None
    if args.target_offset:
        offset = point_option(args.target_offset, "--target-offset")
        if offset is None:
            raise CLIError(f"--target-offset: expected X,Y,Z with a unit on each (e.g. 0mm,0mm,120mm), got "
                           f"{args.target_offset!r}")
    ignored = []
    stamps, points, source, (tj, qj, trajectory, command_source) = read_streams(args, model, ignored)
    options = PathOptions(registration=args.registration, latency=latency, window=window, stations=args.stations,
                          speed_window=speed_window, offset=offset, trajectory=trajectory, reverse=args.reverse,
                          band=limit_option(model, args.band, "length", "--band"))
    doc = path_report(model, stamps, points, tj, qj, budget, options, source=source)
    doc["command"] = {"source": command_source, "kind": "trajectory" if args.trajectory else "joint states",
                      "ignored_columns": ignored}
    if args.trajectory:
        doc["command"]["start_s"] = doc["latency_s"]
    for what in doc["missed"]:
        missed(args, what)
    files = write_path_report(doc, args.out) if args.out else {}
    if args.json:
        return dict(doc, files=files)
    for line in summary_lines(doc):
        print(line)
    print(table(HEADS, segment_rows(doc)))
    for k, v in files.items():
        for f in (v if isinstance(v, list) else [v]):
            print(f"wrote {f}")
    return None
