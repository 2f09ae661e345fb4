"""The robot of a launched suite from launch arguments: ``robot`` (a shipped name, a robot YAML or a URDF path),
``tip_link`` and ``base_link`` (its chain: the tool link the tracker's target is on), and with them ``budget``
and ``campaign``, turned into each node's parameter overrides, laid over the parameters file. One plain
function (no ROS import) that the launch files call at launch time, so that an integrator's own robot is one
argument (``robot:=/path/my_robot.urdf tip_link:=tool0``) instead of seven places of a parameters file.

Where the robot is another than the parameters file's (``SUITE_ROBOT``), what belongs to that robot's
configuration is not carried over to it: the monitor's budget and campaign are left empty (a budget arrives on
``tolerance_budget``), the simulated tracker builds the robot within ``ANY_ROBOT_BUDGET``, and the joint-state
source draws random configurations; a ``budget`` or ``campaign`` given replaces them.
"""
from __future__ import annotations

SUITE_ROBOT = "gao2023_7dof"                 # the robot of config/accuracy_suite.yaml
ANY_ROBOT_BUDGET = "uniform:0.1mm,0.5mrad"   # a budget that fits any robot: the simulated as-built errors
ONE_ROBOT = ("tolerance_joint_state_source", "tolerance_accuracy_monitor", "tolerance_simulated_tracker",
             "tolerance_trajectory_compensator")
SERVING = ("tolerance_error_model", "tolerance_allocator")
LAUNCH_ARGUMENTS = {
    "robot": "the robot: a shipped name, a robot YAML or a URDF path, or robot_description (empty: the "
             "parameters file's)",
    "tip_link": "URDF robots: the link the chain ends in, where the tracker's target is (empty: the only moving "
                "leaf)",
    "base_link": "URDF robots: the link the chain starts from (empty: the URDF's root)",
    "budget": "tolerance budget of the monitor and of the simulated as-built robot (empty: the parameters file's "
              "for its robot; for another robot, none for the monitor and " + ANY_ROBOT_BUDGET + " simulated)",
    "campaign": "campaign the joint-state source plays and the monitor judges (empty: the parameters file's for "
                "its robot; for another robot, random configurations)",
}


def robot_overrides(robot: str = "", tip_link: str = "", base_link: str = "", budget: str = "",
                    campaign: str = "", check: bool = False, suite_campaign: str = "") -> dict:
    """{node name: {parameter: value}} of the launch arguments (see the module docstring); empty arguments
    override nothing. ``check``: load the robot first (ValueError naming the argument when it cannot be: a
    missing file, an unknown link), so that a launch fails once, before any node starts. ``suite_campaign``:
    the campaign a launch file plays on the parameters file's robot when none is given."""
    robot, tip_link, base_link = (str(v or "").strip() for v in (robot, tip_link, base_link))
    budget, campaign = str(budget or "").strip(), str(campaign or "").strip()
    if not campaign and robot in ("", SUITE_ROBOT):
        campaign = suite_campaign
    if check and robot and robot != "robot_description":
        _check(robot, tip_link, base_link)
    chain = {k: v for k, v in (("tip_link", tip_link), ("base_link", base_link)) if v}
    out = {name: dict(chain) for name in ONE_ROBOT + SERVING}
    if robot:
        for name in ONE_ROBOT:
            out[name]["robot"] = robot
        for name in SERVING:
            out[name].update(robots=[robot], default_robot=robot)
    other = bool(robot) and robot != SUITE_ROBOT
    if budget or other:
        out["tolerance_accuracy_monitor"]["budget"] = budget
        out["tolerance_simulated_tracker"]["budget"] = budget or ANY_ROBOT_BUDGET
    if campaign or other:
        out["tolerance_accuracy_monitor"]["campaign"] = campaign
        out["tolerance_joint_state_source"].update(mode="campaign" if campaign else "random", campaign=campaign)
    return {name: params for name, params in out.items() if params}


def _check(robot, tip_link, base_link):
    from ..core.models import load_robot
    from ..core.models.base import ModelError
    from ..core.resources import ConfigNotFound
    try:
        load_robot(robot, tip_link or None, base_link or None)
    except (ModelError, ConfigNotFound, OSError) as exc:
        raise ValueError(f"robot:={robot}" + (f" tip_link:={tip_link}" if tip_link else "")
                         + (f" base_link:={base_link}" if base_link else "") + f": {exc}") from None
