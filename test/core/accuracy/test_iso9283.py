"""ISO 9283 characteristics against the standard's formulas written out independently."""
import numpy as np
import pytest

from tolerance_ros.core.accuracy.iso9283 import iso_cube_points, pose_characteristics, wrap
from tolerance_ros.core.geometry import rpy_from_matrix
from tolerance_ros.core.geometry import rpy_to_matrix, transform


def test_ap_rp_from_the_definitions():
    rng = np.random.default_rng(0)
    cmd = [0.5, -0.2, 0.8, 0.1, -0.3, 2.9]
    C = transform(cmd[:3], cmd[3:])
    pos = np.array(cmd[:3]) + np.array([2e-4, -1e-4, 3e-4]) + rng.normal(0, 5e-5, (30, 3))
    ang = np.array(cmd[3:]) + np.array([1e-3, 0, -2e-3]) + rng.normal(0, 2e-4, (30, 3))
    T = np.array([transform(p, a) for p, a in zip(pos, ang)])
    r = pose_characteristics(C, T)
    # ISO 9283 section 7.2.1 / 7.2.2, term by term.
    xb, yb, zb = pos.mean(axis=0)
    assert r.AP_x == pytest.approx(xb - cmd[0]) and r.AP_z == pytest.approx(zb - cmd[2])
    assert r.AP_p == pytest.approx(np.sqrt((xb - cmd[0]) ** 2 + (yb - cmd[1]) ** 2 + (zb - cmd[2]) ** 2))
    assert r.AP_a == pytest.approx(ang[:, 0].mean() - cmd[3], abs=1e-12)
    assert r.AP_c == pytest.approx(ang[:, 2].mean() - cmd[5], abs=1e-12)
    l = np.sqrt(((pos - pos.mean(axis=0)) ** 2).sum(axis=1))
    S = np.sqrt(((l - l.mean()) ** 2).sum() / 29)
    assert r.RP_l == pytest.approx(l.mean() + 3 * S)
    assert r.RP_b == pytest.approx(3 * np.std(ang[:, 1], ddof=1), rel=1e-9)


def test_angles_across_the_wrap_do_not_bias_the_mean():
    C = transform([0, 0, 0], [0, 0, np.pi])
    T = np.array([transform([0, 0, 0], [0, 0, np.pi + s]) for s in (-1e-3, 1e-3, -2e-3, 2e-3)])
    r = pose_characteristics(C, T)
    assert abs(r.AP_c) < 1e-12 and r.RP_c == pytest.approx(3 * np.std([-1e-3, 1e-3, -2e-3, 2e-3], ddof=1))


def test_rpy_round_trip_and_wrap():
    rng = np.random.default_rng(1)
    rpy = rng.uniform([-np.pi, -1.5, -np.pi], [np.pi, 1.5, np.pi], (50, 3))
    R = np.array([rpy_to_matrix(v) for v in rpy])
    assert np.allclose(rpy_from_matrix(R), rpy, atol=1e-12)
    assert np.allclose(wrap([np.pi, -np.pi, 3 * np.pi, 0.5]), [np.pi, np.pi, np.pi, 0.5])


def test_iso_cube():
    P = iso_cube_points([0.1, 0.2, 0.5], 0.4)
    assert P[0] == pytest.approx([0.1, 0.2, 0.5])
    corners = np.array([0.1, 0.2, 0.5]) + 0.2 * np.array([[-1, -1, -1], [1, 1, -1], [1, 1, 1], [-1, -1, 1]])
    diag = 0.4 * np.sqrt(3)
    for p in P[1:]:
        assert np.min(np.linalg.norm(corners - p, axis=1)) == pytest.approx(0.1 * diag)
        # On the diagonal plane x - y = const.
        assert (p[0] - 0.1) == pytest.approx(p[1] - 0.2)
    with pytest.raises(ValueError):
        iso_cube_points([0, 0], 0.4)
