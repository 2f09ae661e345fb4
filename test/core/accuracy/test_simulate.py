"""Simulated measurements: as-built errors within the tolerances, the tracker frame and its noise."""
import numpy as np
import pytest

from tolerance_ros.core.accuracy.simulate import as_built_errors, measure
from tolerance_ros.core.geometry import rotation_error, transform


def test_as_built_errors_stay_within_the_tolerances():
    delta = np.linspace(1e-5, 1e-3, 28)
    for dist in ("uniform", "extreme", "normal"):
        dx = np.array([as_built_errors(delta, seed, dist) for seed in range(200)])
        assert np.all(np.abs(dx) <= delta * (1 + 1e-12) if dist != "normal" else np.abs(dx) <= 5 * delta / 3)
    np.testing.assert_array_equal(as_built_errors(delta, 3), as_built_errors(delta, 3))
    assert np.allclose(np.abs(as_built_errors(delta, 1, "extreme")), delta)


def test_measure_without_noise_is_the_as_built_pose_in_the_tracker_frame(gao):
    q = gao.sample_joints(20, 1)
    dx = as_built_errors(np.full(gao.n_params, 1e-4), 2)
    T_tb = transform([1.5, 0.2, 0.0], [0.0, 0.0, 0.5])
    T = measure(gao, q, dx, T_tracker_base=T_tb)
    np.testing.assert_allclose(T, T_tb @ gao.fk(q, dx), atol=1e-15)
    assert not np.allclose(T, T_tb @ gao.fk(q), atol=1e-6)


def test_noise_has_the_stated_size(gao):
    q = np.repeat(gao.sample_joints(1, 3), 20000, axis=0)
    T0 = gao.fk(q)
    T = measure(gao, q, noise_position=1e-5, noise_orientation=2e-5, seed=4)
    dp = T[:, :3, 3] - T0[:, :3, 3]
    dphi = rotation_error(T[:, :3, :3], T0[:, :3, :3])
    assert dp.std(axis=0) == pytest.approx([1e-5] * 3, rel=0.03) and np.abs(dp.mean(axis=0)).max() < 3e-7
    assert dphi.std(axis=0) == pytest.approx([2e-5] * 3, rel=0.03)
    np.testing.assert_array_equal(measure(gao, q[:5], noise_position=1e-5, seed=4),
                                  measure(gao, q[:5], noise_position=1e-5, seed=4))
