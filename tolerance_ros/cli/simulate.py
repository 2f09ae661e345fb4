"""`tolerance-ros simulate`: tracker measurements of a campaign on a simulated as-built robot, with the truth beside.

The as-built robot is drawn within a tolerance budget (or ``uniform:LENGTH,ANGLE`` for every length and angle
parameter; seeded), every test pose of the campaign is visited for its cycles, and a tracker placed at
``T_TRACKER_BASE`` reads the tool frame (``--noise``, ``--orientation-noise``) or, with ``--target-offset``,
the points of reflectors on the tool. The measurements go to ``--out`` (the CSV format ``report`` and
``calibrate`` read); the truth (the as-built errors, the tracker's placement and the targets) goes beside
them in the calibration file's format (``<out>.truth.yaml``), so that what ``calibrate`` finds can be checked
against it (``validate --calibration <out>.truth.yaml`` predicts with the truth itself).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .common import CLIError, load_model, quantity, relative

NAME = "simulate"
HELP = "tracker measurements of a campaign on a simulated as-built robot, with the truth beside"
ROBOT = True


def add_arguments(p):
    p.add_argument("--campaign", required=True, help="campaign file or shipped name (the test poses and cycles)")
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
    p.add_argument("--errors", choices=["uniform", "extreme", "normal"], default="uniform",
                   help="how the as-built errors are drawn within the tolerances (default uniform)")
    p.add_argument("--seed", type=int, default=0, help="seed of the as-built robot and the noise (default 0)")


def _tolerances(model, spec):
    from ..core.budget import load_budget
    if spec.startswith("uniform:"):
        parts = spec[len("uniform:"):].split(",")
        if len(parts) != 2:
            raise CLIError(f"--tolerances: expected uniform:LENGTH,ANGLE (e.g. uniform:0.1mm,0.5mrad), got {spec!r}")
        length, angle = quantity(parts[0], "length", "--tolerances"), quantity(parts[1], "angle", "--tolerances")
        return np.array([length if k == "length" else angle for k in model.param_kinds])
    return load_budget(spec, model).vector_for(model)


def _targets(specs):
    from ..core.accuracy.targets import Targets
    if not specs:
        return None
    names, offsets = [], []
    for spec in specs:
        name, eq, coords = spec.partition("=")
        parts = coords.split(",")
        if not eq or not name.strip() or len(parts) != 3:
            raise CLIError(f"--target-offset: expected NAME=X,Y,Z with a unit on each (e.g. R1=30mm,90mm,0mm), got "
                           f"{spec!r}")
        names.append(name.strip())
        offsets.append([quantity(c, "length", "--target-offset", positive=False) for c in parts])
    if len(set(names)) != len(names):
        raise CLIError(f"--target-offset: the names must differ, got {names}")
    return Targets.from_offsets(names, offsets)


def run(args):
    from ..core.accuracy.io import write_csv
    from ..core.accuracy.simulate import as_built_errors, measure_targets
    from ..core.calibration.calibrate import Calibration
    from ..core.calibration.writers import save_calibration
    from ..core.campaign import load_campaign
    from ..core.geometry import transform
    model = load_model(args)
    campaign = load_campaign(args.campaign, model)
    delta = _tolerances(model, args.tolerances)
    noise = quantity(args.noise, "length", "--noise", positive=False)
    targets = _targets(args.target_offset)
    onoise = quantity(args.orientation_noise, "angle", "--orientation-noise", positive=False)
    out = Path(args.out)
    if out.suffix.lower() != ".csv":
        raise CLIError(f"--out: the measurements are a CSV file (name ending in .csv), got {args.out!r}")
    dx = as_built_errors(delta, args.seed, args.errors)
    T_tracker = transform([1.5, -0.3, 0.2], [0.05, -0.02, 1.2])
    qk = campaign.joints_for(model)
    seq = campaign.sequence()
    q = np.array([qk[i] for i, _ in seq])
    labels = np.array([campaign.names[i] for i, _ in seq], dtype=object)
    meas = measure_targets(model, q, dx, targets, noise, 0.0 if targets is not None else onoise, T_tracker,
                           args.seed + 1, np.arange(len(q)) * campaign.dwell_s, labels, points=targets is not None)
    rows = len(meas)
    meas.cycle = np.repeat([c for _, c in seq], rows // len(q))
    comment = (f"simulated by tolerance-ros simulate: {model.name} as built within {args.tolerances} ({args.errors}, "
               f"seed {args.seed}), tracker noise {args.noise}" + (f" / {args.orientation_noise}" if targets is None
                                                                      else "") + f"; truth in {out.stem}.truth.yaml")
    write_csv(out, meas, comments=[comment])
    names, tg = (tuple(targets.names), targets) if targets is not None else (("",), None)
    truth = Calibration(model.name, tuple(model.param_names), tuple(model.param_kinds), dx, np.zeros_like(dx),
                        np.zeros(6), T_tracker, None, [], [], {}, float("nan"), float("nan"), 0, 0, noise,
                        float("nan"), float("nan"), rows, len(campaign.names), 0,
                        "base+tool" if targets is not None else "base", targets=tg, has_orientation=targets is None)
    source = getattr(model, "config_path", None) or getattr(model, "source", None)
    truth.sources = {"robot": relative(source, out.parent) if source and Path(str(source)).is_file() else model.name,
                     "measurements": out.name, "campaign": args.campaign, "joint_names": list(model.joint_names),
                     "truth": f"simulated as built within {args.tolerances} ({args.errors}, seed {args.seed})"}
    if hasattr(model, "tip_link"):
        truth.sources.update(tip_link=model.tip_link, base_link=model.base_link)
    truth.model = {"parameters": "truth", "label": "the simulated as-built robot", "how": "drawn, not identified"}
    truth_path = save_calibration(truth, out.with_name(f"{out.stem}.truth.yaml"))
    doc = {"measurements": str(out), "truth": str(truth_path), "rows": rows, "poses": len(campaign.names),
           "visits": len(q), "targets": [n for n in names if n], "noise_m": noise,
           "orientation_noise_rad": None if targets is not None else onoise}
    if args.json:
        return doc
    print(f"wrote {out}: {rows} measurements of {len(campaign.names)} test poses x {campaign.cycles} cycles of "
          f"{campaign.name}" + (f" at {len(names)} targets" if targets is not None else ""))
    print(f"wrote {truth_path}: the as-built errors, the tracker's placement and the targets (calibration format)")
    return None
