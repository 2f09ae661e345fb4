"""The launch arguments that choose a suite's robot, turned into each node's parameters (issue 49), without ROS:
merged over config/accuracy_suite.yaml as the launch files merge them."""
from pathlib import Path

import pytest
import yaml

from tolerance_ros.services.launch_robot import ANY_ROBOT_BUDGET, ONE_ROBOT, SERVING, robot_overrides

ROOT = Path(__file__).resolve().parents[2]
FANUC = ROOT / "test" / "data" / "fanuc_r2000ic" / "fanuc_r2000ic_165f.urdf"


def effective(overrides) -> dict:
    """{node name: parameters} of config/accuracy_suite.yaml with the overrides laid over, as ROS merges a
    parameters file and a dict given after it."""
    doc = yaml.safe_load((ROOT / "config" / "accuracy_suite.yaml").read_text())
    out = {key.removeprefix("/**/"): dict(v["ros__parameters"]) for key, v in doc.items()}
    for name, params in overrides.items():
        out.setdefault(name, {}).update(params)
    return out


def test_no_argument_changes_nothing():
    assert robot_overrides() == {} and robot_overrides("", "", "", "", "") == {}


def test_an_integrators_urdf_and_tool_link_reach_every_node_and_nothing_of_the_files_robot_is_left():
    over = robot_overrides(str(FANUC), "flange", check=True)
    params = effective(over)
    for name in ONE_ROBOT:
        assert over[name]["robot"] == str(FANUC) and over[name]["tip_link"] == "flange"
    for name in SERVING:
        assert params[name]["robots"] == [str(FANUC)] and params[name]["default_robot"] == str(FANUC)
        assert params[name]["tip_link"] == "flange"
    left = [(n, k) for n, p in params.items() for k, v in p.items() if "gao2023" in str(v)]
    assert left == []                                  # the seven places of the file, and its budget and campaign
    assert params["tolerance_simulated_tracker"]["budget"] == ANY_ROBOT_BUDGET
    assert params["tolerance_accuracy_monitor"]["budget"] == "" == params["tolerance_accuracy_monitor"]["campaign"]
    assert params["tolerance_joint_state_source"]["mode"] == "random"


def test_a_budget_and_a_campaign_given_are_used_and_the_suite_robot_keeps_its_own():
    over = robot_overrides(str(FANUC), budget="my_budget.yaml", campaign="my_campaign.yaml")
    assert over["tolerance_accuracy_monitor"]["budget"] == "my_budget.yaml" == \
        over["tolerance_simulated_tracker"]["budget"]
    assert over["tolerance_joint_state_source"] == {"robot": str(FANUC), "mode": "campaign",
                                                    "campaign": "my_campaign.yaml"}
    assert "budget" not in robot_overrides("gao2023_7dof").get("tolerance_accuracy_monitor", {})
    loop = robot_overrides("", suite_campaign="gao2023_calibration_30")
    assert loop["tolerance_joint_state_source"] == {"mode": "campaign", "campaign": "gao2023_calibration_30"}
    assert robot_overrides(str(FANUC), suite_campaign="gao2023_calibration_30")[
        "tolerance_joint_state_source"]["mode"] == "random"
    only_tip = robot_overrides(tip_link="tool0")            # the file's robot (robot_description), its tool link
    assert all(p == {"tip_link": "tool0"} for p in only_tip.values()) and set(only_tip) == set(ONE_ROBOT + SERVING)


@pytest.mark.parametrize("args, message", [
    ({"robot": "/nowhere/arm.urdf"}, r"robot:=/nowhere/arm.urdf: .*no such file"),
    ({"robot": str(FANUC), "tip_link": "tool_0"}, r"tip_link:=tool_0: .*no link or frame named 'tool_0'"),
    ({"robot": "gao2023_7dof", "tip_link": "tool0"}, r"only for URDF robots"),
])
def test_a_robot_that_cannot_be_loaded_stops_the_launch_with_one_message(args, message):
    with pytest.raises(ValueError, match=message):
        robot_overrides(**args, check=True)


def test_the_nodes_take_the_tool_link_of_a_urdf_file_too():
    from tolerance_ros.core.models.base import ModelError
    from tolerance_ros.services.robots import RobotSet
    robots = RobotSet([str(FANUC)], str(FANUC), tip_link="link6")
    assert robots.single().tip_link == "link6" and robots.single().dof == 6
    assert RobotSet([str(FANUC), "gao2023_7dof"], "gao2023_7dof", tip_link="link5").models[
        "fanuc_r2000ic_165f"].dof == 5
    with pytest.raises(ModelError, match="only for URDF robots"):
        RobotSet(["gao2023_7dof"], "gao2023_7dof", tip_link="tool0")
