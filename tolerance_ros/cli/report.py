"""`tolerance-ros report`: accuracy report of measured poses (registration, errors, budget check, ISO 9283, identification)."""
from __future__ import annotations

from ..core.accuracy.verdicts import describe
from ..core.budget import load_budget
from ..render.text import table
from .common import CLIError, load_model, missed, refuse_overwrite

NAME = "report"
HELP = "accuracy report of measured poses (ISO 9283, budget, identification)"
ROBOT = True


def add_arguments(p):
    p.add_argument("--measurements", required=True, help="CSV file, campaign log (.jsonl) or rosbag2 (dir, .db3, .mcap)")
    p.add_argument("--budget", help="tolerance budget to check against")
    p.add_argument("--campaign", help="campaign with the test poses (ISO 9283 statistics per pose)")
    p.add_argument("--registration", choices=["auto", "base", "base+tool", "none"], default="auto",
                   help="estimate the base (and tool) transform, or take measurements as base-frame; auto (default): "
                        "base or base+tool, the one that predicts held-out poses better (--stream: base)")
    p.add_argument("--skip-bad", action="store_true", help="skip malformed rows (they are listed), instead of failing")
    p.add_argument("--no-robust", action="store_true",
                   help="keep every row in the registration (by default rows beyond 4.6 robust sigmas of its residual "
                        "are left out of it and of the verdicts, and listed)")
    p.add_argument("--out", metavar="DIR", help="write report.md, plots, JSON and CSV into DIR")
    p.add_argument("--stream", action="store_true", help="constant memory for large CSV files (summary only)")
    p.add_argument("--decision-rule", default="guarded:2", metavar="guarded:K|simple",
                   help="how an identified part is judged against the budget (default guarded:2, ISO 14253-1 guarded "
                        "acceptance and rejection: out when |error| - K u > tolerance, within when |error| + K u <= "
                        "tolerance, else undecided; simple: out when |error| > tolerance). Exit 3 follows a part proven "
                        "out")


SKIPPED_SHOWN = 10  # skipped rows and records listed by `report` (--json lists them all)


def run(args):
    from ..core.accuracy.evaluation import evaluate_file
    from ..core.accuracy.io import read_measurements
    from ..core.campaign import load_campaign
    from ..render.accuracy_report import write_report
    from ..core.conformity import DecisionRule
    refuse_overwrite(args.out, ("report.md", "report.json", "measurements.csv", "per_pose.csv", "identification.csv",
                                "error_per_pose.png", "error_vs_bound.png", "identified_vs_tolerance.png"), args,
                     ("measurements", "campaign", "budget"))
    model = load_model(args)
    try:
        rule = DecisionRule.parse(args.decision_rule)
    except ValueError as exc:
        raise CLIError(f"--decision-rule: {exc}") from None
    budget = load_budget(args.budget, model) if args.budget else None
    campaign = load_campaign(args.campaign, model) if args.campaign else None
    if args.stream:
        from ..core.accuracy.evaluation import stream_file
        if args.skip_bad:
            raise CLIError("--skip-bad: not available with --stream, which stops at the first bad row")
        if args.registration == "base+tool":
            raise CLIError("--stream: the tool offset needs all measurements at once; use --registration base")
        res = stream_file(model, args.measurements, budget, campaign,
                          registration="base" if args.registration == "auto" else args.registration, rule=rule)
        _over_limit(args, res["summary"])
        _proven_out(args, res["summary"].get("identification"))
        if args.json:
            return res
        s = res["summary"]
        print(f"robot {model.name}: {res['measurements']} measurements streamed from {res['source']}; "
              f"{describe(s['verdicts'], s['exceeded'])}; position error mean "
              f"{s['position_error_m']['mean'] * 1e3:.4f} mm, max {s['position_error_m']['max'] * 1e3:.4f} mm")
        return None
    meas = read_measurements(args.measurements, joint_names=model.joint_names, skip_bad=args.skip_bad)
    res = evaluate_file(model, meas, budget, campaign, registration=args.registration, robust=not args.no_robust,
                        rule=rule)
    _over_limit(args, res["summary"])
    _proven_out(args, res.get("identification"))
    files = write_report(res, args.out, model, budget) if args.out else {}
    body = {k: v for k, v in res.items() if k != "rows"}
    body["files"] = files
    if args.json:
        return body
    s = res["summary"]
    pe = s["position_error_m"]
    print(f"robot {model.name}: {res['measurements']} measurements from {res['source']}"
          + (f"; {len(meas.skipped)} skipped:" if meas.skipped else ""))
    for skip in meas.skipped[:SKIPPED_SHOWN]:
        print("  " + ", ".join(f"{k} {v}" for k, v in skip.items() if k != "reason") + f": {skip['reason']}")
    if len(meas.skipped) > SKIPPED_SHOWN:
        print(f"  ... and {len(meas.skipped) - SKIPPED_SHOWN} more (all of them in skipped_rows of --json)")
    reg = res["registration"]
    if reg.get("choice"):
        from ..core.accuracy.checks import registration_words
        print(registration_words(reg["choice"]))
    oe = s.get("orientation_error_rad")
    print(f"registration {reg['method']}: residual RMS (3-D) {reg['residual_rms_m'] * 1e3:.4f} mm; position error at "
          f"the {'targets' if len(res['targets']) > 1 else 'measured point'} mean {pe['mean'] * 1e3:.4f}, max "
          f"{pe['max'] * 1e3:.4f} mm" + (f"; orientation error mean {oe['mean'] * 1e3:.4f}, max {oe['max'] * 1e3:.4f} mrad"
                                          if oe else " (points: no orientation measured)"))
    if reg.get("targets_estimated"):
        print("targets in the tool frame [mm]: " + "; ".join(
            f"{t['name'] or 'tool point'} ({', '.join(f'{v * 1e3:.3f}' for v in t['xyz_m'])})" for t in reg["targets"]))
    for r in res.get("left_out", []):
        print(f"left out: {r['where']}: {r['reason']}")
    for r in reg.get("left_out", []):
        print(f"not used by the registration: {r['where']}: {r['reason']}")
    for note in res.get("notes", []):
        print(f"NOTE: {note}")
    for w in res.get("warnings", []):
        print(f"WARNING: {w}")
        missed(args, w)
    if budget is not None:
        print(f"budget ({budget.criterion} bound): {describe(s['verdicts'], s['exceeded'])}")
    if res.get("per_pose"):
        keys = ("AP_p", "AP_a", "AP_b", "AP_c", "RP_l", "RP_a") if res["orientation_measured"] else ("AP_p", "RP_l")
        heads = {"AP_p": "AP_p mm", "AP_a": "AP_a mrad", "AP_b": "AP_b mrad", "AP_c": "AP_c mrad", "RP_l": "RP_l mm",
                 "RP_a": "RP_a mrad"}
        rows = [[n, v["n"]] + ([f"{v[k] * 1e3:.4f}" for k in keys] if "AP_p" in v else ["-"] * len(keys))
                for n, v in res["per_pose"].items()]
        print(table(["pose", "n"] + [heads[k] for k in keys], rows))
    ident = res.get("identification")
    if ident and ident.get("groups") is not None:
        from ..render.accuracy_report import decisions_text
        grp = ident["groups"]
        print(decisions_text(grp, f"identification against the budget, {len(grp['groups'])} groups (an estimated "
                                  f"parameter and the held ones it absorbs)"))
        if grp["absorbed_by_registration"]:
            print(f"absorbed by the registration (no campaign sees them): {', '.join(grp['absorbed_by_registration'])}")
        if grp["not_seen"]:
            print(f"not seen by these measurements: {', '.join(grp['not_seen'])}")
    elif ident:
        print(f"identification: without a budget no parameter is judged; rank {ident.get('rank')} of "
              f"{ident.get('unknowns')} unknowns")
    for k, v in files.items():
        for f in (v if isinstance(v, list) else [v]):
            print(f"wrote {f}")


def _over_limit(args, summary):
    n = summary["verdicts"].get("over limit", 0)
    if n:
        what = "; ".join(f"{v} over the {k}" for k, v in summary["exceeded"].items() if "limit" in k and v)
        missed(args, f"{n} of {summary['measurements']} measurements over the design limit ({what})")


def _proven_out(args, ident):
    """Exit 3 when the identification proves a part out of its tolerance (by the decision rule), naming them."""
    if not ident:
        return
    from ..core.conformity import out_words
    grp = ident.get("groups")
    if grp:
        words = out_words(grp)
    else:   # the linearised identification of a stream: parameters, no groups
        out = [o["name"] for o in ident.get("out_of_tolerance", [])]
        words = (f"{len(out)} part(s) decided out of tolerance by the decision rule {ident.get('decision_rule')}: "
                 f"{', '.join(out)}" if out else None)
    if words:
        missed(args, words)
