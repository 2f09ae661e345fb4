"""``tolerance-ros``: the accuracy jobs from the command line, without ROS.

Every subcommand takes a robot (a shipped name such as ``gao2023_7dof``, or a YAML/URDF path), prints
a readable table (lengths in mm where the header says so), and with ``--json`` prints one JSON
document on stdout in SI units instead. Progress goes to stderr. Every length or angle option carries
its unit (``1.4mm``, ``0.3mrad``); a bare number is an error.

Exit codes: 0 done; 2 bad input (one line on stderr naming the option, file or field); 3 done, but
the target was not met (an allocation that misses its limit, a verification or a report with
errors over the limit; the last line on stderr says what failed); 1 an internal error (a bug).

One module per command (``robots``, ``jacobian``, ..., ``plan_campaign``, ``paper``: its NAME, HELP,
``add_arguments`` and ``run``); ``main`` assembles the parser from them, ``common`` holds what they share.
"""
from ..core.threads import cap_environment

cap_environment()  # before numpy loads: BLAS pools of one thread (see core/threads.py)

from .main import build_parser, entry, main  # noqa: E402

__all__ = ["build_parser", "entry", "main"]
