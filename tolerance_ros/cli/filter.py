"""`tolerance-ros filter`: a robot program corrected through a calibration, in its controller's own format
(docs/programs.md)."""
from __future__ import annotations

import os
import shlex
import shutil
import sys
from pathlib import Path

import numpy as np

from ..render.text import table
from .common import CLIError, enveloped_calibration, envelope_options, load_model, missed, quantity

NAME = "filter"
HELP = "correct a robot program (ABB RAPID, KUKA KRL, FANUC .ls, URScript) through a calibration, in its own format"
ROBOT = True


def add_arguments(p):
    p.add_argument("programs", nargs="+", metavar="PROGRAM",
                   help="the program's files (RAPID modules; a KRL .src or .dat, read with its partner; a FANUC .ls; a "
                        "URScript)")
    p.add_argument("--calibration", required=True, help="calibration.yaml written by calibrate")
    p.add_argument("--out", dest="out_path", metavar="PATH",
                   help="where to write: a folder (the files keep their names), or a file for a one-file program")
    p.add_argument("--in-place", action="store_true", help="write over the program, its original kept as FILE.orig")
    p.add_argument("--format", choices=["rapid", "krl", "fanuc", "urscript"],
                   help="the program's format (default: from its files' names)")
    p.add_argument("--tool", action="append", metavar="[NAME=]X,Y,Z,RX,RY,RZ",
                   help="a tool frame in the controller's flange frame, each value with its unit (rotations about the "
                        "fixed x, y, z axes): NAME= for a named tool (tooldata, TOOL_DATA number, UT number), without "
                        "a name the tool of motions whose tool the program does not say; repeat for several")
    p.add_argument("--frame", action="append", metavar="NAME=X,Y,Z,RX,RY,RZ",
                   help="a work object, user frame or base (wobjdata, BASE_DATA number, UF number, URScript feature) "
                        "in the controller's world frame; repeat for several")
    p.add_argument("--base", metavar="X,Y,Z,RX,RY,RZ",
                   help="the controller's world frame (wobj0, BASE 0, UF 0, the UR base) in the robot model's base "
                        "frame (default: the same frame)")
    p.add_argument("--flange", metavar="X,Y,Z,RX,RY,RZ",
                   help="the controller's flange frame (tool0, UT 0) in the model's tool frame (default: the same)")
    p.add_argument("--fanuc-j3", choices=["absolute", "relative"], default="absolute",
                   help="FANUC joint positions: J3 from the horizontal, as FANUC writes it (default), or relative to "
                        "the upper arm as the model's joint 3")
    envelope_options(p, "move of a Cartesian target")


def pose_option(text, option) -> np.ndarray:
    """4x4 (m) of ``X,Y,Z,RX,RY,RZ`` (a unit on each; turns about the fixed x, y, z axes, R = Rz Ry Rx)."""
    from ..core.geometry import transform
    parts = str(text).split(",")
    if len(parts) != 6:
        raise CLIError(f"{option}: expected X,Y,Z,RX,RY,RZ with a unit on each (e.g. 0mm,0mm,200mm,0deg,0deg,0deg), "
                       f"got {text!r}")
    xyz = [quantity(v, "length", option, positive=False) for v in parts[:3]]
    rpy = [quantity(v, "angle", option, positive=False) for v in parts[3:]]
    return transform(xyz, rpy)


def _named(specs, option, allow_unnamed):
    named, unnamed = {}, None
    for spec in specs or []:
        name, eq, value = spec.partition("=")
        if not eq:
            if not allow_unnamed:
                raise CLIError(f"{option}: expected NAME=X,Y,Z,RX,RY,RZ, got {spec!r}")
            if unnamed is not None:
                raise CLIError(f"{option}: one tool without a name at most")
            unnamed = pose_option(spec, option)
            continue
        name = name.strip()
        if not name or name.lower() in named:
            raise CLIError(f"{option}: {'a name is empty' if not name else f'{name} given twice'} in {spec!r}")
        named[name.lower()] = pose_option(value, option)
    return named, unnamed


def _outputs(args, paths) -> dict:
    """{input path: output path}; CLIError for a destination that would lose the input."""
    if bool(args.out_path) == bool(args.in_place):
        raise CLIError("--out: give where to write (a folder, or a file for a one-file program), or --in-place "
                       "(the original kept as FILE.orig); the program is never written over otherwise")
    if args.in_place:
        for p in paths:
            orig = Path(str(p) + ".orig")
            if orig.exists():
                raise CLIError(f"--in-place: {orig} exists (an earlier --in-place?): the original would be lost; move "
                               f"it away first")
        return {p: p for p in paths}
    out = Path(args.out_path)
    as_dir = out.is_dir() or len(paths) > 1 or args.out_path.endswith(("/", os.sep)) or not out.suffix
    if len(paths) > 1 and out.suffix and not out.is_dir():
        raise CLIError(f"--out {out}: the program has {len(paths)} files ({', '.join(p.name for p in paths)}): give a "
                       f"folder, where they keep their names")
    if as_dir:
        if out.exists() and not out.is_dir():
            raise CLIError(f"--out {out}: is a file; the program has {len(paths)} files: give a folder")
        result = {p: out / p.name for p in paths}
    else:
        result = {paths[0]: out}
    for src, dst in result.items():
        if dst.exists() and dst.resolve() == src.resolve():
            raise CLIError(f"--out {dst}: is the program itself; use --in-place to write over it (the original "
                           f"kept as .orig)")
    return result


def run(args):
    from ..core.programs.filtering import MARK, Setup, check_programs, dialect_for, filter_program
    from ..core.programs.text import to_bytes
    paths = [Path(p) for p in args.programs]
    for p in paths:
        if not p.is_file():
            raise CLIError(f"{p}: no such file")
    model = load_model(args)
    cal, envelope = enveloped_calibration(args, model)
    tools, default_tool = _named(args.tool, "--tool", True)
    frames, _ = _named(args.frame, "--frame", False)
    base = pose_option(args.base, "--base") if args.base else np.eye(4)
    flange = pose_option(args.flange, "--flange") if args.flange else np.eye(4)
    dialect = dialect_for(paths, args.format)
    program = dialect.read(paths)
    paths = list(program.texts)
    outputs = _outputs(args, paths)
    check_programs(program.texts)
    setup = Setup(model, cal.calibrated_chain(model), envelope, base, flange, tools, frames, default_tool,
                  args.fanuc_j3 == "absolute")
    sha = cal.content_sha256 or "unknown"
    command = "tolerance-ros " + shlex.join(str(a) for a in getattr(args, "argv", sys.argv[1:]))
    header = [f"{MARK} through calibration {Path(args.calibration).name}, sha256 {sha}, robot {model.name}:",
              f"command: {command}",
              "filter the original program, never this file again"]
    outcome = filter_program(program, setup, header)
    notes = []
    if any(r["kind"] == "pose" and r["status"] != "left" for r in outcome.rows) and not cal.targets.frames \
            and len(cal.targets) < 3:
        notes.append("the calibration measured one point on the tool, not its orientation: the flange's turns are "
                     "not identified, so a tool centre point away from that point lands off by its distance times "
                     "their error (measure three reflectors or a frame to see them)")
    for note in notes:
        if not args.quiet:
            print(f"filter: note: {note}", file=sys.stderr)
    for src, dst in outputs.items():
        dst.parent.mkdir(parents=True, exist_ok=True)
        if args.in_place:
            shutil.copy2(src, str(src) + ".orig")
        tmp = dst.with_name(dst.name + ".tmp")
        tmp.write_bytes(to_bytes(outcome.texts[src]))
        os.replace(tmp, dst)
    rows = outcome.rows
    counts = {s: sum(r["status"] == s for r in rows) for s in ("corrected", "unchanged", "left")}
    if outcome.left:
        missed(args, f"{len(outcome.left)} target(s) left as written: " + "; ".join(
            f"{t.name} ({t.where}): {why}" for t, why in outcome.left[:5]) + (" ..." if len(outcome.left) > 5 else ""))
    if outcome.unresolved:
        missed(args, f"{len(outcome.unresolved)} motion(s) not corrected: " + "; ".join(
            f"{u.what} ({u.path}:{u.line}): {u.why}" for u in outcome.unresolved[:5])
            + (" ..." if len(outcome.unresolved) > 5 else ""))
    if args.json:
        return {"robot": model.name, "calibration": str(args.calibration), "calibration_sha256": sha,
                "format": program.dialect, "written": {str(k): str(v) for k, v in outputs.items()},
                "counts": counts, "targets": rows, "notes": notes,
                "left": [{"name": t.name, "file": str(t.path), "line": t.line, "reason": why}
                         for t, why in outcome.left],
                "unresolved": [{"file": str(u.path), "line": u.line, "motion": u.what, "reason": u.why}
                               for u in outcome.unresolved]}
    print(f"robot {model.name}, calibration {args.calibration} (sha256 {sha[:12]}...), {program.dialect}: "
          f"{len(rows)} targets in {len(paths)} file(s): {counts['corrected']} corrected, {counts['unchanged']} "
          f"unchanged (a correction below the digits written), {counts['left']} left as written")
    rev = [t != "prismatic" for t in model.joint_types]

    def corr(r):
        if r["status"] == "left":
            return ""
        c = np.asarray(r["correction"])
        j = int(np.argmax(np.abs(c)))
        return f"{c[j] * (180e3 / np.pi if rev[j] else 1e6):+.1f} {'mdeg' if rev[j] else 'um'} j{j + 1}"

    print(table(["target", "where", "kind", "largest joint change", "target moved mm", "status"],
                [[r["name"], f"{Path(r['file']).name}:{r['line']}", r["kind"], corr(r),
                  f"{r['shift_m'] * 1e3:.3f}" if r["status"] != "left" and r["kind"] == "pose" else "",
                  r["status"] if r["status"] != "left" else f"left: {r['reason']}"] for r in rows]))
    for u in outcome.unresolved:
        print(f"not corrected: {Path(u.path).name}:{u.line} {u.what}: {u.why}")
    for src, dst in outputs.items():
        print(f"wrote {dst}" + (f" (original kept as {src}.orig)" if args.in_place else ""))
