"""What every command of the command line shares: its errors, option values with units, the robot of
``--robot``, the target-missed record, and the arguments every command takes."""
from __future__ import annotations

import argparse
import os
import re
import sys
from pathlib import Path

from ..core.ingest import MAX_POSITION_M
from ..core.models import load_robot
from ..core.units import UnitError, parse_quantity

EXIT_OK, EXIT_INTERNAL, EXIT_INPUT, EXIT_TARGET_MISSED = 0, 1, 2, 3


class CLIError(Exception):
    """A user error reported as one line on stderr (and as a JSON error with --json)."""


class UsageError(CLIError):
    """An argument the parser cannot read (unknown option, missing value)."""


class Parser(argparse.ArgumentParser):
    """argparse, but a usage error becomes a UsageError (one line, or JSON with --json), not an exit; an
    option the command does not know is reported before a required one that is missing (``--limt``: did
    you mean ``--limit``?, not "--limit is required")."""

    def parse_known_args(self, args=None, namespace=None):
        self._args = list(args) if args is not None else []
        return super().parse_known_args(args, namespace)

    def error(self, message):
        if message.startswith("the following arguments are required"):
            unknown = self._unknown_options()
            if unknown:
                message = "unrecognized arguments: " + " ".join(unknown)
        raise UsageError(f"{message} (see '{self.prog} --help')")

    def _unknown_options(self) -> list:
        """The options of the arguments being parsed that are neither this parser's nor an abbreviation of
        one, each with the closest known option."""
        import difflib
        known = [o for o in self._option_string_actions if o.startswith("--")]
        out = []
        for arg in getattr(self, "_args", []):
            name = arg.split("=", 1)[0]
            if not name.startswith("--") or name == "--" or name in known or \
                    (self.allow_abbrev and any(o.startswith(name) for o in known)):
                continue
            close = difflib.get_close_matches(name, known, n=1)
            out.append(f"{name} (did you mean {close[0]}?)" if close else name)
        return out


# The largest value of each count option (its argparse dest): what it counts and why it is bounded. Above the
# cap a command refuses up front, in one line naming the option, instead of filling the memory or running
# for hours; each command's own work is done in chunks with progress.
CAPS = {
    "random": (10_000, "configurations", "each pose's pose and Jacobian are printed"),
    "n": (1_000, "test poses", "each exchange of the pose selection scores every candidate"),
    "candidates": (20_000, "candidate poses", "the information matrices of the candidates are held in memory"),
    "samples": (500_000, "samples", "the errors of every sample are held in memory"),
    "poses": (100_000, "poses", "the Jacobians of the poses are held in memory"),
    "mc_poses": (200_000, "Monte Carlo poses", "the errors of every pose are held in memory"),
    "ga_tol": (100_000, "solves per round", "each solve is a full allocation"),
    "ga_rounds": (10_000, "rounds", "each round runs up to --ga-tol solves"),
    "folds": (1_000, "folds", "each fold is a calibration"),
}
CHECKED_BY_COMMAND = ("random",)  # checked by the command itself, which knows the size each one needs
# sensitivity holds (samples, 6, p) Jacobians and their statistics: a smaller cap than verify's chunked samples
SENSITIVITY_SAMPLES = 50_000


def check_cap(value, dest: str, cap: int | None = None, need: str = ""):
    """CLIError (one line naming the option) when a count option exceeds its cap in ``CAPS`` (or ``cap``);
    ``need`` says what the run would need (e.g. its memory)."""
    limit, what, why = CAPS[dest]
    limit = limit if cap is None else cap
    if value is not None and value > limit:
        raise CLIError(f"--{dest.replace('_', '-')}: {value} {what} exceed the cap of {limit} ({why}"
                       f"{'; ' + need if need else ''}); ask for at most {limit}")


def gigabytes(n_bytes: float) -> str:
    """A size for messages: '1.2 GB', '340 MB'."""
    return f"{n_bytes / 1e9:.1f} GB" if n_bytes >= 1e9 else f"{n_bytes / 1e6:.0f} MB"


def quantity(text, kind, option, positive=True):
    """SI value of an option written with its unit (``1.4mm``); None stays None; CLIError otherwise."""
    if text is None:
        return None
    try:
        value = parse_quantity(text, kind, field=option)
    except UnitError as exc:
        raise CLIError(str(exc)) from None
    if positive and not value > 0:
        raise CLIError(f"{option}: must be > 0, got {text!r}")
    return value


def limit_option(model, text, kind, option):
    """SI design limit of an option written with its unit, or None for None; CLIError when it has no unit or
    cannot be meant for ``model`` (``budget.limits_problem``: beyond 5 % of its reach, or 0.1 rad)."""
    value = quantity(text, kind, option)
    if value is None:
        return None
    from ..core.budget import limits_problem
    problem = limits_problem(model, value if kind == "length" else None, value if kind == "angle" else None)
    if problem:
        raise CLIError(f"{option}: {problem}")
    return value


def joints_option(model, text, option):
    """(dof,) joints (rad or m) of an option ``Q1,Q2,...``, each value with its unit (``0deg``, ``0.1rad``, a
    prismatic joint's ``20mm``); CLIError naming the option otherwise."""
    parts = text.split(",")
    if len(parts) != model.dof:
        raise CLIError(f"{option}: expected {model.dof} values (one per joint of {model.name}: "
                       f"{', '.join(model.joint_names)}), got {len(parts)}")
    return [quantity(v, "length" if t == "prismatic" else "angle", option, positive=False)
            for v, t in zip(parts, model.joint_types)]


def point_option(text, option):
    """[x, y, z] m of ``X,Y,Z`` (a unit on each, e.g. ``0mm,0mm,120mm``), or None when it is not three values
    (the caller says what it expected); CLIError for a value without its unit."""
    parts = text.split(",")
    if len(parts) != 3:
        return None
    out = [quantity(c, "length", option, positive=False) for c in parts]
    far = next((c for c, v in zip(parts, out) if not abs(v) <= MAX_POSITION_M), None)
    if far is not None:
        raise CLIError(f"{option}: {far.strip()} lies beyond {MAX_POSITION_M:g} m: no point of a robot's cell")
    return out


def load_model(args):
    """The model of ``--robot`` (with ``--tip-link`` / ``--base-link``); says which tip it took when the
    choice was made for the user among other leaf links (a URDF whose only moving leaf link is the tip, beside
    links fixed to the base); says nothing where the tip is the URDF's only leaf."""
    sensor = getattr(args, "sensor_link", None)
    if sensor:
        model = sensor_chain(args, sensor)
    else:
        model = load_robot(args.robot, getattr(args, "tip_link", None), getattr(args, "base_link", None))
    fixed = getattr(model, "fixed_leaves", [])
    if getattr(model, "tip_chosen", False) and fixed and not sensor and not args.quiet:
        shown = ", ".join(repr(n) for n in fixed[:5]) + (f" and {len(fixed) - 5} more" if len(fixed) > 5 else "")
        print(f"robot {model.name}: tip link {model.tip_link!r}, the only leaf link the joints move (besides "
              f"{shown}, which no joint moves; choose another with --tip-link)", file=sys.stderr)
    return model


OUTPUT_OPTIONS = ("out", "plot")
"""Options that name what a command writes: a folder where their metavar is DIR, else a file."""


def output_kinds(p) -> dict:
    """{dest: 'dir' | 'file'} of a command parser's output options (``OUTPUT_OPTIONS``)."""
    return {a.dest: "dir" if a.metavar == "DIR" else "file" for a in p._actions if a.dest in OUTPUT_OPTIONS}


def check_outputs(args):
    """Refuse, before any work, an output option that cannot be written: a folder that is a file, a file
    that is a folder, a path through a file, a folder without write permission."""
    for dest, kind in getattr(args, "outputs", {}).items():
        value = getattr(args, dest, None)
        if not value or value == "-":
            continue
        path, option = Path(value), f"--{dest}"
        if kind == "dir" and path.exists() and not path.is_dir():
            raise CLIError(f"{option} {value}: is a file, not a folder; give a folder (it is created if missing)")
        if kind == "file" and path.is_dir():
            raise CLIError(f"{option} {value}: is a folder; give the name of the file to write")
        existing = path if kind == "dir" else path.parent
        while not existing.exists() and existing != existing.parent:
            existing = existing.parent
        if not existing.is_dir():
            raise CLIError(f"{option} {value}: {existing} is a file, so no folder can be made there")
        if not os.access(existing, os.W_OK | os.X_OK):
            raise CLIError(f"{option} {value}: cannot write into {existing} (permission denied)")


def envelope_options(p, moved: str):
    """``--max-joint-correction`` and ``--max-tool-correction``, the correction envelope of the nodes; ``moved``
    says what the tool option bounds."""
    p.add_argument("--max-joint-correction", default="20mrad",
                   help="the correction envelope, as the nodes': the largest change of a revolute joint the calibration "
                        "may make (default 20mrad)")
    p.add_argument("--max-tool-correction", default="5mm",
                   help=f"the largest {moved}, and change of a prismatic joint (default 5mm)")


def enveloped_calibration(args, model):
    """(Calibration, Envelope) of ``--calibration`` for ``model`` within ``--max-joint-correction`` and
    ``--max-tool-correction``; CLIError when its correction leaves that envelope (a calibration a node refuses)."""
    from ..core.calibration.calibration_file import load_calibration
    from ..core.calibration.envelope import Envelope
    cal = load_calibration(args.calibration, model)
    envelope = Envelope(quantity(args.max_joint_correction, "angle", "--max-joint-correction"),
                        quantity(args.max_tool_correction, "length", "--max-tool-correction"))
    check = envelope.check(cal, model)
    if not check["ok"]:
        raise CLIError(f"{args.calibration}: refused, its correction is outside the envelope: {check['reason']} "
                       f"(--max-joint-correction and --max-tool-correction widen it, for a calibration you trust)")
    return cal, envelope


def refuse_overwrite(out_dir, names, args, options):
    """CLIError when a file the command would write into ``out_dir`` (its ``names``) is one of its inputs (the
    values of ``options``, dests of ``args``; each a path or a list of them): nothing a user measured is written
    over."""
    if not out_dir:
        return
    written = {(Path(out_dir) / n).resolve(): n for n in names}
    for dest in options:
        values = getattr(args, dest, None)
        for v in (values if isinstance(values, list) else [values]):
            if v and Path(v).resolve() in written:
                raise CLIError(f"--out {out_dir}: would write {written[Path(v).resolve()]} over the input "
                               f"--{dest.replace('_', '-')} {v}; give another folder")


def os_error_message(exc: OSError) -> str:
    """An operating-system error in words, naming its file: ``out/x.yaml: no space left on device``."""
    what = (exc.strerror or str(exc)).lower()
    names = [str(f) for f in (exc.filename, exc.filename2) if f is not None]
    return f"{' -> '.join(names)}: {what}" if names else what


def missed(args, what: str):
    """Record that the run's target was not met (exit code 3; ``what`` is printed last on stderr)."""
    args.missed.append(what)


def relative(path, start) -> str:
    """``path`` relative to the directory ``start`` when it lies at most two levels up from it (files that
    move together), else absolute."""
    target = Path(path).resolve()
    try:
        rel = os.path.relpath(target, Path(start).resolve())
    except ValueError:  # another drive
        return str(target)
    return rel if Path(rel).parts[:3] != (os.pardir,) * 3 else str(target)


def sensor_chain(args, sensor):
    """The chain of ``--sensor-link``: from the sensor's link to the marker, which the tool holds (``--tip-link``, or
    the tool the URDF ends in) or, where the sensor is on the tool itself (the tip link or a link no joint moves
    against it), which is fixed in the cell (the chain then runs back to the URDF's root). Each error names the
    option whose link is wrong."""
    from ..core.models.base import ModelError
    if getattr(args, "base_link", None):
        raise CLIError("--sensor-link: the chain starts from the sensor's link; give it instead of --base-link")
    tip = getattr(args, "tip_link", None)
    try:
        model = load_robot(args.robot, tip, sensor)
    except ModelError as exc:
        text = str(exc)
        if "base_link: no link named" in text:
            raise CLIError(text.replace("base_link: no link named", "--sensor-link: no link named")) from None
        if "tip_link, base_link: only for" in text:
            raise CLIError(f"--sensor-link: needs a URDF robot ({text})") from None
        if "is not moved against base_link" not in text and "is not moved by any joint" not in text:
            raise
        model = None                     # no joint between the sensor and the tool: the sensor is on the tool
    on_tool = model is None or model.tip_link == sensor
    if on_tool:                          # a marker fixed in the cell, on the root
        tool = load_robot(args.robot, sensor)
        if tip is not None and tip != sensor and model is None and tip == tool.base_link:
            raise CLIError(f"--sensor-link {sensor}, --tip-link {tip}: no joint moves the one against the other")
        model = load_robot(args.robot, tool.base_link, sensor)
    if not args.quiet:
        where = " (fixed in the cell)" if on_tool or model.tip_link == model.root_link else " (held by the tool)"
        print(f"robot {model.name}: the sensor on {sensor!r} measures a marker on {model.tip_link!r}{where}: "
              f"{model.dof} joints between them", file=sys.stderr)
    return model


def common_arguments(p, robot=True):
    """The options every command takes (``--robot`` and its chain where it needs a robot)."""
    if robot:
        p.add_argument("--robot", required=True, help="shipped robot name or YAML/URDF path")
        p.add_argument("--tip-link", help="URDF robots: the link the chain ends in (the tool)")
        p.add_argument("--base-link", help="URDF robots: the link the chain starts from (default: the root; a link "
                                           "below joints runs them backwards, e.g. a foot's sole to a gripper)")
        p.add_argument("--sensor-link", metavar="LINK",
                       help="URDF robots: the measuring frame is on this robot link (a camera on the wrist or a head): "
                            "the chain runs from it to the marker, held by the tool (--tip-link), or fixed in the cell "
                            "when LINK is the tool itself; the sensor's placement on LINK is fitted as the registration")
    p.add_argument("--json", action="store_true", help="print one JSON document (SI units) on stdout")
    p.add_argument("--quiet", action="store_true", help="no progress on stderr")
    return p


def target_options(specs, model=None, option="--target") -> dict:
    """{name: (3,) m in the tool frame} of ``NAME=X,Y,Z`` (a unit on each) or ``NAME=link:LINK`` (a URDF link fixed to
    the tip link: its origin in the tool frame)."""
    out = {}
    for spec in specs or []:
        name, eq, value = spec.partition("=")
        name = name.strip()
        if not eq or not name:
            raise CLIError(f"{option}: expected NAME=X,Y,Z with a unit on each (e.g. A=0mm,0mm,120mm) or NAME=link:LINK, "
                           f"got {spec!r}")
        if name in out:
            raise CLIError(f"{option}: target {name!r} given twice")
        if value.strip().startswith("link:"):
            out[name] = link_offset(model, value.strip()[len("link:"):], option)
            continue
        point = point_option(value, option)
        if point is None:
            raise CLIError(f"{option}: expected NAME=X,Y,Z with a unit on each (e.g. {name}=0mm,0mm,120mm), got {spec!r}")
        out[name] = point
    return out


def link_offset(model, link, option="--target"):
    """(3,) m: the origin of URDF link ``link`` in the tool frame of ``model``; CLIError when the model is not a URDF
    chain, the link is unknown, or a joint moves it against the tip link."""
    import numpy as np
    pin_model = getattr(model, "pin_model", None)
    if pin_model is None:
        raise CLIError(f"{option}: link:{link} needs a URDF robot (robot {model.name!r} has no links)")
    if not pin_model.existFrame(link):
        raise CLIError(f"{option}: link {link!r} is not in the URDF of {model.name!r}")
    import pinocchio as pin
    data = pin_model.createData()
    tip, fid = pin_model.getFrameId(model.tip_link), pin_model.getFrameId(link)
    places = []
    for q in (pin.neutral(pin_model), pin.randomConfiguration(pin_model, -np.ones(pin_model.nq), np.ones(pin_model.nq))):
        pin.framesForwardKinematics(pin_model, data, q)
        places.append((data.oMf[tip].inverse() * data.oMf[fid]).translation.copy())
    if np.linalg.norm(places[0] - places[1]) > 1e-9:
        raise CLIError(f"{option}: link {link!r} moves against the tip link {model.tip_link!r} (a joint lies between "
                       f"them); a target is fixed to the tool")
    return places[0].tolist()


def contact_specs(specs, option="--contact"):
    """[(kind, id, where)] of ``--contact`` values: a plane's (unit normal, offset m), a point's (3,) m."""
    import numpy as np
    out = []
    for spec in specs:
        m = re.match(r"^(plane|point):([A-Za-z0-9_.\-]{1,100})=(.*)$", spec.strip())
        if not m:
            raise CLIError(f"{option}: expected plane:ID=NX,NY,NZ@OFFSET or point:ID=X,Y,Z, got {spec!r}")
        kind, cid, rest = m.groups()
        if kind == "point":
            where = point_option(rest, option)
            if where is None:
                raise CLIError(f"{option}: point:{cid}: expected X,Y,Z with a unit on each, got {rest!r}")
            out.append((kind, cid, np.array(where)))
            continue
        normal, at, offset = rest.partition("@")
        try:
            n = np.array([float(v) for v in normal.split(",")])
        except ValueError:
            n = np.zeros(0)
        if not at or n.shape != (3,) or not np.all(np.isfinite(n)) or np.linalg.norm(n) == 0:
            raise CLIError(f"{option}: plane:{cid}: expected NX,NY,NZ@OFFSET (a normal of three numbers, an offset "
                           f"with its unit, e.g. 0,0,1@300mm), got {rest!r}")
        d = quantity(offset, "length", option, positive=False)
        if not abs(d) <= MAX_POSITION_M:
            raise CLIError(f"{option}: plane:{cid}: offset {offset.strip()} lies beyond {MAX_POSITION_M:g} m: no plane "
                           f"of a robot's cell")
        out.append((kind, cid, (n / np.linalg.norm(n), d)))
    if len({(k, i) for k, i, _ in out}) != len(out):
        raise CLIError(f"{option}: each plane and point once")
    return out
