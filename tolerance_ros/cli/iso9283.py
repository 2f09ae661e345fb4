"""`tolerance-ros iso9283`: the ISO 9283 test report of a robot, every characteristic the given data allow (pose
accuracy and repeatability, multi-directional variation, distance, drift, exchangeability, and the path ones from
a stream), the test conditions, and what the others need; as Markdown, HTML and JSON with plots."""
from __future__ import annotations

from ..render.text import table
from .common import CLIError, load_model, quantity, refuse_overwrite

NAME = "iso9283"
HELP = "ISO 9283 test report: every characteristic the data allow, in one report (Markdown, HTML, JSON)"
ROBOT = True
MAX_OTHERS = 100


def add_arguments(p):
    p.add_argument("--campaign", help="the campaign measured (test poses, approaches, cycles); without it and "
                                      "--measurements, the report of a --stream alone")
    p.add_argument("--measurements",
                   help="the tracker's measurements of the campaign (CSV, campaign log or rosbag2), rows named by "
                        "test pose")
    p.add_argument("--other", action="append", default=[], metavar="MEASUREMENTS",
                   help="the same campaign measured on another robot of the type (exchangeability E); repeatable")
    p.add_argument("--distance", metavar="POSE1,POSE2",
                   help="the two test poses of the distance accuracy AD and repeatability RD (default P2,P4)")
    p.add_argument("--drift-window", default="1h",
                   help="AP and RP are taken over windows this long for the drift dAP, dRP (default 1h)")
    p.add_argument("--registration", choices=["base", "none"], default="base",
                   help="without --registration-from or --registration-poses: fit the tracker's placement on the test "
                        "poses themselves (base, default: AP is then a lower bound, and the report says so) or take the "
                        "measurements as base-frame (none: refused where they evidently are not)")
    p.add_argument("--registration-from", metavar="CALIBRATION",
                   help="the base frame of a calibration made with the same tracker set-up (its tracker placement, base "
                        "correction and targets): AP and E in it, every --other robot in that one mounting frame")
    p.add_argument("--registration-poses", metavar="MEASUREMENTS",
                   help="the base frame fitted on a separate registration measurement (the standard's base-frame "
                        "measurement, or any campaign measured apart from the test poses; joint columns, or rows named "
                        "by the campaign's poses)")
    p.add_argument("--stream", metavar="POINTS",
                   help="the tracker's stream along a test path (as path-report's --measurements: a CSV of points, "
                        "or a rosbag2 recording with the joint states): the path characteristics AT, RT, CR, CO, "
                        "AV, RV, FV, the stops' and the weaving's")
    p.add_argument("--joint-states", metavar="JOINTS", help="with --stream: the joint states logged along the path")
    p.add_argument("--trajectory", metavar="FILE", help="with --stream: the joint trajectory driven")
    p.add_argument("--latency", help="with --stream or --reorientation: the tracker's latency, given (e.g. 8ms): the "
                                     "stops are then timed on the command's clock exactly (an estimate also holds the "
                                     "robot's own lag)")
    p.add_argument("--band", default="0.1mm",
                   help="with --stream: the stabilisation band about the pose attained at each stop (default 0.1mm)")
    p.add_argument("--reorientation", metavar="FRAMES",
                   help="a 6-DOF tracker's frames (measurement CSV with orientation) along a reorientation "
                        "(plan-campaign --path reorient): the path accuracy on reorientation, in the campaign's "
                        "registration; needs --reorientation-joints and --latency")
    p.add_argument("--reorientation-joints", metavar="JOINTS",
                   help="with --reorientation: the joint states logged along it")
    p.add_argument("--load", help="test condition: the load at the tool (e.g. '10 kg at 100 mm along z')")
    p.add_argument("--speed", help="test condition: the programmed speed (e.g. '100 %% of rated, 1 m/s')")
    p.add_argument("--temperature", help="test condition: the ambient temperature (e.g. '20.5 C')")
    p.add_argument("--measuring-system", help="test condition: the instrument (e.g. 'laser tracker, MPE 15 um')")
    p.add_argument("--out", metavar="DIR", help="write report.md, report.html, iso9283.json and plots into DIR")


def _path(args, model, latency, frame=None):
    """path_report's result for ``--stream`` (``latency`` s: given, or None), or None; in ``frame`` (a ``Frame``)
    when given."""
    if not args.stream:
        if args.joint_states or args.trajectory:
            raise CLIError("--joint-states, --trajectory: go with --stream (the path's tracker points)")
        return None
    from ..core.accuracy.io.path_streams import read_streams
    from ..core.accuracy.path_report import PathOptions, path_report
    from .common import limit_option
    stamps, points, source, (tj, qj, trajectory, _) = read_streams(model, args.stream, args.joint_states,
                                                                    args.trajectory)
    return path_report(model, stamps, points, tj, qj, None,
                       PathOptions(registration=args.registration, trajectory=trajectory, latency=latency,
                                   band=limit_option(model, args.band, "length", "--band"),
                                   T_tracker_base=None if frame is None else frame.registration.T_tracker_base),
                       source=source)


def _reorientation(args, model, latency):
    """(stamps, frames, joint stamps, joints, latency, source) of ``--reorientation``, or None."""
    if not args.reorientation:
        if args.reorientation_joints:
            raise CLIError("--reorientation-joints: goes with --reorientation")
        return None
    if not (args.reorientation_joints and latency is not None):
        raise CLIError("--reorientation: give --reorientation-joints (the joint states along it) and --latency (the "
                       "tracker's; a fixed tool point shows no speed to estimate it from)")
    from ..core.accuracy.io import read_measurements
    from ..core.accuracy.io.joint_states import read_joint_states
    m = read_measurements(args.reorientation)
    if not m.has_orientation:
        raise CLIError(f"--reorientation: {args.reorientation} has no orientation columns; the path accuracy on "
                       f"reorientation needs a 6-DOF tracker's frames")
    tj, qj = read_joint_states(args.reorientation_joints, model.joint_names, model.joint_types)
    return m.stamps, m.T, tj, model.check_joints(qj, args.reorientation_joints), latency, str(args.reorientation)


def _frame(args, model, campaign):
    """The ``Frame`` of ``--registration-from`` or ``--registration-poses``, or None."""
    from ..core.accuracy.iso9283_report import Frame, ISOReportError
    given = [o for o, v in (("--registration-from", args.registration_from),
                            ("--registration-poses", args.registration_poses)) if v]
    if len(given) > 1 or (given and args.registration == "none"):
        raise CLIError(f"{', '.join(given + (['--registration none'] if args.registration == 'none' else []))}: give one "
                       f"source of the base frame")
    if args.registration_from:
        from ..core.calibration.calibration_file import load_calibration
        cal = load_calibration(args.registration_from, model)
        return Frame.from_calibration(cal.T_tracker_base, cal.base, cal.targets, args.registration_from)
    if args.registration_poses:
        from ..core.accuracy.io import read_measurements
        try:
            return Frame.from_poses(model, read_measurements(args.registration_poses, joint_names=model.joint_names),
                                    campaign)
        except ISOReportError as exc:
            raise CLIError(f"--registration-poses: {exc}") from None
    return None


def _numeric(cell) -> bool:
    try:
        float(cell)
    except (TypeError, ValueError):
        return cell == "-"
    return True


def run(args):
    from ..core.accuracy.io import read_measurements
    from ..core.accuracy.iso9283_report import ISOOptions, ISOReportError, iso9283_report
    from ..core.campaign import load_campaign
    from ..render.iso9283_report import sections, write_iso9283_report
    refuse_overwrite(args.out, ("report.md", "report.html", "iso9283.json", "drift.png", "vap.png"), args,
                     ("campaign", "measurements", "other", "stream", "joint_states", "trajectory", "reorientation",
                      "reorientation_joints", "registration_from", "registration_poses"))
    model = load_model(args)
    if bool(args.campaign) != bool(args.measurements):
        raise CLIError("--campaign, --measurements: give both (the test poses and their measurements), or neither for "
                       "the report of a --stream alone")
    if not args.campaign and not args.stream:
        raise CLIError("--campaign and --measurements, or --stream: nothing to report")
    if not args.campaign and (args.other or args.distance or args.registration_poses):
        raise CLIError(f"{'--other' if args.other else '--distance' if args.distance else '--registration-poses'}: "
                       f"goes with the campaign and its measurements (--campaign, --measurements)")
    campaign = load_campaign(args.campaign, model) if args.campaign else None
    if len(args.other) > MAX_OTHERS:
        raise CLIError(f"--other: {len(args.other)} robots; at most {MAX_OTHERS}")
    pair = None
    if args.distance:
        pair = tuple(p.strip() for p in args.distance.split(","))
        if len(pair) != 2 or not all(pair) or pair[0] == pair[1]:
            raise CLIError(f"--distance: expected two different test poses POSE1,POSE2, got {args.distance!r}")
    window = quantity(args.drift_window, "time", "--drift-window")
    if not 1.0 <= window <= 30 * 86400.0:
        raise CLIError(f"--drift-window: expected 1s to 720h, got {args.drift_window!r}")
    conditions = {"load": args.load, "speed": args.speed, "temperature": args.temperature,
                  "measuring_system": args.measuring_system}
    meas = read_measurements(args.measurements, joint_names=model.joint_names) if args.measurements else None
    others = [read_measurements(f, joint_names=model.joint_names) for f in args.other]
    if args.latency and not (args.stream or args.reorientation):
        raise CLIError("--latency: goes with --stream or --reorientation")
    latency = quantity(args.latency, "time", "--latency", positive=False)
    frame = _frame(args, model, campaign)
    path = _path(args, model, latency, frame)
    reorientation = _reorientation(args, model, latency)
    try:
        doc = iso9283_report(model, meas, campaign, ISOOptions(pair, window, args.registration, conditions, frame),
                             others, path, reorientation)
    except ISOReportError as exc:
        raise CLIError(str(exc)) from None
    files = write_iso9283_report(doc, args.out) if args.out else {}
    if args.json:
        return dict(doc, files=files)
    print(f"robot {model.name}: ISO 9283 from " + (f"{doc['measurements']} measurements of campaign {campaign.name} "
          f"({doc['source']})" if campaign is not None else f"the stream {doc['source']} alone")
          + (f" and {len(others)} other robot(s)" if others else ""))
    print(f"base frame: {doc['frame']['words']}")
    for w in doc["warnings"]:
        print(f"WARNING: {w}")
    for title, note, heads, rows in sections(doc):
        print(f"\n{title}: {note}")
        print(table(heads, rows, [">" if all(_numeric(r[k]) for r in rows) else "<" for k in range(len(heads))]))
    for k, v in files.items():
        for f in (v if isinstance(v, list) else [v]):
            print(f"wrote {f}")
    return None
