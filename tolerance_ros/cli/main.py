"""The parser, assembled from the command modules, and the entry point: exit codes, one-line errors,
the JSON document of ``--json``."""
from __future__ import annotations

import argparse
import os
import re
import sys
import warnings

from ..core.jsonio import dumps
from ..core.resources import ConfigNotFound
from ..core.synthesis.problem import InfeasibleError
from ..core.threads import limited
from . import (allocate, calibrate, compensate, data, filter, import_table, iso9283, jacobian, keystore, paper,
               path_report, plan_campaign, report, robots, sensitivity, signing_key, simulate, ur_kinematics, validate,
               verify)
from .common import (CAPS, CHECKED_BY_COMMAND, EXIT_INPUT, EXIT_INTERNAL, EXIT_OK, EXIT_TARGET_MISSED, CLIError,
                     Parser, UsageError, check_cap, check_outputs, common_arguments, os_error_message,
                     output_kinds)

COMMANDS = (robots, jacobian, sensitivity, verify, allocate, report, path_report, iso9283, calibrate, validate,
            compensate, filter, ur_kinematics, plan_campaign, simulate, import_table, data, paper, keystore, signing_key)


def build_parser() -> argparse.ArgumentParser:
    """The ``tolerance-ros`` parser: one subcommand per module of ``COMMANDS`` (its NAME, HELP, ROBOT,
    ``add_arguments`` and ``run``)."""
    from . import __doc__ as doc
    from .. import __version__
    parser = Parser(prog="tolerance-ros", description=doc.split("\n\n")[0])
    parser.add_argument("--version", action="version", version=f"tolerance-ros {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for command in COMMANDS:
        p = common_arguments(sub.add_parser(command.NAME, help=command.HELP), robot=command.ROBOT)
        command.add_arguments(p)
        p.set_defaults(func=command.run, outputs=output_kinds(p))
    return parser


_NEGATIVE = re.compile(r"^-(\d|\.\d)")


def _attach_negative_values(argv, parser):
    """``--limit -1.4mm`` -> ``--limit=-1.4mm``, so that a negative value reaches the option's own check
    instead of being taken for an option."""
    takes_value = set()
    parsers = [parser] + [p for a in parser._actions if isinstance(a, argparse._SubParsersAction)
                          for p in a.choices.values()]
    for p in parsers:
        for a in p._actions:
            if a.option_strings and a.nargs is None:
                takes_value.update(a.option_strings)
    out, i = [], 0
    while i < len(argv):
        if argv[i] in takes_value and i + 1 < len(argv) and _NEGATIVE.match(argv[i + 1]):
            out.append(f"{argv[i]}={argv[i + 1]}")
            i += 2
        else:
            out.append(argv[i])
            i += 1
    return out


def error_code(exc) -> str:
    """The stable code of an error, as the services use them (not a Python class name)."""
    if isinstance(exc, ConfigNotFound) and exc.kind == "robots":
        return "unknown_robot"
    if isinstance(exc, InfeasibleError):
        return "infeasible"
    if isinstance(exc, (CLIError, ValueError, OSError, NotImplementedError)):
        return "invalid_request"
    return "internal"


def _message(exc) -> str:
    if isinstance(exc, OSError) and exc.strerror:
        return os_error_message(exc)
    return str(exc.args[0]) if isinstance(exc, KeyError) and exc.args else str(exc)


def _fail(prog, code, message, as_json) -> int:
    if as_json:
        print(dumps({"ok": False, "error": {"code": code, "message": message}}))
    print(f"{prog}: error: {message}", file=sys.stderr)
    return EXIT_INTERNAL if code == "internal" else EXIT_INPUT


CHAIN_ONLY = ("calibrate", "compensate", "filter", "ur-kinematics", "jacobian", "simulate", "plan-campaign")
"""Commands whose work is the chain's kinematics, with no worst case of a budget to bound."""


def kernel_needs(argv) -> tuple:
    """(families the command waits for, families next) of ``kernels.FAMILIES`` for a cold start, read from the
    command line without loading its robot. The chain's family (a URDF chain, the 3-PUPS platform or a D-H
    chain) for the commands of ``CHAIN_ONLY`` and under a ``--criterion`` without the worst case; otherwise
    the exact worst case (2 s to compile, and its numpy path is 6x the kernel), the chain next at the lowest
    priority (5 s to compile, and its numpy path costs an allocation under 1 s: compiled at once, it only
    takes the CPU from the job on a loaded machine). A paper's reproduction waits for both: the worst case
    first for a serial chain (it compiles in 0.8 s against the chain's 1.9 s, and in the first seconds of
    ``paper gao2023`` its numpy path costs more than the chain's: ``bench/bench_first_run_replay.py``
    estimates the first run at 1.09-1.15x the second, against 1.16-1.21x chain first), the 3-PUPS platform
    first for ``paper rong2018`` (on numpy it costs +26 s on 10 s)."""
    argv = list(argv)
    command = next((a for a in argv if not a.startswith("-")), "")

    def value(option):
        found = next((argv[i + 1] for i, a in enumerate(argv[:-1]) if a == option), "")
        return found or next((a.split("=", 1)[1] for a in argv if a.startswith(option + "=")), "")
    robot, criterion = value("--robot"), value("--criterion")
    text = robot.lower()
    if "rong2018" in argv or "pups" in text:
        chain = "pups"
    elif text.endswith((".urdf", ".xml")):
        chain = "urdf"
    else:
        chain = "dh"
        if text.endswith((".yaml", ".yml")):
            try:
                with open(robot, encoding="utf-8") as f:
                    if re.search(r"^kind:\s*urdf\b", f.read(20000), re.M):
                        chain = "urdf"
            except OSError:
                pass
    if command in CHAIN_ONLY or criterion in ("paper", "rss"):
        return (chain,), ()
    if command == "paper":
        return ((chain, "zonotope") if chain == "pups" else ("zonotope", chain)), ()
    return ("zonotope",), (chain,)


def entry() -> int:
    """The ``tolerance-ros`` process: ``main`` on the command line's arguments; on a cold kernel cache the
    kernels compile in a background child (said on stderr) while this call answers from the numpy path, the
    families the command needs first, each put in force as soon as it is ready. Where another process's
    child compiles them already, this call starts none (``warmup``: one compiler per cache) and says so; it
    says nothing where the families it needs are in the cache."""
    from ..core.models import warmup
    needs, then = kernel_needs(sys.argv[1:])
    if not warmup.cached() and warmup.start(background=True, needs=needs, then=then, nice=False) == "compiling":
        who = ("compiling the kernels in the background (the first run after an install)"
               if warmup.status["compiler"] == "this process" else
               "the kernels are being compiled by an earlier command (the first runs after an install)")
        print(f"tolerance-ros: {who}; this call answers from the numpy path meanwhile and switches to them as "
              "they are ready", file=sys.stderr)
    return main()


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    as_json = "--json" in argv
    parser = build_parser()
    try:
        args = parser.parse_args(_attach_negative_values(argv, parser))
        for name in ("samples", "poses", "random", "mc_poses", "ga_tol", "ga_rounds", "n"):
            if isinstance(getattr(args, name, None), int) and getattr(args, name) < 1:
                raise UsageError(f"--{name.replace('_', '-')}: must be >= 1")
        if isinstance(getattr(args, "seed", None), int) and not 0 <= args.seed < 2 ** 63:
            raise UsageError(f"--seed: must be a whole number from 0 to 2**63 - 1, got {args.seed}")
    except UsageError as exc:
        return _fail(parser.prog, "invalid_request", str(exc), as_json)
    prog = f"{parser.prog} {args.command}"
    args.missed = []
    args.argv = argv
    said = []
    try:
        own = getattr(sys.modules.get(args.func.__module__), "OWN_CAPS", ())  # the caps the command checks itself
        for name in CAPS:  # a count above its cap is refused before any work
            if name not in CHECKED_BY_COMMAND and name not in own and isinstance(getattr(args, name, None), int):
                check_cap(getattr(args, name), name)
        check_outputs(args)
        with limited(1), warnings.catch_warnings(record=True) as said:
            out = args.func(args)
        for w in said:   # said once the command has answered: a refusal is one line, not numpy's warnings first
            warnings.showwarning(w.message, w.category, w.filename, w.lineno)
        if as_json and out is not None:
            doc = {"ok": not args.missed, **out} if isinstance(out, dict) else out
            if args.missed and isinstance(doc, dict):
                doc["failed"] = list(args.missed)
            print(dumps(doc, indent=1))
    except BrokenPipeError:  # the reader (e.g. `| head`) went away: not an error of ours
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_OK
    except Exception as exc:  # every error is one line (and a JSON document with --json)
        code = error_code(exc)
        if code == "internal":   # a bug: what numpy said on the way may tell where
            for w in said:
                warnings.showwarning(w.message, w.category, w.filename, w.lineno)
        message = _message(exc) if code != "internal" else f"internal error (a bug): {type(exc).__name__}: {exc}"
        return _fail(prog, code, message, as_json)
    for what in args.missed:
        print(f"{prog}: FAILED: {what}", file=sys.stderr)
    return EXIT_TARGET_MISSED if args.missed else EXIT_OK
