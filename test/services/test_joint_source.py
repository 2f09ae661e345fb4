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
