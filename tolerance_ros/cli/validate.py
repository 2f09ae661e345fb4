"""`tolerance-ros validate`: a calibration predicts another campaign (another day, other poses) with its own
registration and target offsets, nothing refitted; before (nominal) and after (calibrated) by test pose."""
from __future__ import annotations

from ..render.text import table
from .common import CLIError, missed

NAME = "validate"
HELP = "predict another campaign with a calibration (nothing refitted): before and after, by test pose"
ROBOT = False


def add_arguments(p):
    p.add_argument("--calibration", required=True, help="calibration.yaml written by calibrate")
    p.add_argument("--measurements", required=True,
                   help="the other campaign: CSV file, campaign log (.jsonl) or rosbag2 (dir, .db3, .mcap)")
    p.add_argument("--robot", help="the nominal robot (default: the one the calibration file names)")
    p.add_argument("--tip-link", help="URDF robots: the link the chain ends in (default: the calibration's)")
    p.add_argument("--base-link", help="URDF robots: the link the chain starts from (default: the calibration's)")
    p.add_argument("--campaign", help="campaign with the test poses (joints of rows labelled by pose)")
    p.add_argument("--reregister", action="store_true",
                   help="refit the tracker's placement only (it moved between the campaigns); the targets and the "
                        "parameters stay the calibration's")
    p.add_argument("--skip-bad", action="store_true", help="skip malformed rows (they are listed), instead of failing")
    p.add_argument("--no-robust", action="store_true",
                   help="with --reregister, keep every row in the tracker's refit (by default rows beyond 4.6 robust "
                        "sigmas are left out of it and of the figures, and listed)")


def run(args):
    from ..core.accuracy.io import read_measurements
    from ..core.calibration.validation import predict_measurements
    from ..core.calibration.calibration_file import calibration_robot, load_calibration
    from ..core.campaign import load_campaign
    from ..core.models import load_robot
    if args.robot:
        model = load_robot(args.robot, args.tip_link, args.base_link)
    else:
        if args.tip_link or args.base_link:
            raise CLIError("--tip-link, --base-link: give them with --robot")
        model = calibration_robot(args.calibration)
    cal = load_calibration(args.calibration, model)
    from ..core.accuracy.io.contact_csv import is_contact_campaign
    if is_contact_campaign(args.measurements):
        return run_contacts(args, model, cal)
    if cal.registration == "contact":
        raise CLIError(f"--measurements: {args.calibration} was made from contacts; give a contact campaign (a CSV with "
                       f"a contact column, or a log with contact events) of another session")
    campaign = load_campaign(args.campaign, model) if args.campaign else None
    meas = read_measurements(args.measurements, joint_names=model.joint_names, skip_bad=args.skip_bad)
    res = predict_measurements(cal, model, meas, args.reregister, campaign, robust=not args.no_robust)
    res["calibration"] = str(args.calibration)
    res["skipped_rows"] = meas.skipped
    b, a = res["before"]["position_rms_m"], res["after"]["position_rms_m"]
    if a >= b:
        missed(args, f"the calibration does not predict {meas.source} better than the nominal robot "
                     f"(3-D position RMS {b * 1e3:.4f} mm before, {a * 1e3:.4f} mm after)")
    for w in res["warnings"]:  # last: the likely cause
        missed(args, w)
    if args.json:
        return res
    print(f"robot {model.name}, calibration {args.calibration}: {res['measurements']} measurements from "
          f"{meas.source}; {'tracker refitted' if args.reregister else 'nothing refitted'}")
    rows = [["position RMS (3-D) [mm]", f"{b * 1e3:.4f}", f"{a * 1e3:.4f}"],
            ["position max [mm]", f"{res['before']['position_max_m'] * 1e3:.4f}",
             f"{res['after']['position_max_m'] * 1e3:.4f}"]]
    if res["orientation_measured"]:
        rows.append(["orientation RMS [mrad]", f"{res['before']['orientation_rms_rad'] * 1e3:.4f}",
                     f"{res['after']['orientation_rms_rad'] * 1e3:.4f}"])
    for r in res["left_out"]:
        print(f"left out: {r['where']}: {r['reason']}")
    print(table(["", "before (nominal)", "after (calibrated)"], rows))
    print(f"position error RMS (3-D) reduced by {res['improvement'] * 100:.1f} %")
    if res.get("by_group"):
        print("\nby posture (against the training campaign):")
        print(table(["postures", "poses", "before RMS mm", "after RMS mm"],
                    [[g, v["poses"], f"{v['before_rms_m'] * 1e3:.4f}", f"{v['after_rms_m'] * 1e3:.4f}"]
                     for g, v in res["by_group"].items()]))
    if len(res["by_target"]) > 1:
        print("\nby target:")
        print(table(["target", "n", "before RMS mm", "after RMS mm"],
                    [[t, v["n"], f"{v['before_rms_m'] * 1e3:.4f}", f"{v['after_rms_m'] * 1e3:.4f}"]
                     for t, v in res["by_target"].items()]))
    print("\nby test pose:")
    print(table(["pose", "n", "group", "before RMS mm", "after RMS mm"],
                [[name, v["n"], v["group"] or "-", f"{v['before_rms_m'] * 1e3:.4f}", f"{v['after_rms_m'] * 1e3:.4f}"]
                 for name, v in res["per_pose"].items()]))
    for note in res["notes"]:
        print(f"NOTE: {note}")
    for w in res["warnings"]:
        print(f"WARNING: {w}")


def run_contacts(args, model, cal):
    """``validate`` on a contact campaign: its planes and points refitted, the calibration's model and targets held
    (``core.calibration.contact_campaign.validate_campaign``)."""
    from ..core.accuracy.io.contact_csv import read_contact_campaign
    from ..core.calibration.contact_campaign import validate_campaign
    if args.campaign or args.reregister:
        raise CLIError("contact campaigns: --campaign and --reregister do not apply (the session's planes and points are "
                       "always refitted)")
    contacts, _ = read_contact_campaign(args.measurements, model.joint_names, model.joint_types, args.skip_bad)
    res = validate_campaign(cal, model, contacts, robust=not args.no_robust)
    res["calibration"] = str(args.calibration)
    res["skipped_rows"] = contacts.skipped
    b, a = res["before"]["contact_rms_m"], res["after"]["contact_rms_m"]
    if a >= b:
        missed(args, f"the calibration does not predict {contacts.source} better than the nominal robot (contact RMS "
                     f"{b * 1e3:.4f} mm before, {a * 1e3:.4f} mm after)")
    if args.json:
        return res
    print(f"robot {model.name}, calibration {args.calibration}: {res['measurements']} contacts from {contacts.source}; "
          f"their planes and points refitted, nothing else")
    print(table(["", "before (nominal)", "after (calibrated)"],
                [["contact RMS [mm]", f"{b * 1e3:.4f}", f"{a * 1e3:.4f}"],
                 ["contact max [mm]", f"{res['before']['contact_max_m'] * 1e3:.4f}",
                  f"{res['after']['contact_max_m'] * 1e3:.4f}"],
                 ["rows rejected", res["before"]["rejected"], res["after"]["rejected"]]]))
    print(f"contact RMS reduced by {res['improvement'] * 100:.1f} %")
    for w in res["warnings"]:
        print(f"WARNING: {w}")
    return None
