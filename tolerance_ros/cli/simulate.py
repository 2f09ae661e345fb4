"""`tolerance-ros simulate`: tracker measurements of a campaign on a simulated as-built robot, with the truth beside.

The as-built robot is drawn within a tolerance budget (or ``uniform:LENGTH,ANGLE`` for every length and angle
parameter; seeded), every test pose of the campaign is visited for its cycles, and a tracker placed at
``T_TRACKER_BASE`` reads the tool frame (``--noise``, ``--orientation-noise``) or, with ``--target-offset``,
the points of reflectors on the tool. The measurements go to ``--out`` (the CSV format ``report`` and
``calibrate`` read); the truth (the as-built errors, the tracker's placement and the targets) goes beside
them in the calibration file's format (``<out>.truth.yaml``), so that what ``calibrate`` finds can be checked
against it (``validate --calibration <out>.truth.yaml`` predicts with the truth itself).

With ``--trajectory`` (a joint trajectory, e.g. of ``plan-campaign --path``) instead of a campaign, the robot
drives it and the tracker streams its tool point during the motion (``--tracker-rate``, ``--latency``,
``--noise``; ``--repeatability`` a joint offset drawn per cycle), the controller logs its commanded joints
(``--joint-rate``) into ``<out>.joints.csv``: the two streams ``path-report`` reads.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .common import CLIError, contact_specs, load_model, point_option, quantity, relative

NAME = "simulate"
HELP = "tracker measurements of a campaign on a simulated as-built robot, with the truth beside"
ROBOT = True


def add_arguments(p):
    p.add_argument("--campaign", help="campaign file or shipped name (the test poses and cycles)")
    p.add_argument("--trajectory", metavar="FILE",
                   help="a joint trajectory (plan-campaign --path) driven instead of a campaign: the tracker streams "
                        "points during the motion and the joint states go to <out>.joints.csv")
    p.add_argument("--tracker-rate", default="1kHz", help="with --trajectory: the tracker's rate (default 1kHz)")
    p.add_argument("--joint-rate", default="500Hz", help="with --trajectory: the joint states' rate (default 500Hz)")
    p.add_argument("--latency", default="8ms",
                   help="with --trajectory: how late the tracker stamps its points (default 8ms)")
    p.add_argument("--repeatability", default="0rad",
                   help="with --trajectory: standard deviation of a joint offset drawn per joint and cycle (e.g. "
                        "0.1mrad; default 0rad)")
    p.add_argument("--settling", metavar="FREQUENCY,DAMPING",
                   help="with --trajectory: every joint follows the command as a second-order system of this natural "
                        "frequency and damping ratio (e.g. 8Hz,0.2): it lags in motion and overshoots at each stop")
    p.add_argument("--tolerances", required=True,
                   help="budget (file or shipped name) the as-built errors are drawn within, or uniform:LENGTH,ANGLE "
                        "(e.g. uniform:0.1mm,0.5mrad) for every parameter")
    p.add_argument("--out", required=True, metavar="FILE.csv",
                   help="the measurements (CSV); the truth goes beside it as FILE.truth.yaml")
    p.add_argument("--noise", default="10um", help="tracker position noise per axis (default 10um)")
    p.add_argument("--orientation-noise", default="10urad",
                   help="tracker orientation noise (default 10urad); measured frames only")
    p.add_argument("--target-offset", action="append", metavar="NAME=X,Y,Z", default=[],
                   help="a reflector at X,Y,Z (each with its unit, tool frame), e.g. R1=30mm,90mm,0mm; repeat for "
                        "several; the tracker then measures points (no orientation)")
    p.add_argument("--contact", action="append", default=[], metavar="plane:ID=NX,NY,NZ@OFFSET|point:ID=X,Y,Z",
                   help="instead of a tracker, the targets (--target-offset) touch this plane (unit normal and offset "
                        "along it, base frame, e.g. plane:table=0,0,1@300mm) or point (e.g. point:tip=1.6m,0.2m,0.6m); "
                        "repeat for several; writes a contact campaign and its truth (--noise: the contact's)")
    p.add_argument("--touches", type=int, default=20,
                   help="with --contact: postures per target and contact (default 20)")
    p.add_argument("--session", default="s1", help="with --contact: the session the rig belongs to (default s1)")
    p.add_argument("--flush", action="store_true",
                   help="with --contact: the targets touch a plane all at once (fingertips flush on a table), one "
                        "posture for all of them, instead of one at a time")
    p.add_argument("--backlash", default="0rad",
                   help="with --campaign: the play of every revolute joint (e.g. 0.2mrad): each lags half of it behind "
                        "the way it last moved, so that a pose attained from another direction (a pre-pose, ISO 9283 "
                        "vAP) or after another pose differs (default 0rad)")
    p.add_argument("--thermal", metavar="EXPANSION,TAU",
                   help="with --campaign: the robot warms up, every length growing by EXPANSION (1 - exp(-t/TAU)), "
                        "e.g. 100ppm,1h (ISO 9283 drift)")
    p.add_argument("--cycles", type=int, help="with --campaign: its cycles, instead of the file's (e.g. an 8-hour "
                                              "drift campaign)")
    p.add_argument("--load", metavar="FORCE",
                   help="with --campaign: each visit is also measured under this force at the tool along +x, -x, +y, "
                        "-y, +z and -z of the base frame (e.g. 200N), written in load columns (ISO 9283 static "
                        "compliance); the robot yields at its joints (--joint-stiffness)")
    p.add_argument("--torque", metavar="TORQUE",
                   help="with --campaign: each visit is also measured under this torque at the tool about +x, -x, +y, "
                        "-y, +z and -z (e.g. 20Nm), written in load:mx, load:my, load:mz columns")
    p.add_argument("--joint-stiffness", default="50kNm/rad",
                   help="with --load: every revolute joint's stiffness (default 50kNm/rad; prismatic joints rigid)")
    p.add_argument("--errors", choices=["uniform", "extreme", "normal"], default="uniform",
                   help="how the as-built errors are drawn within the tolerances (default uniform)")
    p.add_argument("--seed", type=int, default=0, help="seed of the as-built robot and the noise (default 0)")


def _tolerances(model, spec):
    from ..core.budget import BudgetError, tolerance_vector
    try:
        return tolerance_vector(spec, model)
    except BudgetError as exc:
        raise CLIError(f"--{exc}" if str(exc).startswith("tolerances:") else str(exc)) from None


def _targets(specs):
    from ..core.targets import Targets
    if not specs:
        return None
    names, offsets = [], []
    for spec in specs:
        name, eq, coords = spec.partition("=")
        offset = point_option(coords, "--target-offset") if eq and name.strip() else None
        if offset is None:
            raise CLIError(f"--target-offset: expected NAME=X,Y,Z with a unit on each (e.g. R1=30mm,90mm,0mm), got "
                           f"{spec!r}")
        names.append(name.strip())
        offsets.append(offset)
    if len(set(names)) != len(names):
        raise CLIError(f"--target-offset: the names must differ, got {names}")
    return Targets.from_offsets(names, offsets)


def _run_trajectory(args, model, delta, noise, out):
    """The streams of a trajectory driven by the as-built robot (see the module docstring)."""
    from ..core.accuracy.io.joint_states import write_joint_states, write_points
    from ..core.accuracy.iso_paths import read_trajectory
    from ..core.accuracy.simulate import as_built_errors, path_streams
    from ..core.geometry import transform
    if args.campaign:
        raise CLIError("--trajectory: give it instead of --campaign")
    if len(args.target_offset) > 1:
        raise CLIError("--trajectory: one --target-offset at most (the tracker follows one target along the path)")
    targets = _targets(args.target_offset) if args.target_offset else None
    offset = targets.offsets[0] if targets is not None else None
    try:
        jp = read_trajectory(args.trajectory, model)
    except ValueError as exc:
        raise CLIError(str(exc)) from None
    rate = quantity(args.tracker_rate, "frequency", "--tracker-rate")
    jrate = quantity(args.joint_rate, "frequency", "--joint-rate")
    latency = quantity(args.latency, "time", "--latency", positive=False)
    rep = quantity(args.repeatability, "angle", "--repeatability", positive=False)
    if jp.duration * max(rate, jrate) > 5e7:
        raise CLIError(f"--tracker-rate: {jp.duration:.0f} s at {max(rate, jrate):g} Hz exceeds 50,000,000 samples")
    dx = as_built_errors(delta, args.seed, args.errors)
    T_tracker = transform([1.5, -0.3, 0.2], [0.05, -0.02, 1.2])
    frames = jp.kind == "reorient"        # the tool turns about its point: a 6-DOF tracker measures frames
    st = path_streams(model, jp, dx, T_tracker, jrate, rate, latency, noise, args.seed + 1, repeatability=rep,
                      offset=offset, settling=_settling(args.settling),
                      noise_orientation=quantity(args.orientation_noise, "angle", "--orientation-noise",
                                                 positive=False) if frames else None)
    settling = f"joints settling as {args.settling}" if args.settling else ""
    comment = (f"simulated by tolerance-ros simulate: {model.name} as built within {args.tolerances} ({args.errors}, "
               f"seed {args.seed}) driving {args.trajectory}; tracker {args.tracker_rate}, {args.latency} late, "
               f"noise {args.noise}" + (f"; {settling}" if settling else ""))
    if frames:
        from ..core.accuracy.io import Measurements, write_csv
        T = np.tile(np.eye(4), (len(st.stamps), 1, 1))
        T[:, :3, :3], T[:, :3, 3] = st.rotations, st.points
        write_csv(out, Measurements(st.stamps, T, source="simulated"), comments=[comment])
    else:
        write_points(out, st.stamps, st.points, [comment])
    joints = write_joint_states(out.with_name(f"{out.stem}.joints.csv"), st.joint_stamps, st.joints, model.joint_names,
                                model.joint_types, [comment])
    truth_path = _truth(args, model, dx, T_tracker, noise, out, len(st.stamps), 0, targets, "base", False,
                        f" driving {args.trajectory}" + (f", {settling}" if settling else ""))
    doc = {"measurements": str(out), "joint_states": str(joints), "truth": str(truth_path), "rows": len(st.stamps),
           "joint_state_rows": len(st.joint_stamps), "latency_s": latency, "noise_m": noise,
           "duration_s": jp.duration}
    if args.json:
        return doc
    print(f"wrote {out}: {len(st.stamps)} tracker points over {jp.duration:.1f} s ({jp.cycles} cycles of "
          f"{args.trajectory}), stamped {latency * 1e3:g} ms late")
    print(f"wrote {joints}: {len(st.joint_stamps)} joint states")
    print(f"wrote {truth_path}: the as-built errors and the tracker's placement (calibration format)")
    return None


def _run_contacts(args, model, delta, noise, out):
    """A contact campaign of the as-built robot (see ``core.accuracy.simulate.touch``) and its truth."""
    import json
    from ..core.accuracy.io.contact_csv import write_contacts
    from ..core.accuracy.simulate import as_built_errors, touch
    if args.campaign:
        raise CLIError("--contact: give it instead of --campaign (the postures are found to touch the rig)")
    if not args.target_offset:
        raise CLIError("--contact: name the tool's points in contact with --target-offset NAME=X,Y,Z")
    if not 1 <= args.touches <= 10000:
        raise CLIError(f"--touches: expected 1 to 10000, got {args.touches}")
    specs = contact_specs(args.contact)
    targets = _targets(args.target_offset)
    dx = as_built_errors(delta, args.seed, args.errors)
    rows = {"q": [], "target": [], "contact": [], "pose": [], "stamp": []}
    for c, (kind, cid, where) in enumerate(specs):
        flush = args.flush and kind == "plane" and len(targets.names) > 1
        groups = [(list(range(len(targets.names))), "all")] if flush else [([k], n) for k, n in
                                                                         enumerate(targets.names)]
        for g, (ks, label) in enumerate(groups):
            try:
                q = touch(model, dx, targets.offsets[ks], kind, where, args.touches,
                          seed=[args.seed, c, g, int(flush), sum(map(ord, args.session))], noise=noise)
            except ValueError as exc:
                raise CLIError(f"--contact {kind}:{cid}, target(s) {', '.join(targets.names[k] for k in ks)}: {exc}") \
                    from None
            for i, qi in enumerate(q):        # the targets of a flush contact: rows of one stamp and pose
                stamp = float(len(rows["stamp"]) and rows["stamp"][-1] + 1.0)
                for k in ks:
                    rows["q"].append(qi)
                    rows["target"].append(targets.names[k])
                    rows["contact"].append(f"{kind}:{cid}")
                    rows["pose"].append(f"{args.session}-{kind}-{cid}-{label}-{i + 1}")
                    rows["stamp"].append(stamp)
    q = np.array(rows["q"])
    n = len(q)
    comment = (f"simulated by tolerance-ros simulate: {model.name} as built within {args.tolerances} ({args.errors}, "
               f"seed {args.seed}) touching " + ", ".join(args.contact) + f"{' (flush)' if args.flush else ''}; contact "
               f"noise {args.noise}; truth in {out.stem}.truth.yaml and {out.stem}.rig.json")
    write_contacts(out, np.array(rows["stamp"]), rows["pose"], [args.session] * n, rows["target"], rows["contact"], q,
                   model.joint_names, model.joint_types, [comment])
    truth_path = _truth(args, model, dx, np.eye(4), noise, out, n, n, targets, "contact", False, " touching the rig")
    rig = {"session": args.session, "targets": {nm: list(map(float, o)) for nm, o in zip(targets.names, targets.offsets)},
           "planes": [{"id": i, "normal": w[0].tolist(), "offset_m": float(w[1])} for k, i, w in specs if k == "plane"],
           "points": [{"id": i, "xyz_m": w.tolist()} for k, i, w in specs if k == "point"]}
    rig_path = out.with_name(f"{out.stem}.rig.json")
    rig_path.write_text(json.dumps(rig, indent=1) + "\n")
    doc = {"measurements": str(out), "truth": str(truth_path), "rig": str(rig_path), "rows": n, "noise_m": noise}
    if args.json:
        return doc
    planes = sum(k == "plane" for k, _, _ in specs)
    print(f"wrote {out}: {n} contacts of {len(targets.names)} target(s) with {planes} plane(s) and "
          f"{len(specs) - planes} point(s), session {args.session}")
    print(f"wrote {truth_path}: the as-built errors and the targets (calibration format); {rig_path}: the rig")
    return None


def _settling(spec):
    """(natural frequency rad/s, damping ratio) of ``--settling FREQUENCY,DAMPING``, or None."""
    if not spec:
        return None
    parts = spec.split(",")
    if len(parts) != 2:
        raise CLIError(f"--settling: expected FREQUENCY,DAMPING (e.g. 8Hz,0.2), got {spec!r}")
    f = quantity(parts[0], "frequency", "--settling")
    try:
        zeta = float(parts[1])
    except ValueError:
        raise CLIError(f"--settling: the damping ratio {parts[1]!r} is not a number") from None
    if not (0 < zeta <= 10 and 0.1 <= f <= 1e3):
        raise CLIError(f"--settling: expected 0.1Hz to 1kHz and a damping ratio in (0, 10], got {spec!r}")
    return 2 * np.pi * f, zeta


def _growth(spec, stamps):
    """(n,) thermal growth of ``--thermal EXPANSION,TAU`` at the stamps, or None."""
    from ..core.accuracy.simulate import thermal_expansion
    if not spec:
        return None
    parts = spec.split(",")
    if len(parts) != 2 or not parts[0].strip().endswith("ppm"):
        raise CLIError(f"--thermal: expected EXPANSION,TAU with EXPANSION in ppm (e.g. 100ppm,1h), got {spec!r}")
    try:
        expansion = float(parts[0].strip()[:-3]) * 1e-6
    except ValueError:
        raise CLIError(f"--thermal: {parts[0]!r} is not a number of ppm") from None
    if not 0 <= expansion <= 1e-2:
        raise CLIError(f"--thermal: expected an expansion of 0 to 10000ppm, got {parts[0]!r}")
    return thermal_expansion(stamps, expansion, quantity(parts[1], "time", "--thermal"))


def _truth(args, model, dx, T_tracker, noise, out, rows, poses, targets, registration, orientation, what):
    """The truth beside the measurements (calibration format): its path."""
    from ..core.calibration.calibrate import Calibration
    from ..core.calibration.calibration_file import save_calibration
    from ..core.calibration.result import nominal_fingerprint
    truth = Calibration(model.name, tuple(model.param_names), tuple(model.param_kinds), dx, np.zeros_like(dx),
                        np.zeros(6), T_tracker, None, [], [], {}, float("nan"), float("nan"), 0, 0, noise,
                        float("nan"), float("nan"), rows, poses, 0, registration, targets=targets,
                        has_orientation=orientation)
    truth.nominal = nominal_fingerprint(model)
    source = getattr(model, "config_path", None) or getattr(model, "source", None)
    plan = args.campaign or args.trajectory      # a file relative to the truth file, as its other paths; or a name
    truth.sources = {"robot": relative(source, out.parent) if source and Path(str(source)).is_file() else model.name,
                     "measurements": out.name,
                     "campaign": relative(plan, out.parent) if plan and Path(plan).is_file() else plan,
                     "joint_names": list(model.joint_names),
                     "truth": f"simulated as built within {args.tolerances} ({args.errors}, seed {args.seed}){what}"}
    if hasattr(model, "tip_link"):
        truth.sources.update(tip_link=model.tip_link, base_link=model.base_link)
    truth.model = {"parameters": "truth", "label": "the simulated as-built robot", "how": "drawn, not identified"}
    return save_calibration(truth, out.with_name(f"{out.stem}.truth.yaml"))


def run(args):
    from ..core.accuracy.io import write_csv
    from ..core.accuracy.simulate import as_built_errors, backlash, joint_compliance, measure_targets
    from ..core.campaign import load_campaign
    from ..core.geometry import transform
    model = load_model(args)
    delta = _tolerances(model, args.tolerances)
    noise = quantity(args.noise, "length", "--noise", positive=False)
    out = Path(args.out)
    if out.suffix.lower() != ".csv":
        raise CLIError(f"--out: the measurements are a CSV file (name ending in .csv), got {args.out!r}")
    campaign_only = [o for o, v in (("--backlash", args.backlash != "0rad"), ("--thermal", args.thermal),
                                    ("--cycles", args.cycles is not None), ("--load", args.load),
                                    ("--torque", args.torque)) if v]
    if (args.trajectory or args.contact) and campaign_only:
        raise CLIError(f"{', '.join(campaign_only)}: with --campaign only")
    if args.settling and not args.trajectory:
        raise CLIError("--settling: with --trajectory only (the robot's motion between stops)")
    if args.trajectory:
        return _run_trajectory(args, model, delta, noise, out)
    if args.contact:
        return _run_contacts(args, model, delta, noise, out)
    if not args.campaign:
        raise CLIError("--campaign: required (or --trajectory for a path driven while the tracker streams)")
    campaign = load_campaign(args.campaign, model)
    if args.cycles is not None:
        from ..core.campaign import MAX_CYCLES
        if not 1 <= args.cycles <= MAX_CYCLES:
            raise CLIError(f"--cycles: expected 1 to {MAX_CYCLES}, got {args.cycles}")
        campaign.cycles = args.cycles
    targets = _targets(args.target_offset)
    onoise = quantity(args.orientation_noise, "angle", "--orientation-noise", positive=False)
    play = quantity(args.backlash, "angle", "--backlash", positive=False)
    if play < 0 or play > 0.05:
        raise CLIError(f"--backlash: expected 0 to 50mrad, got {args.backlash!r}")
    dx = as_built_errors(delta, args.seed, args.errors)
    T_tracker = transform([1.5, -0.3, 0.2], [0.05, -0.02, 1.2])
    steps, pose, cycle, via = campaign.steps(model)    # every configuration driven, pre-poses too
    visit = ~via
    q = steps[visit]
    stamps = np.flatnonzero(visit) * campaign.dwell_s
    labels = np.array(campaign.names, dtype=object)[pose[visit]]
    revolute = np.array([t != "prismatic" for t in model.joint_types])
    deflection = backlash(steps, play, revolute)[visit] if play > 0 else None
    growth = _growth(args.thermal, stamps)
    cycles = cycle[visit]
    force = None
    if args.load or args.torque:       # each visit: unloaded, then under each load along +-x, +-y, +-z
        F = quantity(args.load, "force", "--load") if args.load else 0.0
        M = quantity(args.torque, "torque", "--torque") if args.torque else 0.0
        width = 6 if args.torque else 3
        axes = [v * np.eye(width)[k] for v, first in ((F, 0), (M, 3)) if v for k in range(first, first + 3)]
        steps6 = np.vstack([np.zeros(width), *[s * a for a in axes for s in (1, -1)]])
        k = len(steps6)
        force = np.tile(steps6, (len(q), 1))
        stiffness = quantity(args.joint_stiffness, "stiffness", "--joint-stiffness")
        q, labels, cycles = np.repeat(q, k, axis=0), np.repeat(labels, k), np.repeat(cycles, k)
        stamps = np.repeat(stamps, k) + np.tile(np.arange(k), len(stamps)) * campaign.dwell_s / k
        deflection = None if deflection is None else np.repeat(deflection, k, axis=0)
        growth = None if growth is None else np.repeat(growth, k)
        stiff = np.where(revolute, stiffness, np.inf)
        bend = joint_compliance(model, q, dx, force, stiff)
        deflection = bend if deflection is None else deflection + bend
    meas = measure_targets(model, q, dx, targets, noise, 0.0 if targets is not None else onoise, T_tracker,
                           args.seed + 1, stamps, labels, points=targets is not None, deflection=deflection,
                           growth=growth)
    rows = len(meas)
    meas.cycle = np.repeat(cycles, rows // len(q))
    if force is not None:
        meas.load = np.repeat(force, rows // len(q), axis=0)
    robot = ((f", backlash {args.backlash}" if play > 0 else "") + (f", warming up {args.thermal}" if args.thermal
                                                                     else "")
             + (f", loads of {' and '.join(x for x in (args.load, args.torque) if x)} on joints of "
                f"{args.joint_stiffness}" if args.load or args.torque else ""))   # in the file and in its truth
    comment = (f"simulated by tolerance-ros simulate: {model.name} as built within {args.tolerances} ({args.errors}, "
               f"seed {args.seed}), tracker noise {args.noise}" + (f" / {args.orientation_noise}" if targets is None
                                                                      else "")
               + robot + f"; truth in {out.stem}.truth.yaml")
    write_csv(out, meas, comments=[comment])
    names, tg = (tuple(targets.names), targets) if targets is not None else (("",), None)
    truth_path = _truth(args, model, dx, T_tracker, noise, out, rows, len(campaign.names), tg,
                        "base+tool" if targets is not None else "base", targets is None, robot)
    doc = {"measurements": str(out), "truth": str(truth_path), "rows": rows, "poses": len(campaign.names),
           "visits": len(q), "targets": [n for n in names if n], "noise_m": noise,
           "orientation_noise_rad": None if targets is not None else onoise}
    if args.json:
        return doc
    print(f"wrote {out}: {rows} measurements of {len(campaign.names)} test poses x {campaign.cycles} cycles of "
          f"{campaign.name}" + (f" at {len(names)} targets" if targets is not None else ""))
    print(f"wrote {truth_path}: the as-built errors, the tracker's placement and the targets (calibration format)")
    return None
