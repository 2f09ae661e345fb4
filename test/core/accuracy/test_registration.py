"""Registration recovers known transforms and tool offsets."""
import numpy as np
import pytest

from tolerance_ros.core.accuracy.registration import register
from tolerance_ros.core.geometry import transform


def _poses(n, seed):
    rng = np.random.default_rng(seed)
    return np.array([transform(rng.uniform(-0.5, 0.5, 3), rng.uniform(-np.pi, np.pi, 3)) for _ in range(n)])


def test_exact_recovery_without_noise():
    T = transform([1.2, -0.4, 0.3], [0.2, -0.1, 2.0])
    nominal = _poses(10, 0)
    reg = register(nominal, T @ nominal)
    assert np.allclose(reg.T_tracker_base, T, atol=1e-12) and reg.rms < 1e-12
    assert np.allclose(reg.to_base(T @ nominal), nominal, atol=1e-12)


def test_tool_offset():
    T = transform([1.2, -0.4, 0.3], [0.2, -0.1, 2.0])
    off = np.array([0.01, -0.02, 0.15])
    nominal = _poses(12, 1)
    actual = nominal.copy()
    actual[:, :3, 3] += np.einsum("nij,j->ni", nominal[:, :3, :3], off)
    reg = register(nominal, T @ actual, tool=True)
    assert np.allclose(reg.tool_offset, off, atol=1e-9) and np.allclose(reg.T_tracker_base, T, atol=1e-9)
    assert np.allclose(reg.to_base(T @ actual)[:, :3, 3], nominal[:, :3, 3], atol=1e-9)


def test_noise_gives_residuals_of_the_noise_level():
    rng = np.random.default_rng(2)
    T = transform([0.5, 0.5, 0.5], [0.0, 0.3, 0.0])
    nominal = _poses(200, 3)
    meas = T @ nominal
    meas[:, :3, 3] += rng.normal(0, 1e-5, (200, 3))
    reg = register(nominal, meas)
    assert reg.rms == pytest.approx(np.sqrt(3) * 1e-5, rel=0.15)
    assert np.allclose(reg.T_tracker_base[:3, 3], T[:3, 3], atol=1e-5)


def test_degenerate_inputs():
    nominal = _poses(2, 4)
    with pytest.raises(ValueError, match="at least 3"):
        register(nominal, nominal)
    line = np.tile(np.eye(4), (5, 1, 1))
    line[:, 0, 3] = np.arange(5)
    with pytest.raises(ValueError, match="collinear"):
        register(line, line)
