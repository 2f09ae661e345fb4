"""Campaign files."""
import time

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


@pytest.mark.parametrize("units", [["deg"], "deg"])
def test_units_that_are_not_a_mapping_are_the_campaigns_error(tmp_path, units):
    p = tmp_path / "c.yaml"
    p.write_text(yaml.safe_dump({**GOOD, "units": units}))
    with pytest.raises(CampaignError, match=rf"^{p}: units: expected a mapping like \{{length: mm, angle: deg\}}"):
        load_campaign(p)


def test_a_joint_outside_its_limits_is_refused_in_the_files_units(gao, tmp_path):
    p = tmp_path / "c.yaml"
    far = {"name": "P2", "joints": [0, 720, 0, 0, 0, 0, 0]}
    p.write_text(yaml.safe_dump({**GOOD, "poses": [GOOD["poses"][0], far]}))
    with pytest.raises(CampaignError, match=rf"^{p}: poses\[1\].joints\[1\] \(joint2\) = 720 deg is outside the "
                                            rf"joint's limits \[-180, 180\] deg on robot 'gao2023_7dof'"):
        load_campaign(p, gao)
    c = load_campaign(p)  # without the robot, the joints cannot be checked; joints_for checks them
    with pytest.raises(CampaignError, match=r"poses\[1\].joints\[0\]\[1\] \(joint2\) = 12.5664 is outside"):
        c.joints_for(gao)


@pytest.mark.parametrize("text, message", [
    ("poses:\n  - {name: P1, joints: [0, 1_000, 0, 0, 0, 0, 0]}\n", r"line 2: '1_000' is a number with digit"),
    ("poses:\n  - {name: P1, joints: [0, 1:30, 0, 0, 0, 0, 0]}\n", r"line 2: '1:30' is a sexagesimal"),
    ("cycles: 3\npose_s: 1\ncycles: 4\n", r"line 3: key 'cycles' given twice"),
    ("poses:\n" + "  " + "[" * 5000 + "]" * 5000 + "\n", r"line 2: nested deeper than 32 levels"),
])
def test_yaml_that_would_change_or_hang_the_campaign_is_refused_with_the_line(tmp_path, text, message):
    p = tmp_path / "c.yaml"
    p.write_text(text)
    with pytest.raises(CampaignError, match=rf"^{p}, {message}"):
        load_campaign(p)


def test_a_campaign_of_20000_poses_loads_fast(gao, tmp_path):
    p = tmp_path / "big.yaml"
    p.write_text("units: {angle: deg}\nposes:\n" + "".join(
        f"  - {{name: P{i}, joints: [10, 20, 30, 40, 50, 60, {i % 90}]}}\n" for i in range(20_000)))
    t0 = time.perf_counter()
    c = load_campaign(p, gao)
    assert time.perf_counter() - t0 < 8.0  # 1 s on an idle core, 5 s at load average 5; PyYAML's Python loader: 12-18 s
    assert len(c.poses) == 20_000 and c.poses[-1].joints[-1] == pytest.approx(np.deg2rad(19_999 % 90))


def test_a_campaign_for_another_robot_says_so_before_its_poses(gao, tmp_path):
    """A 6-joint UR10 campaign given for the 7-joint gao2023 arm: the robot named, not a pose's length."""
    p = tmp_path / "ur10_campaign.yaml"
    p.write_text("robot: ur10\nunits: {angle: deg}\nposes:\n  - {name: P1, joints: [0, -90, 90, 0, 90, 0]}\n")
    with pytest.raises(CampaignError, match=r"this campaign is for robot 'ur10', not 'gao2023_7dof'$"):
        load_campaign(p, gao)


def test_a_campaign_is_checked_against_the_restrictions_it_was_planned_under(gao, tmp_path):
    q = gao.sample_joints(200, 3)
    z = gao.fk(q)[:, 2, 3]
    above, below = q[np.argmax(z)], q[np.argmin(z)]
    floor = f"{(z.max() + z.min()) / 2}m"
    data = {"robot": "gao2023_7dof", "units": {"angle": "deg"},
            "restrictions": {"above_plane": [f"0,0,1@{floor}"], "joint_range": []},
            "poses": [{"name": "C1", "joints": np.degrees(above).tolist()},
                      {"name": "C2", "joints": np.degrees(below).tolist()}]}
    p = tmp_path / "c.yaml"
    p.write_text(yaml.safe_dump(data))
    with pytest.raises(CampaignError, match=rf"1 of 2 poses break the restrictions the campaign was planned under "
                                            rf"\(above plane 0,0,1@{floor}; no collision geometry .*\): C2: tool below "
                                            rf"a plane \(0,0,1@{floor}\)$"):
        load_campaign(p, gao)
    assert load_campaign(p).meta["restrictions"]["above_plane"] == [f"0,0,1@{floor}"]  # without a robot: kept
    data["poses"].pop()
    p.write_text(yaml.safe_dump(data))
    assert load_campaign(p, gao).names == ["C1"]
    data["restrictions"]["above_plane"] = ["0,0,1@0.3"]
    p.write_text(yaml.safe_dump(data))
    with pytest.raises(CampaignError, match=r"restrictions.above_plane offset: '0.3' has no unit"):
        load_campaign(p, gao)
    data["restrictions"]["floor"] = "0m"
    p.write_text(yaml.safe_dump(data))
    with pytest.raises(CampaignError, match=r"restrictions: unknown key\(s\) \['floor'\]"):
        load_campaign(p, gao)


def test_a_campaign_of_a_trillion_cycles_or_a_dated_dwell_is_refused(gao, tmp_path):
    from tolerance_ros.core.campaign import CampaignError, load_campaign
    path = tmp_path / "c.yaml"
    for extra, message in (("cycles: 1000000000000", "at most 100000"), ("dwell: 2001-12-14", "is a date")):
        path.write_text(f"name: c\nrobot: gao2023_7dof\n{extra}\nposes:\n  - {{name: P1, joints: [0, 0, 0, 0, 0, 0, 0]}}\n")
        with pytest.raises(CampaignError, match=message):
            load_campaign(path, gao)


APPROACHED = [{"name": "P1+x", "joints": [0, 10, 20, 30, 40, 50, 60], "of": "P1", "approach": "+x",
               "via": [2, 11, 20, 30, 40, 50, 60]},
              {"name": "P1+y", "joints": [0, 10, 20, 30, 40, 50, 60], "of": "P1", "approach": "+y",
               "via": [0, 12, 18, 30, 40, 50, 60]}]


def test_approaches_of_a_test_pose_with_their_pre_poses(gao):
    c = campaign_from_dict({**GOOD, "poses": GOOD["poses"] + APPROACHED}, model=gao)
    assert c.approaches() == {"P1": ["P1+x", "P1+y"]}
    q, pose, cycle, via = c.steps(gao)             # each pre-pose driven just before its pose, every cycle
    assert pose.tolist() == [0, 1, 2, 2, 3, 3] * 3 and via.tolist() == [False, False, True, False, True, False] * 3
    assert cycle.tolist() == [0] * 6 + [1] * 6 + [2] * 6
    assert np.allclose(q[2], c.poses[2].via) and np.allclose(q[3], c.joints_for(gao)[2])
    assert c.poses[2].via[0] == pytest.approx(np.deg2rad(2)) and c.poses[3].approach == "+y"


@pytest.mark.parametrize("edit, message", [
    ({"via": [0, 720, 0, 0, 0, 0, 0]}, r"poses\[2\].via\[0\]\[1\] \(joint2\) = 12.566.* outside"),
    ({"via": [0, 1]}, r"poses\[2\].via: expected a list of 7 numbers"),
    ({"of": ""}, r"poses\[2\].of: expected a name"),
    ({"of": "P1+y"}, r"poses\[2\].of: 'P1\+y' approaches 'P1' itself"),
])
def test_bad_approaches(gao, edit, message):
    poses = GOOD["poses"] + [dict(APPROACHED[0], **edit), APPROACHED[1]]
    with pytest.raises(CampaignError, match=message):
        campaign_from_dict({**GOOD, "poses": poses}, model=gao)
