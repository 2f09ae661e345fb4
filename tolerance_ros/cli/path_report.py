"""`tolerance-ros path-report`: ISO 9283 path characteristics of a tracker's stream along a commanded path,
with the tracker's latency measured."""
from __future__ import annotations

from ..core.budget import load_budget
from ..render.text import table
from .common import CLIError, limit_option, load_model, missed, point_option, quantity

NAME = "path-report"
HELP = "ISO 9283 path accuracy of a tracker's stream along a commanded path (AT, RT, CR, CO, AV, RV, FV, latency)"
ROBOT = True
MAX_STATIONS = 10_000


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


def run(args):
    from ..core.accuracy.io.path_streams import read_streams
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
    stamps, points, source, (tj, qj, trajectory, command_source) = read_streams(
        model, args.measurements, args.joint_states, args.trajectory, ignored)
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
