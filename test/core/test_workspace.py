"""Where test poses may be: restrictions read with their units, the UR10's self-collision and its links
against a floor, and sampling that keeps only what passes."""
import shutil

import numpy as np
import pytest

from helpers import example_urdf
from tolerance_ros.core.models import URDFChain
from tolerance_ros.core.workspace import (Workspace, WorkspaceError, parse_box, parse_plane, rejection_summary,
                                          restrictions)

D = np.pi / 2
FOLDED = [0, -D, np.pi, 0, 0, 0]   # elbow folded fully: the forearm on the shoulder
UPRIGHT = [0, -D, 0, 0, 0, 0]      # arm straight up
HORIZONTAL = [0, 0, 0, 0, 0, 0]    # arm stretched out at shoulder height, the wrist hanging down


@pytest.fixture(scope="module")
def ur10():
    return URDFChain(example_urdf("ur10_robot.urdf"), tip_link="tool0")


@pytest.mark.parametrize("kwargs, message", [
    ({"joint_range": ["shoulder_lift_joint=-180:0deg"]}, "shoulder_lift_joint low: '-180' has no unit"),
    ({"joint_range": ["shoulder_lift=-180deg:0deg"]}, "no joint 'shoulder_lift' (closest: 'shoulder_lift_joint'"),
    ({"joint_range": ["elbow_joint=10deg:-10deg"]}, "the low end 10deg must be below the high end -10deg"),
    ({"joint_range": ["elbow_joint=-200deg:0deg"]}, "outside the joint's limits [-180, 180] deg"),
    ({"joint_range": ["elbow_joint"]}, "expected NAME=LO:HI"),
    ({"joint_range": ["elbow_joint=0deg:1deg", "elbow_joint=0deg:2deg"]}, "elbow_joint is given twice"),
    ({"floor": "0.05"}, "--floor-plane: '0.05' has no unit"),
    ({"above_plane": ["0,0,1@5"]}, "--above-plane offset: '5' has no unit"),
    ({"above_plane": ["0,0,0@0m"]}, "must be finite and nonzero"),
    ({"above_plane": ["0,1@0m"]}, "expected NX,NY,NZ@OFFSET"),
    ({"inside_box": "0m:1m,0m:1m"}, "expected XMIN:XMAX,YMIN:YMAX,ZMIN:ZMAX"),
    ({"inside_box": "0m:1m,1m:0m,0m:1m"}, "ymin 1m must be below ymax 0m"),
    ({"clearance": "-1mm"}, "--clearance: must be >= 0"),
])
def test_restrictions_with_a_bare_number_or_out_of_range_are_refused_in_one_line(ur10, kwargs, message):
    with pytest.raises(WorkspaceError) as exc:
        restrictions(ur10, **kwargs)
    assert message in str(exc.value) and "\n" not in str(exc.value)


def test_plane_and_box_are_read_in_si():
    n, d = parse_plane("0,0,2@50mm")
    assert np.allclose(n, [0, 0, 1]) and d == pytest.approx(0.05)
    assert np.allclose(parse_box("200mm:1.2m,-0.6m:0.6m,0m:1m"), [[0.2, 1.2], [-0.6, 0.6], [0, 1]])


def test_ur10_folded_elbow_is_in_self_collision_and_upright_is_free(ur10):
    ws = Workspace(ur10, restrictions(ur10))
    assert ws.collider is not None and "shoulder_link-forearm_link" in ws.collider.pairs
    assert "upper_arm_link-forearm_link" not in ws.collider.pairs  # adjacent links
    v = ws.check(np.array([FOLDED, UPRIGHT]))
    assert list(v.ok) == [False, True] and v.reason[0] == "self-collision"
    assert v.detail[0] == "shoulder_link-forearm_link"


def test_floor_rejects_the_tool_below_it_and_a_link_through_it(ur10):
    ws = Workspace(ur10, restrictions(ur10, floor="0m"))
    down = [0, D, 0, 0, 0, 0]  # arm pointing down through the floor
    T = ur10.fk(np.array([HORIZONTAL, down]))
    assert T[0, 2, 3] > 0 > T[1, 2, 3]  # the horizontal arm's tool is above the floor, its wrist is not
    v = ws.check(np.array([HORIZONTAL, down, UPRIGHT]))
    assert list(v.reason) == ["link through a plane", "tool below a plane", ""]
    assert v.detail[0].endswith("through 0,0,1@0m") and v.detail[1] == "0,0,1@0m"
    assert Workspace(ur10, restrictions(ur10, floor="0m", collision=False)).check(np.array([HORIZONTAL])).ok[0]


def test_clearance_keeps_links_that_far_from_the_plane(ur10):
    h = Workspace(ur10, restrictions(ur10, floor="0m"))
    low = h.collider.plane_heights(h.collider.check(np.array([UPRIGHT]))[1], h.rest.planes).min()
    assert 0 < low < 0.1  # the upright arm's lowest moving link (the shoulder) is a few cm above z = 0
    assert Workspace(ur10, restrictions(ur10, floor="0m", clearance=f"{low * 0.9}m")).check([UPRIGHT]).ok[0]
    assert not Workspace(ur10, restrictions(ur10, floor="0m", clearance=f"{low * 1.1}m")).check([UPRIGHT]).ok[0]


def test_sampled_candidates_pass_and_the_rejected_are_counted(ur10):
    ws = Workspace(ur10, restrictions(ur10, ["shoulder_lift_joint=-180deg:0deg"], floor="0m",
                                      inside_box="-1.5m:1.5m,-1.5m:1.5m,-1m:1.2m"))
    q, rep = ws.sample(150, np.random.default_rng(4), 2000)
    assert len(q) == rep["kept"] == 150 and rep["drawn"] == 150 + sum(rep["rejected"].values())
    assert np.all((q[:, 1] >= -np.pi) & (q[:, 1] <= 0)) and ur10.fk(q)[:, 2, 3].min() >= 0
    assert ws.check(q).ok.all()
    assert {"self-collision", "tool below a plane"} <= set(rep["rejected"])
    assert rejection_summary(rep).startswith(f"kept 150 of {rep['drawn']:,} candidates drawn: ")


def test_a_dh_robot_has_no_collision_geometry_and_still_its_joint_ranges_and_floor(gao):
    ws = Workspace(gao, restrictions(gao, [f"{gao.joint_names[1]}=0deg:30deg"], floor="0.3m"))
    assert ws.collider is None and ws.collision_note.endswith("collisions not checked")
    q, rep = ws.sample(50, np.random.default_rng(0), 5000)
    assert len(q) == 50 and np.all((q[:, 1] >= 0) & (q[:, 1] <= np.radians(30)))
    assert gao.fk(q)[:, 2, 3].min() >= 0.3


def test_collision_meshes_that_cannot_be_found_say_what_to_do(tmp_path):
    urdf = tmp_path / "ur10_robot.urdf"
    shutil.copy(example_urdf("ur10_robot.urdf"), urdf)
    model = URDFChain(urdf, tip_link="tool0")
    with pytest.raises(WorkspaceError, match=r"could not be found.*ROS_PACKAGE_PATH, or plan with --no-collision"):
        Workspace(model, restrictions(model))
    assert Workspace(model, restrictions(model, collision=False)).collider is None
    from tolerance_ros.core.campaign import CampaignError, campaign_from_dict
    data = {"restrictions": {"collision": True}, "poses": [{"name": "P1", "joints": [0, -90, 0, 0, 0, 0]}],
            "units": {"angle": "deg"}}
    with pytest.raises(CampaignError, match=r"could not be found.*, or set restrictions.collision to false\)$"):
        campaign_from_dict(data, model=model)
    data["restrictions"]["collision"] = False
    assert campaign_from_dict(data, model=model).names == ["P1"]


def test_an_srdf_disables_its_pairs_instead_of_the_zero_configuration_rule(ur10):
    default = Workspace(ur10, restrictions(ur10)).collider
    srdf = example_urdf("ur5.srdf")  # the UR5's link names are the UR10's
    given = Workspace(ur10, restrictions(ur10, srdf=str(srdf))).collider
    assert "forearm_link-wrist_3_link" in default.pairs and "forearm_link-wrist_3_link" not in given.pairs
    assert set(given.pairs) < set(default.pairs) and "ur5.srdf disables" in given.excluded
    with pytest.raises(WorkspaceError, match="--srdf: file not found: missing.srdf"):
        restrictions(ur10, srdf="missing.srdf")


def test_a_tool_outside_the_box_names_the_side_it_left(ur10):
    ws = Workspace(ur10, restrictions(ur10, inside_box="-2m:2m,-2m:2m,0m:1m", collision=False))
    z = ur10.fk(np.array([UPRIGHT, HORIZONTAL]))[:, 2, 3]
    assert z[0] > 1 > z[1] > 0
    v = ws.check(np.array([UPRIGHT, HORIZONTAL]))
    assert list(v.reason) == ["tool outside the box", ""] and v.detail[0] == "z > 1m"
