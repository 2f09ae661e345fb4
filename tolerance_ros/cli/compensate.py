"""`tolerance-ros compensate`: joints that put the calibrated robot's tool at each of a program's poses."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from ..render.text import table
from .common import CLIError, enveloped_calibration, envelope_options, load_model, missed

NAME = "compensate"
HELP = "joints that put the calibrated robot's tool at each of a program's poses"
ROBOT = True


def add_arguments(p):
    p.add_argument("--calibration", required=True, help="calibration.yaml written by calibrate")
    p.add_argument("--poses", help="the program's poses to correct: a campaign file of nominal joints or tool poses")
    p.add_argument("--targets", dest="poses_old", help=argparse.SUPPRESS)  # the name before --poses: a reflector
    # is a "target" everywhere else (--target below, the monitor's targets)
    p.add_argument("--match", choices=["pose", "position"], default="pose", help="match the whole pose or the position")
    p.add_argument("--seed", type=int, default=0, help="seed of the starts for tool poses")
    p.add_argument("--target", help="the calibration's target whose point is the tool point (default: its first; "
                                    "pose targets are tool poses there)")
    p.add_argument("--out", metavar="FILE", help="write the compensated joints as a campaign file (a flagged "
                                                  "pose with its nominal joints, named in the file's notes)")
    envelope_options(p, "displacement of the tool point")
    p.add_argument("--accept-flagged", action="store_true",
                   help="write the compensated joints of flagged poses too (out of reach, near a singularity, out "
                        "of limits)")


FLAGS = ("out of reach", "near singularity", "out of limits")


def compensate_poses(model, targets, calibrated, nominal, envelope, match="pose", seed=0) -> list:
    """One dict per pose of the campaign ``targets``: its nominal and compensated joints (SI), the correction,
    the residuals and its ``flags`` (out of reach, near a singularity, out of the limits, or a joint changed beyond
    the ``envelope``: ``Envelope.point_changes``, as the trajectory node holds every point); a pose approached from
    a pre-pose (``via``) has its pre-pose compensated too (``via``: its joints, correction, flags), and the
    pre-pose's flags are the pose's."""
    from ..core.calibration.compensate import compensate
    results = [None] * len(targets.poses)
    jobs = [([i for i, tp in enumerate(targets.poses) if tp.joints is not None], "joints", None),
            ([i for i, tp in enumerate(targets.poses) if tp.joints is None], "pose", None),
            ([i for i, tp in enumerate(targets.poses) if tp.via is not None], "joints", "via")]
    for idx, kind, part in jobs:
        if not idx:
            continue
        if kind == "joints":
            q = np.array([targets.poses[i].via if part else targets.poses[i].joints for i in idx])
            comp = compensate(calibrated, nominal, joints=model.check_joints(q, "poses"), match=match)
        else:
            comp = compensate(calibrated, nominal, poses=np.array([targets.poses[i].pose for i in idx]), match=match,
                              rng=seed)
        d = comp.to_dict()
        over = envelope.point_changes(model, comp.correction)
        for k, i in enumerate(idx):
            r = {"nominal_joints": d["nominal_joints"][k], "joints": d["joints"][k], "correction": d["correction"][k],
                 "residual_position_m": float(comp.residual_position[k]),
                 "residual_orientation_rad": float(comp.residual_orientation[k]),
                 "reached": bool(comp.reached[k]), "near_singularity": bool(comp.near_singularity[k]),
                 "out_of_limits": bool(comp.out_of_limits[k])}
            r["flags"] = [f for f, on in zip(FLAGS, (not r["reached"], r["near_singularity"], r["out_of_limits"]))
                          if on] + ([f"beyond the envelope: {over[k]}"] if k in over else [])
            if part is None:
                results[i] = {"name": targets.poses[i].name, "given": kind, **r}
            else:
                results[i]["via"] = r
                results[i]["flags"] += [f"pre-pose {f}" for f in r["flags"]]
                results[i]["reached"] = results[i]["reached"] and r["reached"]
    return results


def run(args):
    from ..core.campaign import load_campaign
    model = load_model(args)
    cal, envelope = enveloped_calibration(args, model)
    try:
        calibrated, nominal = cal.mechanism(model, args.target), cal.nominal_at_tool_point(model, args.target)
    except ValueError as exc:
        raise CLIError(f"--target: {exc}") from None
    if args.poses_old and args.poses:
        raise CLIError("--poses: give it once (--targets is its old name)")
    if args.poses_old:
        print("compensate: --targets is now --poses (a target is a reflector or marker elsewhere)", file=sys.stderr)
    if not (args.poses or args.poses_old):
        raise CLIError("--poses: the program's poses to correct (a campaign file) are required")
    targets = load_campaign(args.poses or args.poses_old, model)
    results = compensate_poses(model, targets, calibrated, nominal, envelope, args.match, args.seed)
    unreached = [r["name"] for r in results if not r["reached"]]
    if unreached:
        missed(args, f"{len(unreached)} pose(s) out of reach of the calibrated robot: {', '.join(unreached)}")
    for r in results:
        r["written"] = "nominal" if r["flags"] and not args.accept_flagged else "compensated"
    out_path = None
    if args.out:
        from ..core.calibration.planning import campaign_dict, file_joints
        doc = campaign_dict(model, np.array([r["joints"] if r["written"] == "compensated" else r["nominal_joints"]
                                             for r in results]), f"{targets.name}_compensated",
                            targets.cycles, targets.dwell_s,
                            f"{targets.name} compensated with {Path(args.calibration).name} (tolerance-ros compensate)")
        doc["order"] = targets.order
        prismatic = [t == "prismatic" for t in model.joint_types]
        for entry, r, tp in zip(doc["poses"], results, targets.poses):
            entry["name"] = r["name"]
            if tp.of is not None:
                entry["of"] = tp.of
            if tp.approach is not None:
                entry["approach"] = tp.approach
            if "via" in r:   # the pre-pose corrected with its pose, so that the approach keeps its direction
                entry["via"] = file_joints(r["via"]["joints"] if r["written"] == "compensated"
                                           else r["via"]["nominal_joints"], prismatic)
        kept = [f"{r['name']} ({', '.join(r['flags'])})" for r in results if r["written"] == "nominal"]
        if kept:
            doc["notes"] = ("flagged, written with their nominal joints (--accept-flagged writes their compensated "
                            "joints): " + "; ".join(kept))
            if not args.quiet:
                print(f"compensate: {len(kept)} flagged pose(s) written with their nominal joints: "
                      f"{'; '.join(kept)} (--accept-flagged to write the corrections)", file=sys.stderr)
        out_path = Path(args.out)
        out_path.parent.mkdir(parents=True, exist_ok=True)
        from ..core.yamlio import dump_yaml
        out_path.write_text(dump_yaml(doc, sort_keys=False, default_flow_style=None, width=120))
    if args.json:
        return {"robot": model.name, "calibration": str(args.calibration), "match": args.match,
                "joint_names": list(model.joint_names), "poses": results,
                "out_of_reach": unreached, "out": str(out_path) if out_path else None}
    rev = [t != "prismatic" for t in model.joint_types]

    def shown(v, per_rad, per_m):
        return ", ".join(f"{x * (per_rad if r else per_m):.4f}" for x, r in zip(v, rev))

    print(f"robot {model.name}, calibration {args.calibration}: {len(results)} poses ({args.match}); joints in deg "
          f"(prismatic mm), corrections in mdeg (prismatic um)")
    print(table(["pose", "given", "compensated joints", "correction", "residual um", "flags"],
                [[r["name"], r["given"], shown(r["joints"], 180 / np.pi, 1e3),
                  shown(r["correction"], 18e4 / np.pi, 1e6), f"{r['residual_position_m'] * 1e6:.3g}",
                  ", ".join(r["flags"]) + (" (nominal written)" if out_path and r["written"] == "nominal" else "")]
                 for r in results]))
    if out_path:
        print(f"wrote {out_path}")
