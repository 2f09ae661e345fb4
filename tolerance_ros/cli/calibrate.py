"""`tolerance-ros calibrate`: a calibrated robot file from measured poses, chosen by what predicts held-out
poses, fitted robustly, refused when it cannot be right."""
from __future__ import annotations

from pathlib import Path

from ..render.text import Progress, table
from .common import CLIError, load_model, missed, point_option, quantity, relative, target_options

NAME = "calibrate"
HELP = "calibrated robot file from measured poses, validated on held-out poses"
ROBOT = True
PARAMETERS = ("auto", "registration", "joint-offsets", "full", "full+elastic", "joint-offsets+elastic")


def add_arguments(p):
    p.add_argument("--measurements", required=True,
                   help="CSV file, campaign log (.jsonl) or rosbag2 (dir, .db3, .mcap)")
    p.add_argument("--campaign", help="campaign with the test poses (joints of rows labelled by pose)")
    p.add_argument("--target", action="append", default=[], metavar="NAME=X,Y,Z|NAME=link:LINK",
                   help="contact campaigns: the nominal place of a target of the tool in the tool frame (a unit on "
                        "each, e.g. A=0mm,0mm,120mm) or a URDF link fixed to the tip; one per target of the file")
    p.add_argument("--registration", choices=["auto", "base", "base+tool"], default="auto",
                   help="estimate the tracker-to-base transform (base), and each target's offset on the tool "
                        "(base+tool); auto (default): the one that predicts held-out poses better, said in the output")
    p.add_argument("--parameters", choices=PARAMETERS, default="auto",
                   help="what to identify: auto (default: the candidate that predicts held-out poses best), the "
                        "registration alone, the joint offsets, every parameter, or every parameter and a joint "
                        "compliance times its gravity load (URDF robots: their inertials, --payload, or a lumped "
                        "point mass at the tool frame). Contact campaigns: auto, joint-offsets, full, or "
                        "joint-offsets+elastic (the joint offsets and every joint's compliance under the whole robot's "
                        "weight: a URDF with inertials, its chain from a fixed base or from the sole it stands on)")
    p.add_argument("--prior", default="5mm,5mrad",
                   help="prior std of the origin errors of the regularised fits, LENGTH,ANGLE (default 5mm,5mrad), "
                        "or none")
    p.add_argument("--registration-prior", default="none",
                   help="prior std of the base correction, LENGTH,ANGLE (default none: the registration is free)")
    p.add_argument("--payload", metavar="MASS@X,Y,Z",
                   help="a point mass on the tool loading the joints of the elastostatic term, e.g. 165kg@0.1m,0m,0.2m "
                        "(tool frame); added to the URDF's inertials, or instead of the lumped 1 kg at the tool frame "
                        "that stands for the load of a URDF without inertials")
    p.add_argument("--no-robust", action="store_true",
                   help="keep every measurement (by default outliers beyond 4.6 robust sigmas are left out and listed)")
    p.add_argument("--noise", help="tracker position noise, weights the rows (default 10um); the uncertainties use "
                                   "the residual noise. Contact campaigns: the contact noise, estimated from the rows by "
                                   "default (given, it overrides that estimate)")
    p.add_argument("--target-prior", metavar="LENGTH",
                   help="contact campaigns: fit every target's place with a Gaussian prior of this std on its nominal "
                        "place (e.g. 2mm); by default a target coordinate is fitted only where the contacts determine "
                        "it well")
    p.add_argument("--fit-targets", action="store_true",
                   help="contact campaigns: fit every target coordinate the rig does not make a copy of, however "
                        "poorly the contacts see it")
    p.add_argument("--orientation-noise", help="tracker orientation noise, e.g. 10urad: also fit orientations")
    p.add_argument("--folds", type=int, default=10, help="k of the k-fold validation by test pose (default 10)")
    p.add_argument("--seed", type=int, default=0, help="seed of the split into folds")
    p.add_argument("--skip-bad", action="store_true", help="skip malformed rows (they are listed), instead of failing")
    p.add_argument("--signing-key", metavar="PEM",
                   help="sign calibration.yaml with this Ed25519 private key (`tolerance-ros signing-key` makes one), "
                        "for nodes that trust only signed calibrations (parameter trusted_calibration_keys)")
    p.add_argument("--budget", help="tolerance budget: judge each identified part against it (report's groups and "
                                    "decision rule); exit 3 when a part is decided out")
    p.add_argument("--decision-rule", default="guarded:2", metavar="guarded:K|simple",
                   help="with --budget: how a part is judged (default guarded:2: out when |error| - K u > tolerance, "
                        "within when |error| + K u <= tolerance, else undecided; simple: out when |error| > tolerance)")
    p.add_argument("--out", required=True, metavar="DIR",
                   help="write the calibrated robot file, calibration.yaml, calibration.md/.json and plots into DIR "
                        "(a calibration that is refused goes to calibration.refused.yaml, and no robot file)")


def prior_option(text, option="--prior"):
    """(length m, angle rad) of ``--prior LENGTH,ANGLE``, or None for ``none``."""
    if text.strip().lower() == "none":
        return None
    parts = text.split(",")
    if len(parts) != 2:
        raise CLIError(f"{option}: expected LENGTH,ANGLE (e.g. 10mm,10mrad) or none, got {text!r}")
    return quantity(parts[0], "length", option), quantity(parts[1], "angle", option)


def payload_option(text):
    """(kg, (3,) m) of ``--payload MASS@X,Y,Z``, or None."""
    if text is None:
        return None
    mass, at, point = text.partition("@")
    coords = point_option(point, "--payload") if at else None
    if coords is None:
        raise CLIError(f"--payload: expected MASS@X,Y,Z, each with its unit (e.g. 165kg@0.1m,0m,0.2m), got {text!r}")
    return quantity(mass, "mass", "--payload"), tuple(coords)


def run(args):
    from ..core.accuracy.io import read_measurements
    from ..core.calibration.calibrate import FitOptions, calibrate_measurements
    from ..core.calibration.elastic import Load
    from ..core.calibration.provenance import ProvenanceError, file_sha256, load_signing_key, new_provenance
    from ..core.campaign import load_campaign
    from ..render.calibration_report import write_calibration_report
    model = load_model(args)
    if args.folds < 2:
        raise CLIError("--folds: must be >= 2")
    try:
        key = load_signing_key(args.signing_key) if args.signing_key else None
    except ProvenanceError as exc:
        raise CLIError(f"--signing-key: {exc}") from None
    if args.payload and args.parameters not in ("auto", "full+elastic"):
        raise CLIError(f"--payload: only the elastostatic term loads the joints with it (--parameters full+elastic, or "
                       f"auto, which tries it); with --parameters {args.parameters} it would be ignored")
    try:
        payload = payload_option(args.payload)
        if payload is not None:
            Load("point-mass", *payload)
    except ValueError as exc:
        raise CLIError(f"--payload: {exc}") from None
    opts = FitOptions(registration="base" if args.registration == "auto" else args.registration,
                      sigma_position=quantity(args.noise or "10um", "length", "--noise"),
                      sigma_orientation=quantity(args.orientation_noise, "angle", "--orientation-noise"),
                      robust=not args.no_robust, prior=prior_option(args.prior),
                      registration_prior=prior_option(args.registration_prior, "--registration-prior"),
                      folds=args.folds, seed=args.seed, payload=payload)
    from ..core.accuracy.io.contact_csv import is_contact_campaign
    if is_contact_campaign(args.measurements):
        return run_contacts(args, model, opts, key)
    if args.target or args.target_prior or args.fit_targets:
        raise CLIError("--target, --target-prior, --fit-targets: for contact campaigns (a CSV with a contact column, or "
                       "a campaign log with contact events); a tracker's targets are fitted with --registration "
                       "base+tool")
    if args.parameters == "joint-offsets+elastic":
        raise CLIError("--parameters joint-offsets+elastic: for contact campaigns; with a tracker the compliances are "
                       "fitted with every parameter (--parameters full+elastic)")
    campaign = load_campaign(args.campaign, model) if args.campaign else None
    meas = read_measurements(args.measurements, joint_names=model.joint_names, skip_bad=args.skip_bad)
    log_sha256 = file_sha256(args.measurements)
    prog = Progress("calibrate (cross-validating the candidates)", not args.quiet)
    cal = calibrate_measurements(model, meas, campaign, opts, parameters=args.parameters, progress=prog,
                                 registration=args.registration)
    out = Path(args.out)
    source = getattr(model, "config_path", None) or getattr(model, "source", None)
    cal.sources.update({"robot": relative(source, out) if source else model.name,
                        "measurements": relative(args.measurements, out),
                        "campaign": (relative(args.campaign, out) if campaign is not None
                                     and Path(args.campaign).is_file() else args.campaign)})
    if hasattr(model, "tip_link"):  # a URDF chain: the links that choose it, to load the same chain again
        cal.sources.update(tip_link=model.tip_link, base_link=model.base_link)
    cal.provenance = new_provenance("tolerance-ros calibrate", log=str(Path(args.measurements).resolve()),
                                    log_sha256=log_sha256)
    files = write_files(args, model, cal, out, key)
    written = write_calibration_report(cal, out, files)
    files.update(report=written["report"], json=written["json"], plots=written["plots"])
    budget = against_budget(args, model, cal, Path(written["report"]))
    if args.json:
        doc = cal.to_dict()
        doc["files"] = files
        if budget is not None:
            doc["budget"] = budget
        return doc
    print_calibration(cal, meas.source)
    if budget is not None:
        print_budget(budget)
    for f in dict.fromkeys(files[k] for k in ("robot", "urdf", "calibration", "refused", "report", "json")
                           if k in files):
        print(f"wrote {f}")
    for f in files["plots"]:
        print(f"plot: {f}")


def write_files(args, model, cal, out, key) -> dict:
    """The calibrated robot and calibration.yaml of an accepted calibration, calibration.refused.yaml of a refused
    one (its reasons the run's missed targets, the most basic last); a fit that did not converge is missed too."""
    from ..core.calibration.calibrated_robot import write_calibrated_robot
    from ..core.calibration.calibration_file import save_calibration
    files = {}
    if cal.plausibility["ok"]:
        files = write_calibrated_robot(model, cal, out)
        if "note" in files:
            cal.warnings.append(files.pop("note"))
        cal.sources["calibrated_robot"] = Path(files["robot"]).name
        files["calibration"] = str(save_calibration(cal, out / "calibration.yaml", signing_key=key))
    else:
        files["refused"] = str(save_calibration(cal, out / "calibration.refused.yaml"))
        for problem in reversed(cal.plausibility["problems"]):  # the first, most basic reason on the last line
            missed(args, f"calibration refused: {problem}")
    if not cal.convergence.get("converged", True):
        missed(args, f"calibration: the fit {cal.convergence['words']}")
    return files


def against_budget(args, model, cal, report):
    """With ``--budget``: the identified parts judged against it (``conformity.judged``, the groups of each
    estimated parameter and the held ones it absorbs), a section appended to the calibration's report; exit 3 when
    a part is decided out. None without a budget."""
    if not args.budget:
        return None
    from ..core.budget import load_budget
    from ..core.conformity import DecisionRule, judged, out_words
    from ..render.accuracy_report import budget_lines
    try:
        rule = DecisionRule.parse(args.decision_rule)
    except ValueError as exc:
        raise CLIError(f"--decision-rule: {exc}") from None
    budget = load_budget(args.budget, model)
    res = judged(cal.names, cal.kinds, cal.dx, cal.std, cal.held, cal.aliases, budget.vector_for(model), rule,
                 cal.undetermined, model.reach())
    res["budget"] = args.budget
    if "prior" in str(cal.model.get("label", "")):
        res["note"] = ("the chosen fit is regularised: its prior pulls each estimate toward nominal, so a part out "
                       "of tolerance may be decided within or undecided")
    with report.open("a") as fh:
        fh.write("\n".join(["", f"## Against the budget {res['budget']}", ""] + budget_lines(res)
                           + (["", f"Note: {res['note']}."] if "note" in res else [])) + "\n")
    if out_words(res):
        missed(args, out_words(res))
    return res


def print_budget(res):
    """The parts judged against the budget, as ``report`` prints them (out and undecided listed)."""
    from ..render.accuracy_report import decisions_text
    print("\n" + decisions_text(res, f"against the budget {res['budget']}, {len(res['groups'])} identified parts"))
    if "note" in res:
        print(f"NOTE: {res['note']}")


def run_contacts(args, model, opts, key):
    """``calibrate`` on a contact campaign (``core.calibration.contact_campaign``)."""
    from ..core.accuracy.io.contact_csv import read_contact_campaign
    from ..core.calibration.contact_campaign import calibrate_campaign
    from ..core.calibration.provenance import file_sha256, new_provenance
    from ..render.contact_report import summary_lines, write_contact_report
    if args.campaign or args.registration not in ("auto", "base") or args.orientation_noise or args.payload:
        raise CLIError("contact campaigns: --campaign, --registration, --orientation-noise and --payload do not apply "
                       "(the rig is fitted with the parameters; contacts have no orientation)")
    if args.parameters not in ("auto", "joint-offsets", "full", "joint-offsets+elastic"):
        raise CLIError(f"--parameters {args.parameters}: contact campaigns identify auto, joint-offsets, full or "
                       f"joint-offsets+elastic")
    if args.target_prior and args.fit_targets:
        raise CLIError("--target-prior, --fit-targets: give one (a prior on the targets' places, or none)")
    target_prior = quantity(args.target_prior, "length", "--target-prior")
    contacts, logged = read_contact_campaign(args.measurements, model.joint_names, model.joint_types, args.skip_bad)
    offsets = {k: v for k, v in logged.items() if v is not None} | target_options(args.target, model)
    prog = Progress("calibrate (cross-validating the candidates)", not args.quiet)
    cal = calibrate_campaign(model, contacts, offsets, args.parameters, opts.prior,
                             quantity(args.noise, "length", "--noise"), args.folds, args.seed, opts.robust, prog,
                             "fit" if args.fit_targets else "auto", target_prior)
    out = Path(args.out)
    source = getattr(model, "config_path", None) or getattr(model, "source", None)
    cal.sources.update({"robot": relative(source, out) if source else model.name,
                        "measurements": relative(args.measurements, out)})
    if hasattr(model, "tip_link"):
        cal.sources.update(tip_link=model.tip_link, base_link=model.base_link)
    if contacts.skipped:
        cal.warnings.insert(0, f"{len(contacts.skipped)} malformed row(s) skipped: " + "; ".join(
            f"line {s['line']}: {s['reason']}" for s in contacts.skipped[:5]))
    cal.provenance = new_provenance("tolerance-ros calibrate", log=str(Path(args.measurements).resolve()),
                                    log_sha256=file_sha256(args.measurements))
    files = write_files(args, model, cal, out, key)
    written = write_contact_report(cal, out, files)
    files.update(report=written["report"], json=written["json"])
    if args.json:
        from ..render.contact_report import contact_document
        doc = contact_document(cal)
        doc["files"] = files
        return doc
    for line in summary_lines(cal):
        print(line)
    for f in dict.fromkeys(files[k] for k in ("robot", "urdf", "calibration", "refused", "report", "json") if k in files):
        print(f"wrote {f}")
    return None


def print_calibration(cal, source):
    """The calibration's figures as a person reads them (mm, mrad; every RMS of the 3-D error)."""
    from ..core.accuracy.checks import registration_words
    from ..render.calibration_report import (candidate_rows, fit_summary, parameter_rows, row_lines, summary_rows,
                                             target_rows)
    v = cal.validation
    choice = cal.model.get("registration") or {}
    said = (registration_words(choice) if choice.get("how", "given") != "given" else
            f"registration '{cal.registration}'")
    print(f"robot {cal.robot}: {cal.measurements} measurements at {cal.poses} test poses from {source}; "
          f"{said}; " + ("frames (their orientation fitted with --orientation-noise)"
                                                    if cal.has_orientation else "points (no orientation)"))
    print(f"\nwhat to identify ({cal.model.get('how', '')}, compared on {cal.model.get('compared_on', '')}; "
          f"{v['method']}):")
    print(table(["candidate", "unknowns", "held-out RMS (3-D) mm", "held-out max mm", ""], candidate_rows(cal)))
    print(f"identified: {cal.model.get('label', cal.model.get('parameters'))}; " + fit_summary(cal))
    if cal.held:
        print("held at nominal (not identifiable from these poses): " + ", ".join(cal.held))
    rows = parameter_rows(cal)
    if rows:
        print(table(["param", "unit", "error", "std", "|error|/std", "absorbs (first order)", "note"], rows))
    if cal.registration == "base+tool":
        print("targets in the tool frame [mm]:")
        print(table(["target", "x", "y", "z", "std"], target_rows(cal)))
    if cal.compliance is not None:
        print("joint compliance (elastostatic term): " + ", ".join(
            f"{n} {c:+.4g} +- {s:.2g}" for n, c, s in zip(cal.sources.get("joint_names", []), cal.compliance,
                                                          cal.compliance_std) if c != 0)
              + " (rad/(N m); m/N for prismatic joints)")
        if cal.load:
            print(f"  loaded by {cal.load.get('description', cal.load.get('model'))}")
    for line in row_lines(cal.rejected, "rejected") + row_lines(cal.suspect, "suspect"):
        print(line)
    print(f"\nvalidation: {v['method']}")
    print(table(["held-out poses", "before", "after"], summary_rows(v)))
    print(f"position error RMS (3-D, every measurement) reduced by {v['improvement'] * 100:.1f} %")
    rep = cal.repeatability or {}
    if rep.get("scatter_m") is not None:
        print(f"what is left: residual RMS (3-D) {rep['residual_rms_m'] * 1e3:.4f} mm beside the repeat scatter of "
              f"repeated poses {rep['scatter_m'] * 1e3:.4f} mm; not explained by noise "
              f"{rep['unexplained_m'] * 1e3:.4f} mm")
    elif rep:
        print(f"what is left: residual RMS (3-D) {rep['residual_rms_m'] * 1e3:.4f} mm; no pose was repeated, so the "
              f"noise floor is not measured (repeat poses to tell noise from model error)")
    for w in cal.warnings:
        print(f"WARNING: {w}")
    for problem in cal.plausibility["problems"]:
        print(f"REFUSED: {problem}")
