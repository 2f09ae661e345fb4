"""`tolerance-ros plan-campaign`: test poses that make the identification best conditioned, or (``--path``) an
ISO 9283 test path as the joint trajectory that drives it."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..core.budget import load_budget
from ..render.text import Progress, table
from .common import CAPS, CLIError, contact_specs, joints_option, load_model, quantity, target_options

NAME = "plan-campaign"
HELP = "test poses that make the identification best conditioned"
ROBOT = True


MAX_WORK = 2_000_000  # --n x --candidates: the work of the pose selection, besides the caps of each


def add_arguments(p):
    p.add_argument("--n", type=int, default=30, help=f"number of test poses (default 30, at most {CAPS['n'][0]})")
    p.add_argument("--criterion", choices=["observability", "condition", "min-singular", "noise-amplification"],
                   default="observability",
                   help="observability: O1 (Borm & Menq 1991); condition: O2; min-singular: O3; "
                        "noise-amplification: O4 (Nahvi & Hollerbach 1996)")
    p.add_argument("--candidates", type=int, default=2000,
                   help=f"candidate poses within the joint limits (default 2000, at most {CAPS['candidates'][0]})")
    p.add_argument("--seed", type=int, default=0, help="seed of the candidate configurations (default 0)")
    p.add_argument("--cycles", type=int, help="visits per test pose in the campaign file (default 3), or cycles of "
                                               "the --path (default 10)")
    p.add_argument("--path", choices=["line", "circle", "rectangle", "weave", "reorient", "positioning"],
                   help="write an ISO 9283 test path in the ISO cube instead: the joint trajectory that drives it "
                        "(docs/path-accuracy.md)")
    p.add_argument("--iso9283", action="store_true",
                   help="write the ISO 9283 pose campaign instead: the cube's test poses P1-P5 (30 cycles unless "
                        "--cycles), and with --approach each also approached along +x, +y and +z (docs/iso9283.md)")
    p.add_argument("--configuration", metavar="Q1,Q2,...",
                   help="with --iso9283: the arm configuration to keep (each joint with its unit), its tool pose the "
                        "cube's centre when it fits there (default: the configuration nearest the reference "
                        "posture, each joint at zero, or mid-range where zero is beyond its limits)")
    p.add_argument("--approach", metavar="LENGTH",
                   help="with --iso9283: the pre-poses this far before each test pose, one per direction (e.g. "
                        "100mm), for the multi-directional pose accuracy variation vAP")
    p.add_argument("--stroke", help="with --path weave: the weaving's peak-to-peak width across the line (default "
                                    "10 %% of the cube's edge)")
    p.add_argument("--pitch", help="with --path weave: the weaving's period along the line (default 20 %% of the "
                                   "edge; rounded to a whole number of periods, at least 3)")
    p.add_argument("--distances", metavar="D1,D2,...",
                   help="with --path positioning: the moves, each out and back from the cube's centre along the test "
                        "line, a unit on each (default 10mm,20mm,50mm,100mm,200mm, those that fit)")
    p.add_argument("--angle", help="with --path reorient: the tool turns from -ANGLE to +ANGLE about the base's x "
                                   "axis, its point held (default 30deg)")
    p.add_argument("--angular-speed", default="0.5rad/s",
                   help="with --path reorient: the programmed turning speed (default 0.5rad/s)")
    p.add_argument("--angular-accel", default="2.5rad/s^2",
                   help="with --path reorient: the turning acceleration at start and stop (default 2.5rad/s^2)")
    p.add_argument("--speed", default="0.1m/s", help="with --path: the programmed speed (default 0.1m/s)")
    p.add_argument("--accel", default="1m/s^2", help="with --path: the acceleration at start and stop (default 1m/s^2)")
    p.add_argument("--side", help="with --path: the cube's edge (default: the largest of 400mm halved that the robot "
                                  "reaches along the whole path)")
    p.add_argument("--center-joints", metavar="Q1,Q2,...",
                   help="with --path: the joints (each with its unit) whose tool pose is the cube's centre (default: "
                        "the centre of the ISO cube the planner finds)")
    p.add_argument("--dwell", default="0.5s", help="with --path: the rest before each cycle (default 0.5s)")
    p.add_argument("--profile", choices=["trapezoid", "raised-cosine", "minimum-jerk"], default="trapezoid",
                   help="with --path: each move's speed profile within --speed and --accel (default trapezoid; "
                        "raised-cosine and minimum-jerk as jerk-limited controllers move)")
    p.add_argument("--budget", help="scale each parameter by its tolerance (default 1 mm / 1 mrad)")
    p.add_argument("--noise", default="10um", help="tracker position noise (default 10um)")
    p.add_argument("--orientation-noise",
                   help="tracker orientation noise, e.g. 10urad: the tracker measures orientation")
    p.add_argument("--compare", metavar="CAMPAIGN",
                   help="ISO 9283 cube campaign to compare with (default: built by IK)")
    p.add_argument("--joint-range", action="append", metavar="NAME=LO:HI",
                   help="sample joint NAME only within LO:HI, with units (shoulder_lift_joint=-180deg:0deg); "
                        "repeatable; within the joint's limits")
    p.add_argument("--floor-plane", metavar="Z",
                   help="the plane z = Z of the base frame (e.g. 0m): the tool and the moving links stay above it")
    p.add_argument("--above-plane", action="append", metavar="NX,NY,NZ@OFFSET",
                   help="a plane (normal, then offset with its unit: 0,0,1@0.05m is z >= 0.05 m; -1,0,0@-0.8m "
                        "is x <= 0.8 m): the tool and the moving links stay on its side; repeatable")
    p.add_argument("--inside-box", metavar="XMIN:XMAX,YMIN:YMAX,ZMIN:ZMAX",
                   help="the tool position stays in this box of the base frame, with units "
                        "(0.2m:1.2m,-0.6m:0.6m,0m:1m)")
    p.add_argument("--clearance", metavar="LENGTH",
                   help="least distance of the moving links from the planes (default 0m)")
    p.add_argument("--no-collision", action="store_true",
                   help="do not check self-collision and the links against the planes (URDF collision geometry)")
    p.add_argument("--srdf", metavar="FILE",
                   help="link pairs not checked for self-collision (its disable_collisions; default: adjacent "
                        "links and those in contact at the zero configuration)")
    p.add_argument("--contact", action="append", default=[], metavar="plane:ID=NX,NY,NZ@OFFSET|point:ID=X,Y,Z",
                   help="plan contacts instead of tracker poses: the targets (--target) touch this plane or point (its "
                        "nominal place, base frame); repeatable (docs/calibration.md, 'Without a tracker')")
    p.add_argument("--target", action="append", default=[], metavar="NAME=X,Y,Z|NAME=link:LINK",
                   help="with --contact: a target of the tool (tool frame, a unit on each); repeatable")
    p.add_argument("--out", metavar="FILE", help="campaign file to write (without it nothing is written, as allocate)")
    p.add_argument("--plot", metavar="DIR", help="write singular_values.png into DIR")


def run_path(args, model):
    """``--path``: the test path's joint trajectory written to ``--out`` (YAML, SI)."""
    from ..core.accuracy import iso_paths as P
    from ..core.accuracy.path import arc_length, corners
    cycles = 10 if args.cycles is None else args.cycles
    if cycles < 1:
        raise CLIError("--cycles: must be >= 1")
    if args.path == "reorient":
        speed = bounded(args.angular_speed, "angular speed", "--angular-speed", top=P.MAX_ANGULAR_SPEED)
        accel = bounded(args.angular_accel, "angular acceleration", "--angular-accel", top=P.MAX_ANGULAR_ACCEL)
    else:
        speed = bounded(args.speed, "speed", "--speed", top=P.MAX_SPEED)
        accel = bounded(args.accel, "acceleration", "--accel", top=P.MAX_ACCEL)
    dwell = bounded(args.dwell, "time", "--dwell", 0.0, P.MAX_DWELL, "the rest before each cycle; one longer than ten "
                                                                     "minutes is a drift test (iso9283 --drift)")
    side = bounded(args.side, "length", "--side", P.MIN_SIDE, 2 * model.reach(),
                   "below 10 mm the test line holds fewer than 30 knots; beyond twice the robot's reach no cube fits")
    stroke = bounded(args.stroke, "length", "--stroke", P.MIN_STROKE, None,
                     "below 0.1 mm, ten times a tracker's noise, there is no weaving to measure")
    center = joints_option(model, args.center_joints, "--center-joints") if args.center_joints else None
    try:
        jp, tp = P.plan_path(model, args.path, speed, accel, dwell, cycles, side, center, seed=args.seed,
                             stroke=stroke,
                             pitch=quantity(args.pitch, "length", "--pitch"),
                             angle=quantity(args.angle, "angle", "--angle"),
                             distances=[quantity(x, "length", "--distances") for x in args.distances.split(",")]
                             if args.distances else None, profile=args.profile)
    except ValueError as exc:
        raise CLIError(str(exc)) from None
    if jp.period > P.MAX_PERIOD:
        raise CLIError(f"--speed, --dwell: a cycle would last {jp.period:.4g} s, beyond {P.MAX_PERIOD:g} s (an hour "
                       f"is no path test's cycle); a faster --speed or a shorter --dwell")
    test = tp.moves[tp.test]
    doc = jp.to_dict()
    doc.update(robot=model.name, side_m=tp.side, center_m=tp.center.tolist(), length_m=float(arc_length(test)[-1]),
               corners=len(corners(test)), period_s=jp.period, duration_s=jp.duration)
    turning = tp.turns is not None
    desc = (f"ISO 9283 {args.path} path by tolerance-ros plan-campaign: cube edge {tp.side * 1e3:.1f} mm centred at "
            f"[{', '.join(f'{v * 1e3:.1f}' for v in tp.center)}] mm, {speed:g} {'rad/s' if turning else 'm/s'}, "
            f"{cycles} cycles; SI (s, rad, m)")
    if args.out:
        write_yaml(args.out, desc, doc)
    if args.json:
        return {k: v for k, v in doc.items() if k != "points"} | {"points": len(jp.t), "file": args.out}
    print(desc)
    what = (f"the tool turning {np.degrees(2 * tp_angle(tp)):.1f} deg about its point" if turning else
            f"test path {doc['length_m'] * 1e3:.1f} mm with {doc['corners']} corner(s)")
    print(f"{what}; a cycle lasts {jp.period:.2f} s ({len(jp.t)} knots), {cycles} cycles {jp.duration:.1f} s")
    print(f"wrote {args.out}" if args.out else "trajectory not saved (give --out FILE.yaml to save it)")
    return None


def bounded(text, kind, option, low=None, top=None, why=""):
    """``quantity`` of an option that must lie in [low, top] (SI; None: no bound; a ``low`` of 0 allows 0, any other
    bound is inclusive too); CLIError naming the option and the bound, with ``why``."""
    value = quantity(text, kind, option, positive=low is None or low > 0)
    if value is None:
        return None
    if (low is not None and value < low) or (top is not None and value > top):
        unit = {"length": "m", "speed": "m/s", "acceleration": "m/s^2", "angular speed": "rad/s",
                "angular acceleration": "rad/s^2", "time": "s"}[kind]
        span = (f"from {low:g} to {top:.4g} {unit}" if low is not None and top is not None else
                f"at least {low:g} {unit}" if low is not None else f"at most {top:g} {unit}")
        raise CLIError(f"{option}: {text} is out of range: expected {span}" + (f" ({why})" if why else ""))
    return value


def tp_angle(tp) -> float:
    """Half the angle (rad) a reorientation turns through."""
    from ..core.geometry import rotation_error
    R = tp.turns[tp.test]
    return 0.5 * float(np.linalg.norm(rotation_error(R[-1], R[0])))


def write_yaml(path, desc, doc):
    """A campaign or trajectory file: ``desc`` as its first comment line, then ``doc`` as YAML."""
    from ..core.yamlio import dump_yaml
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(f"# {desc}\n" + dump_yaml(doc, sort_keys=False, default_flow_style=None, width=120))


def run_contacts(args, model):
    """``--contact``: contacts that make the contact calibration well determined (``contact_planning``)."""
    from ..core.calibration.contact_planning import plan_contacts
    from ..core.calibration.planning import CRITERIA, REFERENCES, campaign_dict
    if not args.contact or not args.target:
        raise CLIError("--contact, --target: give both (the planes or points, and the targets of the tool that touch "
                       "them)")
    if args.candidates < args.n:
        raise CLIError(f"--n: {args.n} contacts cannot be chosen from {args.candidates} candidates")
    if args.n * args.candidates > MAX_WORK:
        raise CLIError(f"--n x --candidates: {args.n} x {args.candidates} exceeds the cap of {MAX_WORK}")
    specs = contact_specs(args.contact)
    targets = target_options(args.target, model)
    try:
        pl = plan_contacts(model, specs, targets, args.n, args.candidates, args.criterion, args.seed)
    except ValueError as exc:
        raise CLIError(str(exc)) from None
    idx = CRITERIA[args.criterion]
    which = "; ".join(f"C{i + 1} {c} with {t}" for i, (c, t) in enumerate(zip(pl.contact, pl.target)))
    desc = (f"{args.n} contacts chosen by tolerance-ros plan-campaign: {idx} ({REFERENCES[idx]}) over {pl.candidates} "
            f"candidates touching {', '.join(args.contact)} (seed {args.seed}), nominal robot and rig: {which}")
    if args.out:
        write_yaml(args.out, desc, campaign_dict(model, pl.q, f"{model.name}_contacts", args.cycles or 1,
                                                 description=desc))
    if args.json:
        return pl.to_dict() | {"robot": model.name, "campaign_file": args.out}
    print(f"robot {model.name}: {args.n} contacts maximising {idx} ({REFERENCES[idx]}) over {pl.candidates} "
          f"candidates; {len(pl.columns)} unknowns (parameters and rig), held: {', '.join(pl.held) or 'none'}")
    rows = [[label, d.get("rank"), f"{d['O1'] * 1e3:.4g}", f"{d['O2']:.4g}", f"{d['O3'] * 1e3:.4g}",
             f"{d['O4'] * 1e3:.4g}", f"{d['condition']:.4g}"]
            for label, d in (("planned", pl.planned), ("random (median of 20)", pl.random))]
    print(table(["contact set", "rank", "O1 mm", "O2", "O3 mm", "O4 mm", "condition"], rows))
    print(table(["pose", "contact", "target"], [[f"C{i + 1}", c, t] for i, (c, t) in
                                                enumerate(zip(pl.contact, pl.target))]))
    print(f"wrote {args.out}" if args.out else "campaign not saved (give --out FILE.yaml to save it)")
    return None


def run_iso9283(args, model, ws):
    """``--iso9283``: the ISO 9283 cube's test poses, with their approaches (``planning.iso9283_campaign``)."""
    from ..core.accuracy.iso9283 import iso_cube_joints
    from ..core.calibration.planning import iso9283_campaign
    approach = quantity(args.approach, "length", "--approach") if args.approach else None
    reference = joints_option(model, args.configuration, "--configuration") if args.configuration else None
    if reference is not None:
        v = ws.check(np.array([reference]))
        if not v.ok[0]:
            raise CLIError(f"--configuration: {v.reason[0]}" + (f" ({v.detail[0]})" if v.detail[0] else ""))
    qc, _ = ws.sample(int(args.candidates), np.random.default_rng(args.seed), 10 * int(args.candidates))
    q, note = iso_cube_joints(model, qc, args.seed, allowed=lambda x: ws.check(x).ok, reference=reference)
    if q is None:
        raise CLIError(f"{note}; widen the restrictions or give more --candidates")
    desc = (f"ISO 9283 pose campaign by tolerance-ros plan-campaign: {note}"
            + (f"; each pose also approached along +x, +y, +z from {approach * 1e3:g} mm before it" if approach else ""))
    try:
        doc = iso9283_campaign(model, q, approach, cycles=args.cycles, description=desc, allowed=ws.check)
    except ValueError as exc:
        raise CLIError(str(exc)) from None
    if args.out:
        write_yaml(args.out, desc, doc)
    if args.json:
        return {"robot": model.name, "campaign_file": args.out, "description": desc,
                "poses": [p["name"] for p in doc["poses"]], "cycles": doc["cycles"]}
    print(desc)
    print(f"{len(doc['poses'])} test poses ({', '.join(p['name'] for p in doc['poses'])}), {doc['cycles']} cycles")
    print(f"wrote {args.out}" if args.out else "campaign not saved (give --out FILE.yaml to save it)")
    return None


def run(args):
    from ..core.calibration.planning import CRITERIA, REFERENCES, campaign_dict, plan
    from ..core.campaign import load_campaign
    from ..core.workspace import Workspace, listed, rejection_summary, restrictions
    model = load_model(args)
    if (args.stroke or args.pitch) and args.path != "weave":
        raise CLIError("--stroke, --pitch: go with --path weave")
    if args.angle and args.path != "reorient":
        raise CLIError("--angle: goes with --path reorient")
    if args.distances and args.path != "positioning":
        raise CLIError("--distances: goes with --path positioning")
    if args.configuration and not args.iso9283:
        raise CLIError("--configuration: goes with --iso9283 (a test path's centre: --center-joints)")
    modes = [o for o, on in (("--path", args.path), ("--iso9283", args.iso9283),
                             ("--contact", args.contact or args.target)) if on]
    if len(modes) > 1:
        raise CLIError(f"{', '.join(modes)}: one kind of campaign at a time (a test path, the ISO 9283 pose campaign, "
                       f"or contacts); run plan-campaign once for each")
    if args.path:
        return run_path(args, model)
    if args.approach and not args.iso9283:
        raise CLIError("--approach: goes with --iso9283")
    if args.contact or args.target:
        return run_contacts(args, model)
    if args.cycles is None:
        args.cycles = 30 if args.iso9283 else 3
    for name in ("candidates", "cycles"):
        if getattr(args, name) < 1:
            raise CLIError(f"--{name}: must be >= 1")
    if args.n * args.candidates > MAX_WORK:
        raise CLIError(f"--n x --candidates: {args.n} x {args.candidates} = {args.n * args.candidates} exceeds the cap "
                       f"of {MAX_WORK} (each of up to 20 x --n exchanges scores every candidate); lower --n or "
                       f"--candidates")
    if args.n > args.candidates:
        raise CLIError(f"--n: {args.n} test poses cannot be chosen from {args.candidates} candidates; give "
                       f"--candidates >= {args.n}")
    noise = quantity(args.noise, "length", "--noise")
    onoise = quantity(args.orientation_noise, "angle", "--orientation-noise")
    delta = load_budget(args.budget, model).vector_for(model) if args.budget else None
    ws = Workspace(model, restrictions(model, args.joint_range, args.above_plane, args.floor_plane, args.inside_box,
                                       args.clearance, not args.no_collision, args.srdf))
    if args.iso9283:
        return run_iso9283(args, model, ws)
    compare_bad = []
    iso = None
    if args.compare:
        camp = load_campaign(args.compare, model)
        iso = camp.joints_for(model)
        compare_bad = ws.violations(iso, camp.names)
    prog = Progress("plan-campaign", not args.quiet)
    prog(0, 1)
    pl = plan(model, args.n, args.criterion, args.candidates, args.seed, delta,
              noise / onoise if onoise else None, iso, progress=prog, workspace=ws)
    prog(1, 1)
    out_path = Path(args.out) if args.out else None
    idx = CRITERIA[args.criterion]
    desc = (f"{args.n} poses chosen by tolerance-ros plan-campaign: {idx} ({REFERENCES[idx]}) maximised by a DETMAX "
            f"exchange over {pl.candidates} candidates (seed {args.seed}); restrictions: "
            f"{ws.describe()}")
    if out_path is not None:
        write_yaml(out_path, desc, campaign_dict(model, pl.q, f"{model.name}_planned", args.cycles, description=desc,
                                                 restrictions=ws.rest.texts))
    plots = []
    if args.plot:
        from ..render import plots as P
        plots.append(str(P.singular_values(pl.spectra, Path(args.plot) / "singular_values.png",
                                           f"{model.name}: scaled identification Jacobian")))
    if args.json:
        doc = pl.to_dict()
        doc.update(robot=model.name, campaign_file=str(out_path) if out_path else None, plots=plots,
                   compare_violations=compare_bad)
        return doc
    print(f"restrictions: {ws.describe()}")
    print(rejection_summary(pl.restrictions) + (f"; {ws.collision_note}" if ws.collider is not None else ""))
    if pl.candidates < args.candidates:
        print(f"only {pl.candidates:,} of the {args.candidates:,} candidates asked for passed in "
              f"{pl.restrictions['drawn']:,} draws (at most 10 x --candidates are drawn); the poses are chosen "
              f"from those")
    print(f"robot {model.name}: {args.n} poses maximising {idx} ({REFERENCES[idx]}) over {pl.candidates} "
          f"candidates (seed {args.seed}, {pl.exchanges} exchanges); {len(pl.columns)} unknowns "
          f"({len(pl.columns) - 6} parameters + base), held: {', '.join(pl.held) or 'none'}")
    rows = []
    for label, d in (("planned", pl.chosen), (f"random (median of {pl.random['draws']})", pl.random),
                     ("ISO 9283 cube", pl.iso_cube)):
        if d is None:
            rows.append([label, "-", "-", "-", "-", "-", "-", "-"])
            continue
        rows.append([label, d.get("poses", args.n), f"{d['rank']}/{len(pl.columns)}", f"{d['O1'] * 1e3:.4g}",
                     f"{d['O2']:.4g}", f"{d['O3'] * 1e3:.4g}", f"{d['O4'] * 1e3:.4g}", f"{d['condition']:.4g}"])
    print(table(["pose set", "poses", "rank", "O1 mm", "O2", "O3 mm", "O4 mm", "condition"], rows))
    print(pl.iso_cube_note)
    if compare_bad:
        print(f"warning: {len(compare_bad)} of {len(iso)} poses of {args.compare} break the restrictions: "
              f"{listed(compare_bad)}")
    print(f"wrote {out_path}" if out_path else "campaign not saved (give --out FILE.yaml to save it)")
    for f in plots:
        print(f"plot: {f}")
