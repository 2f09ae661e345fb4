"""Joint configurations over time for the joint-state publisher."""
import numpy as np
import pytest

from tolerance_ros.core.campaign import Campaign, TestPose
from tolerance_ros.services.joint_source import JointStateSequence
from tolerance_ros.core.synthesis.search import pose_index


def test_campaign_sequence_dwell_and_hold(gao):
    qk = gao.sample_joints(2, 0)
    camp = Campaign("c", [TestPose("P1", joints=qk[0]), TestPose("P2", joints=qk[1])], cycles=2, dwell_s=1.5)
    seq = JointStateSequence(gao, "campaign", camp)
    assert len(seq) == 4
    assert [seq.at(t)[1] for t in (0.0, 1.4, 1.6, 3.1, 4.6)] == ["P1", "P1", "P2", "P1", "P2"]
    step, label, q, finished = seq.at(100.0)
    assert finished and label == "P2" and np.allclose(q, qk[1])
    looped = JointStateSequence(gao, "campaign", camp, loop=True)
    assert looped.at(6.1)[1] == "P1" and not looped.at(6.1)[3]


def test_random_is_seeded_and_within_limits(gao):
    a = JointStateSequence(gao, "random", count=20, seed=3, dwell=0.1)
    b = JointStateSequence(gao, "random", count=20, seed=3, dwell=0.1)
    assert np.array_equal(a.q, b.q) and not gao.out_of_limits(a.q).any()


def test_selected_poses_have_high_index(gao):
    sel = JointStateSequence(gao, "selected", count=3, seed=1)
    rand = gao.sample_joints(2000, 5)
    assert pose_index(gao, sel.q).min() >= np.percentile(pose_index(gao, rand), 99)


@pytest.mark.parametrize("kwargs, message", [(dict(mode="spiral"), "mode"), (dict(mode="campaign"), "campaign"),
                                             (dict(mode="random", count=0), "count"),
                                             (dict(mode="random", dwell=-1.0), "dwell")])
def test_bad_settings(gao, kwargs, message):
    with pytest.raises(ValueError, match=message):
        JointStateSequence(gao, **kwargs)


@pytest.mark.parametrize("t", [float("nan"), float("inf")])
def test_a_time_that_is_not_finite_is_refused(gao, t):
    seq = JointStateSequence(gao, "random", count=3)
    with pytest.raises(ValueError, match="t: expected a finite time in s"):
        seq.at(t)
    assert seq.at(1e300)[3] is True  # long after the end: the last configuration, held


def test_trajectory_mode_moves_along_the_knots_for_its_cycles(gao):
    from tolerance_ros.core.accuracy.iso_paths import JointPath
    q = gao.sample_joints(3, 2)
    path = JointPath(tuple(gao.joint_names), np.array([0.0, 1.0, 3.0]), q, cycles=2)
    seq = JointStateSequence(gao, "trajectory", trajectory=path)
    step, label, qa, finished = seq.at(0.5)
    assert np.allclose(qa, (q[0] + q[1]) / 2) and label == "cycle1 knot0" and step == 0 and not finished
    step, label, qb, _ = seq.at(3.0 + 2.0)  # the second cycle, halfway between knots 1 and 2
    assert np.allclose(qb, (q[1] + q[2]) / 2) and label == "cycle2 knot1" and step == 4
    step, label, qc, finished = seq.at(100.0)
    assert finished and np.allclose(qc, q[2])
    looped = JointStateSequence(gao, "trajectory", trajectory=path, loop=True)
    assert not looped.at(6.5)[3] and np.allclose(looped.at(6.5)[2], (q[0] + q[1]) / 2)
    with pytest.raises(ValueError, match="needs a trajectory"):
        JointStateSequence(gao, "trajectory")


def test_a_pose_with_a_pre_pose_is_approached_through_it(gao):
    qk = gao.sample_joints(3, 0)
    camp = Campaign("c", [TestPose("P1", joints=qk[0]), TestPose("P1+x", joints=qk[0], of="P1", via=qk[2])],
                    cycles=1, dwell_s=1.0)
    seq = JointStateSequence(gao, "campaign", camp)
    assert [seq.at(t + 0.5)[1] for t in range(3)] == ["P1", "P1+x via", "P1+x"]
    assert np.allclose(seq.at(1.5)[2], qk[2]) and np.allclose(seq.at(2.5)[2], qk[0])
