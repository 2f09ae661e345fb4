"""Campaign files."""
import numpy as np
import pytest
import yaml

from tolerance_ros.core.campaign import CampaignError, campaign_from_dict, load_campaign

GOOD = {"name": "c", "robot": "gao2023_7dof", "units": {"angle": "deg"}, "cycles": 3, "dwell": 0.5,
        "poses": [{"name": "P1", "joints": [0, 10, 20, 30, 40, 50, 60]},
                  {"name": "P2", "joints": [0, -10, 20, -30, 40, -50, 60]}]}


def test_joints_in_degrees_and_sequence(gao, tmp_path):
    p = tmp_path / "c.yaml"
    p.write_text(yaml.safe_dump(GOOD))
    c = load_campaign(p, gao)
    assert c.joints_for(gao)[0, 1] == pytest.approx(np.deg2rad(10))
    assert c.sequence()[:3] == [(0, 0), (1, 0), (0, 1)] and len(c.sequence()) == 6
    c.order = "pose"
    assert c.sequence()[:3] == [(0, 0), (0, 1), (0, 2)]


@pytest.mark.parametrize("edit, message", [
    ({"cycles": 0}, "cycles"),
    ({"dwell": -1}, "dwell"),
    ({"order": "random"}, "order"),
    ({"poses": []}, "poses"),
    ({"poses": [{"name": "P1", "joints": [0] * 7}, {"name": "P1", "joints": [0] * 7}]}, "duplicate"),
    ({"poses": [{"name": "P1"}]}, "exactly one of"),
    ({"poses": [{"name": "P1", "joints": [0] * 6}]}, "poses[0].joints"),
    ({"units": {"angle": "grad"}}, "units.angle"),
    ({"extra": 1}, "unknown key"),
])
def test_bad_campaigns(edit, message):
    with pytest.raises(CampaignError, match=message.replace("[", r"\[").replace("]", r"\]")):
        campaign_from_dict({**GOOD, **edit}, dof=7)


def test_pose_without_ik_is_an_error(gao):
    c = campaign_from_dict({**GOOD, "poses": [{"name": "P1", "pose": {"xyz": [0, 0, 1], "rpy": [0, 0, 0]}}]})
    with pytest.raises(CampaignError, match="no inverse kinematics"):
        c.joints_for(gao)
