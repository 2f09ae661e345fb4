"""The README's commands: the two main commands, CI's test command, every documented command line (of the
README and of the pages in docs/ it links), and the walkthrough of its blocks that need no ROS, run as
written."""
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from helpers import SHARED_DATA
from tolerance_ros.cli import build_parser

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()
BLOCKS = re.findall(r"```bash\n(.*?)\n```", README, re.S)
DOC_BLOCKS = [b for page in sorted((ROOT / "docs").glob("*.md"))
              for b in re.findall(r"```bash\n(.*?)\n```", page.read_text(), re.S)]


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
    for block in BLOCKS + DOC_BLOCKS:
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


WALK_SKIP = ("ros2 ", "colcon ", "rosdep ", "source ", "python3 -m venv", "git clone")
"""A shell block with one of these needs ROS, a workspace or the network: not part of the walkthrough."""


def walkthrough_steps():
    """The README's runnable steps in its order: (kind, text, expected exit code). A bash block that needs
    no ROS, in which no line is a synopsis (``[--option]``), gives one step per command; a trailing
    ``# exits N`` says the command is documented to exit N. A Python block that needs no graph (does not
    import ``tolerance_ros.nodes``) is one step."""
    steps = []
    for m in re.finditer(r"```(bash|python)\n(.*?)\n```", README, re.S):
        kind, text = m.groups()
        if kind == "python":
            if "tolerance_ros.nodes" not in text:
                steps.append(("python", text, 0))
            continue
        commands = [c for c in text.replace("\\\n", " ").splitlines() if c.strip()]
        if any(c.lstrip().startswith(WALK_SKIP) or " [--" in c for c in commands):
            continue
        for c in commands:
            exits = re.search(r"#\s*exits (\d+)", c)
            steps.append(("bash", c, int(exits.group(1)) if exits else 0))
    return steps


def test_the_walkthrough_covers_the_first_hour():
    steps = walkthrough_steps()
    shell = [t for k, t, _ in steps if k == "bash"]
    assert shell[0] == ". .venv/bin/activate"  # before any bare tolerance-ros or python
    for word in ("robots", "jacobian", "sensitivity", "verify", "allocate", "plan-campaign", "simulate", "calibrate",
                 "compensate", "import", "validate"):
        assert any(t.startswith(f"tolerance-ros {word} ") or t == f"tolerance-ros {word}" for t in shell), word
    assert [k for k, _, _ in steps].count("python") == 2


TIAGO = SHARED_DATA / "tiago_mocap"


def offline(steps) -> list:
    """The walkthrough without the network: ``tolerance-ros data fetch`` takes the public set from the shared
    data folder (``--data``: its files' sha256 checked as a download's are), or, where that folder is absent,
    the steps that use the set are left out."""
    out = []
    for kind, text, code in steps:
        uses = "tiago" in text
        if uses and not TIAGO.is_dir():
            continue
        if kind == "bash" and text.startswith("tolerance-ros data fetch tiago_mocap"):
            text = f"{text} --data {shlex.quote(str(TIAGO))}"
        out.append((kind, text, code))
    return out


def test_the_walkthrough_fetches_the_real_data_and_runs_offline_with_the_shared_folder():
    steps = walkthrough_steps()
    fetch = [t for k, t, _ in steps if k == "bash" and t.startswith("tolerance-ros data fetch")]
    assert fetch == ["tolerance-ros data fetch tiago_mocap --out data"]
    assert not any("test/data/tiago" in t for _, t, _ in steps)        # no copy in the repository to read
    run = offline(steps)
    if TIAGO.is_dir():
        assert [t for k, t, _ in run if "data fetch" in t] == [f"{fetch[0]} --data {shlex.quote(str(TIAGO))}"]
    else:
        assert not any("tiago" in t for _, t, _ in run) and len(run) < len(steps)


@pytest.mark.skipif(not (Path(sys.prefix) / "bin" / "activate").is_file(), reason="not run from a venv")
def test_the_readme_walkthrough_runs_as_written_from_a_fresh_folder(tmp_path):
    """Every step of ``walkthrough_steps`` in one shell, in a folder with only the repository's bench/ and
    test/ and the venv: each exits as documented, and what it says it writes is there."""
    for name in ("bench", "test"):
        (tmp_path / name).symlink_to(ROOT / name)
    (tmp_path / ".venv").symlink_to(Path(sys.prefix))
    steps = offline(walkthrough_steps())
    script = ["set -u"]
    for i, (kind, text, _) in enumerate(steps):
        if kind == "python":
            (tmp_path / f"step{i}.py").write_text(text + "\n")
            text = f"python step{i}.py"
        script += [f"echo '>>> step {i}' >&2", text, f"echo {i} $? >> rc.txt"]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT)] + os.environ.get("PYTHONPATH", "").split(
        os.pathsep)).rstrip(os.pathsep), MPLBACKEND="Agg")
    proc = subprocess.run(["bash", "-c", "\n".join(script)], cwd=tmp_path, env=env, capture_output=True, text=True,
                          timeout=1500)
    codes = dict(line.split() for line in (tmp_path / "rc.txt").read_text().splitlines())
    for i, (kind, text, expected) in enumerate(steps):
        assert int(codes[str(i)]) == expected, f"step {i} ({text[:90]!r}) exited {codes[str(i)]}:\n{proc.stderr[-3000:]}"
    for f in ("out/budget.yaml", "out/salience.png", "out/planned.yaml", "out/measurements.csv",
              "out/measurements.truth.yaml", "out/report/report.md", "out/cal/calibration.yaml",
              "out/iso_compensated.yaml") + (("out/tiago/cal/calibration.yaml",) if TIAGO.is_dir() else ()):
        assert (tmp_path / f).is_file(), f
