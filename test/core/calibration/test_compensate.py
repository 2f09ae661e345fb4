"""Compensated joints: the joint Jacobian against finite differences, targets reached on the calibrated
model with the smallest joint change, pose targets, and the flags."""
import numpy as np
import pytest

from helpers import fd_jacobian, random_dh
from tolerance_ros.core.accuracy.simulate import as_built_errors
from tolerance_ros.core.budget import load_budget
from tolerance_ros.core.calibration.calibrate import calibrated_mechanism
from tolerance_ros.core.calibration.compensate import compensate
from tolerance_ros.core.models.ik import into_limits, joint_jacobian
from tolerance_ros.core.geometry import rotation_error
from tolerance_ros.core.models import DHChain

BASE = np.array([2e-4, -1e-4, 3e-4, 1e-4, -2e-4, 5e-4])


def test_joint_jacobian_is_the_derivative_of_fk(gao, ur5):
    chain = random_dh(np.random.default_rng(2), dof=6)
    for model in (gao, ur5, chain):
        q = model.sample_joints(3, 1)
        _, J = joint_jacobian(model, q)
        for k in range(len(q)):
            ref = fd_jacobian(lambda v: model.fk(v[None]), q[k])[0]
            np.testing.assert_allclose(J[k], ref, atol=1e-7)


@pytest.fixture(scope="module")
def gao_calibrated(gao):
    delta = load_budget("gao2023_delta2", gao).vector_for(gao)
    return calibrated_mechanism(gao, as_built_errors(delta, 5), BASE)


def test_joint_targets_are_reached_with_the_smallest_joint_change(gao, gao_calibrated):
    """The calibrated tool reaches the nominal pose of each joint target; on the redundant 7-DOF arm the
    change is the minimum-norm one to first order (pinv(J) times the pose error at the nominal joints;
    the second order grows near singular poses, where corrections reach tens of mrad)."""
    q = gao.sample_joints(200, 3)
    comp = compensate(gao_calibrated, gao, joints=q)
    ok = comp.reached & ~comp.near_singularity
    assert ok.mean() > 0.95 and np.all(comp.residual_position[comp.reached] <= 1e-9)
    np.testing.assert_allclose(gao_calibrated.fk(comp.q[ok]), gao.fk(q[ok]), atol=1e-8)
    T0, J0 = joint_jacobian(gao_calibrated, q[ok])
    T = gao.fk(q[ok])
    e = np.concatenate([T[:, :3, 3] - T0[:, :3, 3], rotation_error(T[:, :3, :3], T0[:, :3, :3])], axis=1)
    dq_min = np.einsum("nij,nj->ni", np.linalg.pinv(J0), e)
    dq = comp.correction[ok]
    rel = np.linalg.norm(dq - dq_min, axis=1) / np.linalg.norm(dq_min, axis=1)
    assert np.median(rel) < 0.01 and np.percentile(rel, 90) < 0.02
    assert np.median(np.abs(dq)) < 5e-3


def test_batch_equals_one_at_a_time(gao, gao_calibrated):
    q = gao.sample_joints(6, 8)
    batch = compensate(gao_calibrated, gao, joints=q)
    for k in range(len(q)):
        one = compensate(gao_calibrated, gao, joints=q[k:k + 1])
        np.testing.assert_allclose(one.q[0], batch.q[k], atol=1e-12)


def test_pose_targets_start_from_the_nominal_solution(ur5, ur5_delta):
    cal = calibrated_mechanism(ur5, as_built_errors(ur5_delta, 2), BASE)
    T = ur5.fk(ur5.sample_joints(20, 4))
    comp = compensate(cal, ur5, poses=T)
    good = ~comp.near_singularity
    assert good.sum() >= 18 and np.all(comp.reached[good])
    np.testing.assert_allclose(ur5.fk(comp.q_nominal[good]), T[good], atol=1e-8)
    np.testing.assert_allclose(cal.fk(comp.q[good]), T[good], atol=1e-8)
    assert np.all(np.abs(comp.correction[good]) < 0.05)
    seeded = compensate(cal, ur5, poses=T[:3], seed=comp.q_nominal[:3])
    np.testing.assert_allclose(seeded.q_nominal, comp.q_nominal[:3], atol=1e-8)


def test_flags_out_of_reach_near_singularity_and_out_of_limits(ur5, planar2r):
    far = ur5.fk(ur5.sample_joints(2, 1))
    far[:, :3, 3] *= 5.0  # several metres: beyond the arm's reach
    comp = compensate(ur5, ur5, poses=far)
    assert not comp.reached.any() and comp.to_dict()["out_of_reach"] == [0, 1]
    q = ur5.sample_joints(3, 2)
    q[:, 4] = 0.0  # wrist_2 at zero: wrist_1 and wrist_3 axes are parallel
    comp = compensate(ur5, ur5, joints=q)
    assert comp.near_singularity.all()
    narrow = planar2r.with_joint_limits([[-np.pi, np.pi], [-0.5, 0.5]])
    longer = DHChain("planar2r", a=[0.401, 0.301], alpha=[0, 0], d=[0, 0], theta=[0, 0],
                     joint_limits=[[-np.pi, np.pi], [-0.5, 0.5]])
    comp = compensate(longer, narrow, joints=[[0.2, 0.5], [0.2, 0.3]], match="position")
    assert comp.reached.all() and comp.out_of_limits.tolist() == [True, False] and comp.q[0, 1] > 0.5


def test_into_limits_takes_the_full_turn_nearest_the_reference(gao):
    q = np.array([[3.2, -3.3, 0.1, 0, 0, 0, 7.0]])
    out = into_limits(gao, q, near=np.array([[3.1, -3.1, 0.1, 0, 0, 0, 0.5]]))
    np.testing.assert_allclose(out[0, :3], [3.2 - 2 * np.pi, -3.3 + 2 * np.pi, 0.1])
    assert out[0, 6] == pytest.approx(7.0 - 2 * np.pi)
    with pytest.raises(ValueError, match="either joints or poses"):
        compensate(gao, gao)
