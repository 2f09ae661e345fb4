"""The README's commands: the two main commands, CI's test command, and every documented command line."""
import re
import shlex
from pathlib import Path

import pytest

from tolerance_ros.cli import build_parser

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()
BLOCKS = re.findall(r"```bash\n(.*?)\n```", README, re.S)


def test_ci_runs_the_readme_test_command():
    ci = (ROOT / ".ci" / "run").read_text()
    test_cmd = next(b for b in BLOCKS if "pytest" in b and "\n" not in b.strip())
    assert test_cmd.strip() in ci


def test_the_two_commands_come_first_main_job_then_tests():
    main_job, tests = BLOCKS[0].strip(), BLOCKS[1].strip()
    assert main_job.endswith("tolerance-ros paper gao2023") and "pip install" in main_job
    assert tests.endswith("python -m pytest") and 'pip install -q ".[test]"' in tests


def _documented_command_lines():
    lines = []
    for block in BLOCKS:
        for cmd in block.replace("\\\n", " ").splitlines():
            cmd = cmd.split(" #")[0].strip()
            m = re.search(r"(?:^|&& )(?:\.venv/bin/)?tolerance-ros (.*)$", cmd)
            if m:
                lines.append(re.sub(r"\s*\[[^\]]*\]", "", m.group(1)).strip())
    return lines


@pytest.mark.parametrize("argv", _documented_command_lines())
def test_every_documented_command_line_parses(argv):
    args = build_parser().parse_args(shlex.split(argv))
    assert callable(args.func)


def test_the_documented_commands_cover_every_subcommand():
    documented = {shlex.split(a)[0] for a in _documented_command_lines()}
    sub = next(a for a in build_parser()._actions if a.dest == "command")
    assert documented == set(sub.choices)
