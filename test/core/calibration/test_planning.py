"""Pose planning: the observability indices as defined, the exchange's local optimality, and planned sets
against random ones and the ISO 9283 cube."""
import itertools

import numpy as np
import pytest
import yaml

from helpers import random_dh
from tolerance_ros.core.calibration.planning import _gains, campaign_dict, indices, plan, select
from tolerance_ros.core.campaign import load_campaign


def test_indices_follow_their_definitions():
    s = np.array([1.0, 4.0, 2.0])
    out = indices(s, 2, 3)
    assert out["O1"] == pytest.approx(2.0 / np.sqrt(2)) and out["O2"] == pytest.approx(0.25)
    assert out["O3"] == pytest.approx(1.0) and out["O4"] == pytest.approx(0.25) and out["condition"] == pytest.approx(4)
    short = indices(np.array([3.0, 1.0]), 1, 3)  # fewer equations than unknowns
    assert short["O1"] == 0 and short["rank"] == 2 and short["condition"] == np.inf


@pytest.mark.parametrize("index", ["O1", "O2", "O3", "O4"])
def test_gains_are_the_criterion_of_the_updated_matrix(index):
    rng = np.random.default_rng(1)
    A = rng.standard_normal((30, 5))
    M = A.T @ A
    G = rng.standard_normal((7, 2, 5)) * 0.3
    for sign in (+1.0, -1.0):
        got = _gains(M, G, index, sign)
        for k in range(len(G)):
            Mk = M + sign * G[k].T @ G[k]
            lam = np.linalg.eigvalsh(Mk)
            ref = {"O1": np.sum(np.log(lam)) - np.linalg.slogdet(M)[1], "O2": np.sqrt(lam[0] / lam[-1]),
                   "O3": np.sqrt(lam[0]), "O4": lam[0] / np.sqrt(lam[-1])}[index]
            assert got[k] == pytest.approx(ref, rel=1e-9)


def test_the_exchange_ends_where_no_single_swap_improves_the_determinant():
    rng = np.random.default_rng(2)
    G = rng.standard_normal((40, 2, 5))
    design, exchanges = select(G, 6, "O1", seed=3)
    assert exchanges > 0 and len(set(design.tolist())) == 6
    info = np.einsum("kri,krj->kij", G, G)
    best = np.linalg.slogdet(info[design].sum(axis=0))[1]
    start = rng.choice(40, 6, replace=False)
    assert best > np.linalg.slogdet(info[start].sum(axis=0))[1]
    for i, c in itertools.product(design, np.setdiff1d(np.arange(40), design)):
        M = info[design].sum(axis=0) - info[i] + info[c]
        assert np.linalg.slogdet(M)[1] <= best + 1e-9


def test_planned_poses_beat_random_ones_and_the_iso_cube(gao):
    pl = plan(gao, 30, "observability", candidates=600, seed=1)
    assert set(pl.held) == {"d1", "theta1", "alpha6", "theta6", "alpha7", "theta7"} and len(pl.columns) == 28
    assert pl.chosen["rank"] == 28 and pl.chosen["O1"] > pl.random["O1"]
    assert pl.chosen["condition"] < pl.random["condition"]
    assert pl.iso_cube["poses"] == 5 and pl.iso_cube["rank"] == 15 and pl.iso_cube["O1"] == 0
    assert np.all(~gao.out_of_limits(pl.q))
    ampl = plan(gao, 30, "noise-amplification", candidates=300, seed=1, iso_joints=pl.q[:5])
    assert ampl.chosen["O4"] > ampl.random["O4"] and ampl.iso_cube_note.startswith("ISO 9283 cube: the given")
    with pytest.raises(ValueError, match="plan at least 10 poses"):
        plan(gao, 9, candidates=100)


def test_the_campaign_file_reads_back_the_planned_joints(gao, tmp_path):
    chain = random_dh(np.random.default_rng(5), dof=4)
    assert "prismatic" in chain.joint_types  # its joint is written in m, the others in degrees
    for model in (gao, chain):
        q = model.sample_joints(7, 2)
        path = tmp_path / f"{model.name}.yaml"
        path.write_text(yaml.safe_dump(campaign_dict(model, q, "planned", cycles=2)))
        camp = load_campaign(path, model)
        assert camp.names == [f"C{i + 1}" for i in range(7)] and camp.cycles == 2
        np.testing.assert_allclose(camp.joints_for(model), q, atol=1e-13)


def test_planned_ur10_poses_keep_the_joint_range_the_floor_and_no_collision():
    from helpers import example_urdf
    from tolerance_ros.core.models import URDFChain
    from tolerance_ros.core.workspace import Workspace, restrictions
    ur10 = URDFChain(example_urdf("ur10_robot.urdf"), tip_link="tool0")
    ws = Workspace(ur10, restrictions(ur10, ["shoulder_lift_joint=-180deg:0deg"], floor="0m"))
    pl = plan(ur10, 10, candidates=150, seed=2, workspace=ws)
    assert np.all((pl.q[:, 1] >= -np.pi) & (pl.q[:, 1] <= 0)) and ur10.fk(pl.q)[:, 2, 3].min() >= 0
    assert ws.check(pl.q).ok.all() and pl.candidates == 150
    r = pl.restrictions
    assert r["kept"] == 150 and r["drawn"] == 150 + sum(r["rejected"].values()) and r["rejected"]["self-collision"]
    assert r["above_plane"] == ["0,0,1@0m"] and r["collision_checked"] and pl.to_dict()["restrictions"] is r
    unrestricted = plan(ur10, 10, candidates=150, seed=2)
    assert unrestricted.q[:, 1].max() > 0 and not Workspace(ur10, ws.rest).check(unrestricted.q).ok.all()
    box = Workspace(ur10, restrictions(ur10, inside_box="1.2m:1.21m,0m:0.01m,0m:0.01m"))
    with pytest.raises(ValueError, match=r"too few candidates for 10 poses: kept 0 of 1,500 candidates drawn: "
                                         r"1,500 tool outside the box .*enlarge --inside-box"):
        plan(ur10, 10, candidates=150, workspace=box)


def test_the_iso_cube_keeps_the_configuration_nearest_the_reference_posture(gao):
    """Issue 49: the planner had put P1-P5 with the arm folded over its back and P5 on another branch; now the cube
    is centred in the configuration nearest the reference posture (the joints' zeros), all five poses reached from
    it without a change of branch, and a configuration given (--configuration) is kept, centred on its tool."""
    from tolerance_ros.core.accuracy.iso9283 import iso_cube_joints, iso_cube_points, posture_distance, \
        reference_posture
    candidates = gao.sample_joints(2000, np.random.default_rng(0))
    q, note = iso_cube_joints(gao, candidates, 0)
    ref = reference_posture(gao)
    assert np.array_equal(ref, np.zeros(7)) and "nearest the reference posture" in note
    near = posture_distance(gao, q, ref)
    assert near.max() < np.percentile(posture_distance(gao, candidates, ref), 10)
    steps = np.abs(gao.within_turn(q - q.mean(axis=0))).max()
    assert steps < np.radians(90)                    # one branch: no joint half a turn from the others
    given = np.radians([10.0, -30.0, 0.0, 70.0, 0.0, -30.0, 90.0])
    q2, note2 = iso_cube_joints(gao, candidates, 0, reference=given)
    centre = gao.fk(given[None])[0]
    T = gao.fk(q2)
    assert "nearest the one given" in note2 and np.allclose(T[:, :3, :3], centre[:3, :3], atol=1e-6)
    side = np.linalg.norm(T[1, :3, 3] - T[2, :3, 3]) / (0.8 * np.sqrt(3))
    np.testing.assert_allclose(T[:, :3, 3], iso_cube_points(centre[:3, 3], side), atol=1e-6)
    assert posture_distance(gao, q2, given).max() < 0.1


def test_an_infeasible_pre_pose_names_what_stops_it(gao):
    """The reach, a joint limit (its joint, value and limits) or a restriction (its reason), each by name."""
    from tolerance_ros.core.accuracy.iso9283 import iso_cube_joints
    from tolerance_ros.core.calibration.planning import iso9283_campaign
    from tolerance_ros.core.workspace import Verdict
    q, _ = iso_cube_joints(gao, gao.sample_joints(2000, np.random.default_rng(0)), 0)
    with pytest.raises(ValueError, match=r"P1: its pre-pose 2000 mm before it along \+x is beyond the robot's reach "
                                         r"\(the nominal inverse kinematics stops [0-9.]+ mm from it"):
        iso9283_campaign(gao, q, 2.0)
    lim = gao.joint_limits.copy()
    lim[:, 0] = q.min(axis=0) - 1e-3                   # each joint held to the span of the five poses
    lim[:, 1] = q.max(axis=0) + 1e-3
    with pytest.raises(ValueError, match=r"P1: its pre-pose 100 mm before it along \+x needs joint joint\d at "
                                         r"-?[0-9.]+ deg, beyond its limits \[-?[0-9.]+ deg, -?[0-9.]+ deg\]"):
        iso9283_campaign(gao.with_joint_limits(lim), q, 0.1)

    def below_the_cube(x):
        low = gao.fk(x)[:, 2, 3] < gao.fk(q)[:, 2, 3].min() - 1e-6
        return Verdict(~low, np.where(low, "tool below a plane", ""), np.where(low, "0,0,1@0.2m", ""))
    with pytest.raises(ValueError, match=r"along \+z breaks a restriction: tool below a plane \(0,0,1@0.2m\)"):
        iso9283_campaign(gao, q, 0.1, allowed=below_the_cube)
    doc = iso9283_campaign(gao, q, 0.05, allowed=lambda x: np.ones(len(x), bool))   # the plain form still taken
    assert len(doc["poses"]) == 20
