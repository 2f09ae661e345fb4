"""Searches of the joint space: maxima of a function, column maxima, the pose-selection index F."""
import numpy as np
import pytest

from tolerance_ros.core.synthesis.search import column_maxima, maximize, pose_index, select_poses, top_samples


def test_maximize_finds_the_reach_of_a_planar_arm(planar2r):
    """The distance of the 2R tool from the base is largest (0.7 m) with the arm stretched, q2 = 0."""
    def reach(q):
        return np.linalg.norm(planar2r.fk(q)[:, :3, 3], axis=1)

    res = maximize(planar2r, reach, n_samples=200, n_starts=4, seed=1)
    assert res.value == pytest.approx(0.7, abs=1e-9) and abs(np.cos(res.q[1]) - 1) < 1e-6
    assert res.value >= res.sample_max and res.maxima[0] == res.value and res.samples == 200
    assert res.evaluations > 200
    again = maximize(planar2r, reach, n_samples=200, n_starts=4, seed=1)
    np.testing.assert_array_equal(again.q, res.q)                       # seeded


def test_maximize_stays_within_the_joint_limits(planar2r):
    limited = planar2r.with_joint_limits([[-0.5, 0.5], [0.3, 1.0]])

    def reach(q):
        return np.linalg.norm(limited.fk(q)[:, :3, 3], axis=1)

    res = maximize(limited, reach, n_samples=100, n_starts=3)
    assert res.q[1] == pytest.approx(0.3) and np.all(res.maxima_q[:, 1] >= 0.3 - 1e-12)
    assert res.value == pytest.approx(np.linalg.norm([0.4 + 0.3 * np.cos(0.3), 0.3 * np.sin(0.3)]))


def test_top_samples_with_an_upper_bound_is_exact_and_evaluates_less(planar2r):
    q = planar2r.sample_joints(3000, 4)
    calls = {"n": 0}

    def reach(qq):
        calls["n"] += len(qq)
        return np.linalg.norm(planar2r.fk(qq)[:, :3, 3], axis=1)

    idx_ref, v_ref, _ = top_samples(reach, q, 5)
    calls["n"] = 0
    idx, v, evaluated = top_samples(reach, q, 5, upper=lambda qq: 1.01 * np.linalg.norm(planar2r.fk(qq)[:, :3, 3],
                                                                                         axis=1))
    np.testing.assert_array_equal(idx, idx_ref)
    np.testing.assert_allclose(v, v_ref)
    assert evaluated == calls["n"] < len(q) / 2


def test_column_maxima_of_a_planar_arm_are_exact(planar2r):
    mu = column_maxima(planar2r, "position", 500)
    names = list(planar2r.param_names)
    assert mu[names.index("theta1")] == pytest.approx(0.7, rel=1e-9)   # reached by local refinement
    assert mu[names.index("theta2")] == pytest.approx(0.3, rel=1e-9)
    assert mu[names.index("alpha2")] == 0.0


def test_pose_selection_index(planar2r):
    q = np.array([[0.0, 0.0]])
    # With 1 mm length errors and 1 rad angle errors, the stretched 2R arm moves by |(a) + (theta)|.
    F = pose_index(planar2r, q)
    J = planar2r.error_jacobian(q).position[0]
    unit = np.array([1e-3 if k == "length" else 1.0 for k in planar2r.param_kinds])
    assert F[0] == pytest.approx(np.linalg.norm(J @ unit))
    poses = select_poses(planar2r, 3, n_samples=500)
    assert poses.shape == (3, 2)
    assert pose_index(planar2r, poses).min() >= np.sort(pose_index(planar2r, planar2r.sample_joints(500, 0)))[-50]
