"""Registration recovers known transforms and tool offsets: the global solution for any tracker placement,
several targets, measured frames, from no starting guess."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from tolerance_ros.core.accuracy.registration import register
from tolerance_ros.core.targets import Targets
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
    assert np.allclose(reg.to_base(T @ actual)[:, :3, 3], actual[:, :3, 3], atol=1e-9)
    assert np.allclose(reg.targets.poses(nominal, [])[:, :3, 3], actual[:, :3, 3], atol=1e-9)


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


def _placements(n):
    """Tracker placements over every rotation (upside down included), a few metres away, and up to three
    targets up to 1 m from the tool frame."""
    rng = np.random.default_rng(11)
    for k in range(n):
        A = transform(rng.uniform(-5, 5, 3), [0, 0, 0])
        A[:3, :3] = Rotation.random(random_state=100 + k).as_matrix()
        K = 1 + k % 3
        off = rng.normal(size=(K, 3))
        off *= (rng.uniform(0.0, 1.0, (K, 1)) / np.linalg.norm(off, axis=1, keepdims=True))
        yield A, off


@pytest.mark.parametrize("case", range(12))
def test_the_global_solution_for_any_tracker_placement_and_offsets_up_to_1m(gao, case):
    A, off = list(_placements(12))[case]
    K = len(off)
    q = gao.sample_joints(25, case)
    T = np.repeat(gao.fk(q), K, axis=0)
    idx = np.tile(np.arange(K), len(q))
    pts = np.einsum("nij,nj->ni", T[:, :3, :3], off[idx]) + T[:, :3, 3]
    M = np.tile(np.eye(4), (len(pts), 1, 1))
    rng = np.random.default_rng(case)
    M[:, :3, 3] = pts @ A[:3, :3].T + A[:3, 3] + rng.normal(0, 1e-5, pts.shape)
    reg = register(T, M, tool=True, index=idx, names=tuple("ABC"[:K]))
    assert np.abs(reg.targets.offsets - off).max() < 3e-5
    assert np.abs(reg.T_tracker_base - A).max() < 3e-5
    assert reg.rms < 2.5e-5 and reg.estimated


def test_measured_frames_get_the_targets_rotation(gao):
    q = gao.sample_joints(20, 5)
    T = gao.fk(q)
    X = transform([0.1, -0.2, 0.3], [2.0, -1.0, 0.5])
    A = transform([2, 1, -1], [3.0, 0.2, -2.5])
    reg = register(T, A @ T @ X, tool=True, frames=True)
    assert np.allclose(reg.targets.X[0], X, atol=1e-9) and np.allclose(reg.T_tracker_base, A, atol=1e-9)


def test_known_targets_refit_the_tracker_only(gao):
    q = gao.sample_joints(20, 6)
    T = gao.fk(q)
    tg = Targets.from_offsets(["A", "B"], [[0.1, 0, 0], [0, 0.2, 0]])
    idx = np.arange(20) % 2
    A = transform([2, 1, -1], [0.3, 0.2, -2.5])
    M = A @ tg.poses(T, idx)
    reg = register(T, M, index=idx, targets=tg)
    assert np.allclose(reg.T_tracker_base, A, atol=1e-9) and not reg.estimated and reg.rms < 1e-9
    with pytest.raises(ValueError, match="not both"):
        register(T, M, tool=True, index=idx, targets=tg)


def test_offsets_that_the_data_cannot_determine_are_refused(gao):
    q = np.tile(gao.sample_joints(1, 1), (6, 1))
    q[:, 0] += np.linspace(0, 1, 6)  # only the first joint turns: every orientation about one axis
    T = gao.fk(q)
    with pytest.raises(ValueError, match="tool offsets are not determined"):
        register(T, T, tool=True)
    idx = np.r_[np.zeros(19, int), 1]
    q = gao.sample_joints(20, 2)
    with pytest.raises(ValueError, match="target B has 1 measurement"):
        register(gao.fk(q), gao.fk(q), tool=True, index=idx, names=("A", "B"))
