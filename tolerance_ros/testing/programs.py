"""The example programs of ``test/data/programs`` with the robots and command-line options they are written for, and
as-built robots in the calibration format: shared by the program filter's tests and ``bench/bench_filter.py``."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..core.accuracy.simulate import as_built_errors
from ..core.calibration.result import Calibration, nominal_fingerprint
from ..core.models import Mechanism, load_robot
from .example_robots import example_urdf

ROOT = Path(__file__).resolve().parents[2]
PROGRAMS = ROOT / "test" / "data" / "programs"
FANUC_URDF = ROOT / "test" / "data" / "fanuc_r2000ic" / "fanuc_r2000ic_165f.urdf"

# per example: its files, robot (--robot, --tip-link) and the options that tie its frames to the model (as typed on
# the command line, units included); the FANUC R-2000iC URDF stands for the ABB, KUKA and FANUC arms
EXAMPLES = {
    "rapid": {"files": ["pick_place.mod"], "robot": "fanuc", "options": []},
    "krl": {"files": ["weldcell.src"], "robot": "fanuc",
            "options": ["--tool", "1=200mm,0mm,0mm,0deg,90deg,0deg", "--frame", "2=1800mm,-400mm,300mm,0deg,0deg,30deg"]},
    "fanuc": {"files": ["pallet.ls"], "robot": "fanuc",
              "options": ["--base", "0mm,0mm,670mm,0deg,0deg,0deg", "--flange", "0mm,0mm,0mm,180deg,-90deg,0deg",
                          "--tool", "1=0mm,0mm,200mm,0deg,0deg,0deg",
                          "--frame", "1=1800mm,-400mm,-370mm,0deg,0deg,-15deg"]},
    "urscript": {"files": ["pick_place.script"], "robot": "ur5", "options": ["--base", "0m,0m,0m,0deg,0deg,180deg"]},
}


def robot_args(kind: str) -> list:
    """--robot (and --tip-link) of an example's robot."""
    if kind == "fanuc":
        return ["--robot", str(FANUC_URDF)]
    return ["--robot", str(example_urdf("ur5_robot.urdf")), "--tip-link", "tool0"]


def robot(kind: str) -> Mechanism:
    return load_robot(str(FANUC_URDF)) if kind == "fanuc" else load_robot(str(example_urdf("ur5_robot.urdf")), "tool0")


def as_built(model: Mechanism, length: float, angle: float, seed: int = 0, base=None) -> Calibration:
    """A calibration that is the truth of a robot as built: each length parameter within +-``length`` m and each
    angle within +-``angle`` rad of nominal (uniform, seeded), and a base correction [x y z m, rotation vector rad];
    zero errors for ``length`` = ``angle`` = 0."""
    delta = np.array([length if k == "length" else angle for k in model.param_kinds])
    dx = as_built_errors(delta, seed) if np.any(delta) else np.zeros(model.n_params)
    cal = Calibration(model.name, tuple(model.param_names), tuple(model.param_kinds), dx, np.zeros_like(dx),
                      np.zeros(6) if base is None else np.asarray(base, float), np.eye(4), None, [], [], {},
                      float("nan"), float("nan"), 0, 0, 0.0, float("nan"), float("nan"), 0, 0, 0, "base")
    cal.nominal = nominal_fingerprint(model)
    source = getattr(model, "source", None) or getattr(model, "config_path", None)
    cal.sources = {"robot": str(source) if source else model.name, "joint_names": list(model.joint_names)}
    if hasattr(model, "tip_link"):
        cal.sources.update(tip_link=model.tip_link, base_link=model.base_link)
    cal.model = {"parameters": "truth", "label": "a simulated as-built robot", "how": "drawn, not identified"}
    return cal


def example_setup(kind: str, model: Mechanism, calibration: Calibration, **kw):
    """The ``Setup`` of an example program (its options of ``EXAMPLES``) corrected through ``calibration``."""
    from ..cli.filter import _named, pose_option
    from ..core.programs.filtering import Setup
    opts = EXAMPLES[kind]["options"]
    given = {}
    for flag in ("--tool", "--frame", "--base", "--flange"):
        given[flag] = [opts[i + 1] for i, o in enumerate(opts) if o == flag]
    tools, default_tool = _named(given["--tool"], "--tool", True)
    frames, _ = _named(given["--frame"], "--frame", False)
    base = pose_option(given["--base"][0], "--base") if given["--base"] else np.eye(4)
    flange = pose_option(given["--flange"][0], "--flange") if given["--flange"] else np.eye(4)
    return Setup(model, calibration.calibrated_chain(model), base=base, flange=flange, tools=tools, frames=frames,
                 default_tool=default_tool, **kw)
