"""`tolerance-ros import`: a tracker, motion-capture or controller export with its own column names and
units (CSV, whitespace table, MATLAB .mat) turned into the documented measurement CSV, by an explicit map."""
from __future__ import annotations

from pathlib import Path

from .common import CLIError, quantity

NAME = "import"
HELP = "turn an export with its own columns and units (CSV, whitespace table, .mat) into the measurement CSV"
ROBOT = False


def add_arguments(p):
    p.add_argument("--input", required=True, help="the export: .csv, a whitespace table (.txt, .dat, ...) or .mat")
    p.add_argument("--out", required=True, metavar="FILE", help="the measurement CSV to write (SI: m, rad, s)")
    p.add_argument("--point", action="append", default=[], metavar="[NAME=]X,Y,Z[unit]",
                   help="a measured point: its three columns and their length unit, e.g. BL=x1,y1,z1[m]; repeat for "
                        "several targets (each becomes a row of the target column)")
    p.add_argument("--joint", action="append", default=[], metavar="[NAME=]COLUMN[unit]",
                   help="a joint reading: the column (named as the joint, or NAME=COLUMN) and its unit, e.g. "
                        "arm_1_joint[rad] or torso_lift_joint=torso[mm]")
    p.add_argument("--stamp", metavar="COLUMN[unit]", help="the stamp column and its time unit (s, ms, us, ns)")
    p.add_argument("--period", help="without --stamp: time between rows, e.g. 1s (default 1s)")
    p.add_argument("--orientation", metavar="A,B,C[unit] | QX,QY,QZ,QW",
                   help="orientation of the one measured frame: roll,pitch,yaw columns with an angle unit, or four "
                        "quaternion columns x,y,z,w")
    p.add_argument("--marker", action="append", default=[], metavar="NAME=X,Y,Z[unit]",
                   help="with --orientation: the measured frame is a rigid body's pose, and this is one of its "
                        "markers in the body frame; each row becomes one point per marker (repeat for each)")
    p.add_argument("--pose", metavar="COLUMN", help="the test-pose label column")
    p.add_argument("--cycle", metavar="COLUMN", help="the cycle column")
    p.add_argument("--ignore", action="append", default=[], metavar="COLUMN[,COLUMN...]",
                   help="columns deliberately not imported (any other unmapped column is an error)")
    p.add_argument("--delimiter", choices=[",", "whitespace"], help="text exports: default ',' when the header has a "
                                                                     "comma, else whitespace")


def run(args):
    from ..core.accuracy.io import write_csv
    from ..core.accuracy.io.importer import ColumnMap, parse_spec, read_table, to_measurements
    from ..core.units import LENGTH_UNITS
    points = []
    for text in args.point:
        name, cols, unit = parse_spec(text, "--point")
        points.append((name or "", tuple(cols), unit))
    joints = []
    for text in args.joint:
        name, cols, unit = parse_spec(text, "--joint")
        if len(cols) != 1:
            raise CLIError(f"--joint: one column per joint, got {text!r}")
        joints.append((name or cols[0], cols[0], unit))
    stamp = None
    if args.stamp:
        _, cols, unit = parse_spec(args.stamp, "--stamp")
        stamp = (cols[0], unit)
    if args.stamp and args.period:
        raise CLIError("--period: only without --stamp")
    period = quantity(args.period, "time", "--period") if args.period else 1.0
    orientation = None
    if args.orientation:
        _, cols, unit = parse_spec(args.orientation, "--orientation")
        orientation = (tuple(cols), unit)
    ignore = [c.strip() for item in args.ignore for c in item.split(",") if c.strip()]
    markers = []
    for text in args.marker:
        name, values, unit = parse_spec(text, "--marker")
        if not name or len(values) != 3:
            raise CLIError(f"--marker: expected NAME=X,Y,Z[unit] (the marker in the body frame), got {text!r}")
        markers.append((name, [quantity(f"{v}{unit}", "length", "--marker", positive=False) for v in values]))
    cmap = ColumnMap(joints, points, stamp, period, orientation, args.pose, args.cycle, ignore, markers)
    cols, n = read_table(args.input, args.delimiter)
    meas = to_measurements(cols, n, cmap, str(args.input))
    out = write_csv(Path(args.out), meas, comments=[f"imported from {args.input} by tolerance-ros import"],
                    length_unit="m", angle_unit="rad",
                    joint_units=["m" if u in LENGTH_UNITS else "rad" for _, _, u in joints])
    doc = {"input": str(args.input), "out": str(out), "rows": int(n), "measurements": len(meas),
           "targets": [t for t in meas.target_names if t], "joints": list(meas.joint_names),
           "orientation": bool(meas.has_orientation), "ignored": ignore}
    if args.json:
        return doc
    print(f"imported {n} rows of {args.input} as {len(meas)} measurements"
          + (f" of {len(doc['targets'])} targets ({', '.join(doc['targets'])})" if len(doc["targets"]) > 1 else "")
          + f", {len(joints)} joints" + (", with orientation" if meas.has_orientation else ", points (no orientation)")
          + (f"; ignored: {', '.join(ignore)}" if ignore else ""))
    print(f"wrote {out}")
