"""Compensated trajectories: positions as ``compensate`` gives them, rates that follow the compensated
positions (against finite differences along the path), flags per point."""
import numpy as np
import pytest

from tolerance_ros.core.accuracy.simulate import as_built_errors
from tolerance_ros.core.budget import load_budget
from tolerance_ros.core.calibration.calibrate import calibrated_mechanism
from tolerance_ros.core.calibration.compensate import compensate
from tolerance_ros.core.models.ik import joint_jacobian
from tolerance_ros.core.calibration.trajectory import compensate_trajectory


@pytest.fixture(scope="module")
def calibrated(gao):
    return calibrated_mechanism(gao, as_built_errors(load_budget("gao2023_delta2", gao).vector_for(gao), 3))


def _path(model, t, seed=1):
    rng = np.random.default_rng(seed)
    q0 = model.sample_joints(1, seed)[0] * 0.5
    w = rng.uniform(-0.6, 0.6, model.dof)
    q = q0 + np.sin(np.outer(t, [1.0] * model.dof)) * w
    qd = np.cos(np.outer(t, [1.0] * model.dof)) * w
    qdd = -np.sin(np.outer(t, [1.0] * model.dof)) * w
    return q, qd, qdd


def test_positions_are_compensates_and_rates_follow_the_compensated_positions(gao, calibrated):
    t = np.linspace(0.0, 2.0, 21)
    q, qd, qdd = _path(gao, t)
    tr = compensate_trajectory(calibrated, gao, q, qd, qdd)
    ref = compensate(calibrated, gao, joints=q)
    assert np.allclose(tr.positions, ref.q, atol=1e-12) and not tr.flagged.any()
    h = 1e-5
    up = compensate(calibrated, gao, joints=_path(gao, t + h)[0]).q
    down = compensate(calibrated, gao, joints=_path(gao, t - h)[0]).q
    fd = (up - down) / (2 * h)
    assert np.abs(tr.velocities - fd).max() < 2e-4 * np.abs(fd).max()
    assert np.abs(tr.velocities - qd).max() > 1e-5      # the rates do change
    _, J_c = joint_jacobian(calibrated, tr.positions)
    _, J_n = joint_jacobian(gao, q)
    twist_c = np.einsum("mij,mj->mi", J_c, tr.velocities)
    twist_n = np.einsum("mij,mj->mi", J_n, qd)
    assert np.allclose(twist_c, twist_n, atol=1e-9)      # the tool moves as the nominal plan says
    assert tr.accelerations.shape == qdd.shape


def test_a_point_out_of_reach_is_flagged_with_its_reason(gao, calibrated):
    q = gao.sample_joints(3, 2)
    q[1] = 0.0                                           # the stretched-out arm: a singular pose
    tr = compensate_trajectory(calibrated, gao, q)
    assert tr.flagged[1] and "singularity" in tr.reasons[1] and tr.velocities is None
