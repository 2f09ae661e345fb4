"""The vendors' orientations against scipy's rotations, and the values written nearest the old ones: unchanged to the
last bit for an unchanged rotation, exact for a new one, never a branch or a turn away."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from tolerance_ros.core.geometry import exp_so3, rotation_error
from tolerance_ros.core.programs.orientation import nearest, to_matrix


def _samples(kind, rng, n=200):
    if kind == "quat":
        q = rng.normal(size=(n, 4))
        return q / np.linalg.norm(q, axis=1, keepdims=True)
    if kind in ("zyx", "wpr"):
        v = rng.uniform(-180, 180, (n, 3))
        v[:, 1] /= 2
        v[:10, 1] = 90.0            # at the gimbal lock
        v[10:20, 1] = -90.0
        return v
    v = rng.normal(size=(n, 3))
    v *= (rng.uniform(0, np.pi, n) / np.linalg.norm(v, axis=1))[:, None]
    v[:10] *= np.pi / np.linalg.norm(v[:10], axis=1, keepdims=True)      # a half turn: tool down on a UR
    return v


def test_the_conventions_are_the_vendors():
    rng = np.random.default_rng(0)
    q = _samples("quat", rng)
    np.testing.assert_allclose(to_matrix("quat", q), Rotation.from_quat(q[:, [1, 2, 3, 0]]).as_matrix(), atol=1e-12)
    abc = _samples("zyx", rng)
    np.testing.assert_allclose(to_matrix("zyx", abc), Rotation.from_euler("ZYX", abc, degrees=True).as_matrix(),
                               atol=1e-12)
    wpr = _samples("wpr", rng)
    np.testing.assert_allclose(to_matrix("wpr", wpr), Rotation.from_euler("xyz", wpr, degrees=True).as_matrix(),
                               atol=1e-12)
    r = _samples("rotvec", rng)
    np.testing.assert_allclose(to_matrix("rotvec", r), Rotation.from_rotvec(r).as_matrix(), atol=1e-12)


@pytest.mark.parametrize("kind", ["quat", "zyx", "wpr", "rotvec"])
def test_values_nearest_the_old_ones(kind):
    rng = np.random.default_rng(1)
    old = _samples(kind, rng)
    R = to_matrix(kind, old)
    same = nearest(kind, old, R)
    assert np.abs(same - old).max() < 1e-9 * (180 if kind in ("zyx", "wpr") else 1)   # far below any digit written
    new_R = exp_so3(rng.normal(0, 1e-3, (len(old), 3))) @ R
    new = nearest(kind, old, new_R)
    assert np.abs(rotation_error(to_matrix(kind, new), new_R)).max() < 1e-12
    step = np.abs(new - old).max(axis=1)
    if kind in ("zyx", "wpr"):
        # near +-90 deg of pitch a tilt of 1 mrad turns the other two angles by up to 1 mrad / cos(pitch), as it must
        cos = np.maximum(np.cos(np.radians(old[:, 1])), 1e-12)
        assert np.all(step[20:] < 0.5 / cos[20:]) and np.all(step[20:] < 90)
    else:
        assert step.max() < 0.01        # a correction's size: no sign flip of the quaternion, no turn of the vector
