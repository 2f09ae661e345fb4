"""The README's test command is the one CI runs."""
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_ci_runs_the_readme_test_command():
    readme = (ROOT / "README.md").read_text()
    ci = (ROOT / ".ci" / "run").read_text()
    blocks = re.findall(r"```bash\n(.*?)\n```", readme, re.S)
    test_cmd = next(b for b in blocks if "pytest" in b and "\n" not in b.strip())
    assert test_cmd.strip() in ci


def test_readme_main_job_uses_the_paper_command():
    readme = (ROOT / "README.md").read_text()
    assert "tolerance-ros paper gao2023" in readme
