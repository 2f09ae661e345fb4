"""`tolerance-ros calibrate`: a calibrated robot file from measured poses, validated on held-out poses."""
from __future__ import annotations

from pathlib import Path

from ..render.text import Progress, table
from .common import CLIError, load_model, missed, quantity, relative

NAME = "calibrate"
HELP = ("calibrated robot file from measured poses, validated on "
        "held-out poses")
ROBOT = True


def add_arguments(p):
    p.add_argument("--measurements", required=True,
                   help="CSV file, campaign log (.jsonl) or rosbag2 (dir, .db3, .mcap)")
    p.add_argument("--campaign", help="campaign with the test poses (joints of rows labelled by pose)")
    p.add_argument("--registration", choices=["base", "base+tool"], default="base",
                   help="estimate the tracker-to-base transform (and the tool offset)")
    p.add_argument("--noise", default="10um", help="tracker position noise, weights the rows (default 10um); the "
                                                   "uncertainties use the residual noise")
    p.add_argument("--orientation-noise", help="tracker orientation noise, e.g. 10urad: also fit orientations")
    p.add_argument("--folds", type=int, default=5, help="k of the k-fold validation by test pose (default 5)")
    p.add_argument("--seed", type=int, default=0, help="seed of the split into folds")
    p.add_argument("--skip-bad", action="store_true", help="skip malformed rows (they are listed), instead of failing")
    p.add_argument("--out", required=True, metavar="DIR",
                   help="write the calibrated robot file, calibration.yaml, calibration.md/.json and plots into DIR")


def run(args):
    from ..core.accuracy.io import read_measurements
    from ..core.calibration.calibrate import calibrate_measurements
    from ..core.calibration.writers import save_calibration, write_calibrated_robot
    from ..core.campaign import load_campaign
    from ..render.calibration_report import parameter_rows, summary_rows, write_calibration_report
    model = load_model(args)
    noise = quantity(args.noise, "length", "--noise")
    onoise = quantity(args.orientation_noise, "angle", "--orientation-noise")
    if args.folds < 2:
        raise CLIError("--folds: must be >= 2")
    campaign = load_campaign(args.campaign, model) if args.campaign else None
    meas = read_measurements(args.measurements, joint_names=model.joint_names, skip_bad=args.skip_bad)
    prog = Progress("calibrate", not args.quiet)
    prog(0, 1)
    cal = calibrate_measurements(model, meas, campaign, args.registration, noise, onoise, args.folds, args.seed)
    prog(1, 1)
    out = Path(args.out)
    files = write_calibrated_robot(model, cal, out)
    source = getattr(model, "config_path", None) or getattr(model, "source", None)
    cal.sources.update({"robot": relative(source, out) if source else model.name,
                        "measurements": relative(args.measurements, out),
                        "campaign": (relative(args.campaign, out) if campaign is not None
                                     and Path(args.campaign).is_file() else args.campaign),
                        "calibrated_robot": Path(files["robot"]).name})
    if hasattr(model, "tip_link"):  # a URDF chain: the links that choose it, to load the same chain again
        cal.sources.update(tip_link=model.tip_link, base_link=model.base_link)
    files["calibration"] = str(save_calibration(cal, out / "calibration.yaml"))
    written = write_calibration_report(cal, out, files)
    files.update(report=written["report"], json=written["json"], plots=written["plots"])
    v = cal.validation
    if v["after"]["position_rms_m"] >= v["before"]["position_rms_m"]:
        missed(args, f"hold-out validation: the calibrated model does not reduce the position error RMS "
                     f"({v['before']['position_rms_m'] * 1e3:.4f} mm before, {v['after']['position_rms_m'] * 1e3:.4f} "
                     f"mm after)")
    if args.json:
        doc = cal.to_dict()
        doc["files"] = files
        return doc
    print(f"robot {model.name}: {cal.measurements} measurements at {cal.poses} test poses from {meas.source}; "
          f"registration '{cal.registration}'")
    print(f"identified {cal.unknowns - 6} parameter errors and the base correction from {cal.rows} equations; "
          f"condition number {cal.fit_condition:.1f} (scaled); residual noise {cal.sigma * 1e6:.2f} um")
    print("held at nominal (not identifiable from these poses): " + (", ".join(cal.held) or "none"))
    print(table(["param", "unit", "error", "std", "|error|/std", "absorbs (first order)"], parameter_rows(cal)))
    print(f"\nvalidation: {v['method']}")
    print(table(["held-out poses", "before", "after"], summary_rows(v)))
    print(f"position error RMS reduced by {v['improvement'] * 100:.1f} %")
    for f in dict.fromkeys(files[k] for k in ("robot", "urdf", "calibration", "report", "json") if k in files):
        print(f"wrote {f}")
    for f in files["plots"]:
        print(f"plot: {f}")
