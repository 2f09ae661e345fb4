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


def _poses(pos, ang):
    return np.array([transform(p, a) for p, a in zip(pos, ang)])


def test_distance_accuracy_and_repeatability_from_the_definitions():
    from tolerance_ros.core.accuracy.iso9283 import distance_characteristics
    rng = np.random.default_rng(2)
    c1, c2 = np.array([0.5, -0.2, 0.8, 0.1, -0.3, 3.1]), np.array([0.3, 0.1, 0.6, 0.2, 0.1, -3.1])
    p1 = c1[:3] + [1e-4, 0, 0] + rng.normal(0, 2e-5, (30, 3))
    p2 = c2[:3] + [0, -2e-4, 0] + rng.normal(0, 2e-5, (30, 3))
    a1 = c1[3:] + [0, 1e-3, 2e-3] + rng.normal(0, 1e-4, (30, 3))
    a2 = c2[3:] + [0, 0, -2e-3] + rng.normal(0, 1e-4, (30, 3))
    r = distance_characteristics(transform(c1[:3], c1[3:]), transform(c2[:3], c2[3:]), _poses(p1, a1), _poses(p2, a2))
    D = np.linalg.norm(p1 - p2, axis=1)
    Dc = np.linalg.norm(c1[:3] - c2[:3])
    assert r["AD_p"] == pytest.approx(D.mean() - Dc) and r["RD_p"] == pytest.approx(3 * np.std(D, ddof=1))
    assert r["AD_y"] == pytest.approx((p1 - p2)[:, 1].mean() - (c1[1] - c2[1]))
    assert r["RD_x"] == pytest.approx(3 * np.std((p1 - p2)[:, 0], ddof=1))
    # yaw crosses +-pi between the two poses: the deviations' difference, not the raw angles', is averaged
    dc = (a1[:, 2] - c1[5]) - (a2[:, 2] - c2[5])
    assert r["AD_c"] == pytest.approx(dc.mean(), abs=1e-12) and r["RD_c"] == pytest.approx(3 * np.std(dc, ddof=1))
    assert distance_characteristics(np.eye(4), np.eye(4), _poses(p1, a1), _poses(p2, a2), orientation=False)["AD_a"] \
        is None
    with pytest.raises(ValueError, match="paired"):
        distance_characteristics(np.eye(4), np.eye(4), _poses(p1, a1), _poses(p2, a2)[:5])


def test_multidirectional_variation_is_the_largest_distance_between_barycentres():
    from tolerance_ros.core.accuracy.iso9283 import multidirectional
    rng = np.random.default_rng(3)
    C = transform([0.5, 0, 0.5], [0, 0, 0])
    shift = {"+x": [1e-4, 0, 0], "+y": [0, 3e-4, 0], "+z": [0, 0, -2e-4]}
    turn = {"+x": [0, 0, 1e-3], "+y": [0, 0, -2e-3], "+z": [5e-4, 0, 0]}
    groups = {k: _poses(np.array([0.5, 0, 0.5]) + shift[k] + rng.normal(0, 1e-5, (20, 3)),
                        np.array(turn[k]) + rng.normal(0, 1e-5, (20, 3))) for k in shift}
    r = multidirectional(C, groups)
    bary = {k: g[:, :3, 3].mean(axis=0) for k, g in groups.items()}
    best = max(np.linalg.norm(bary[h] - bary[k]) for h in bary for k in bary)
    assert r["vAP_p"] == pytest.approx(best) and set(r["pair"]) == {"+y", "+z"}
    yaw = [rpy_from_matrix(g[:, :3, :3])[:, 2].mean() for g in groups.values()]
    assert r["vAP_c"] == pytest.approx(max(yaw) - min(yaw), rel=1e-9)
    with pytest.raises(ValueError, match="two or more"):
        multidirectional(C, {"+x": groups["+x"]})


def test_drift_compares_the_first_and_the_last_window():
    from tolerance_ros.core.accuracy.iso9283 import drift
    rng = np.random.default_rng(4)
    t = np.arange(0, 8 * 3600, 60.0)                       # a visit a minute for 8 hours
    creep = 2e-4 * (1 - np.exp(-t / 7200.0))               # the barycentre creeps along y
    pos = np.array([0.5, 0, 0.5]) + np.outer(creep, [0, 1, 0]) + rng.normal(0, 1e-5, (len(t), 3))
    r = drift(np.eye(4), t, _poses(pos, np.zeros((len(t), 3))), 3600.0)
    first, last = pos[t < 3600].mean(axis=0), pos[t >= 7 * 3600].mean(axis=0)
    assert len(r["windows"]) == 8 and r["dAP_p"] == pytest.approx(np.linalg.norm(first - last))
    hours = (t[t >= 7 * 3600].mean() - t[t < 3600].mean()) / 3600
    assert r["dAP_p_per_h"] == pytest.approx(r["dAP_p"] / hours)
    assert r["dRP_l"] == pytest.approx(abs(r["windows"][0]["RP_l"] - r["windows"][-1]["RP_l"]))
    with pytest.raises(ValueError, match="two windows"):
        drift(np.eye(4), t[:50], _poses(pos[:50], np.zeros((50, 3))), 3600.0)


def test_exchangeability_spans_the_barycentres_per_axis():
    from tolerance_ros.core.accuracy.iso9283 import exchangeability
    b = np.array([[0.5, 0.0, 0.5], [0.5001, -0.0002, 0.5], [0.4999, 0.0001, 0.5003]])
    assert exchangeability(b)["E"] == pytest.approx(np.sqrt(2e-4 ** 2 + 3e-4 ** 2 + 3e-4 ** 2))
    with pytest.raises(ValueError, match="two or more"):
        exchangeability(b[:1])


def test_the_drift_followed_on_line_equals_the_offline_figure():
    from tolerance_ros.core.accuracy.iso9283 import DriftTracker, drift
    rng = np.random.default_rng(5)
    t = 50.0 + np.arange(0, 4 * 3600, 30.0)
    creep = 1e-4 * (1 - np.exp(-(t - t[0]) / 3600.0))
    err = np.outer(creep, [0.6, 0.8, 0]) + rng.normal(0, 5e-6, (len(t), 3)) + [2e-5, 0, -1e-5]
    track = DriftTracker(window=3600.0, limit=5e-5)
    for ti, e in zip(t, err):
        track.add("P1", ti, e)
    track.add("P1", t[-1] + 3600.0, err[-1])            # a visit past the last window closes it
    offline = drift(np.eye(4), t, _poses(np.array([0.5, 0, 0.5]) + err, np.zeros((len(t), 3))), 3600.0)
    s = track.summary()["poses"]["P1"]
    assert s["windows"] == 4 and s["dAP_p_m"] == pytest.approx(offline["dAP_p"], rel=1e-9)
    assert s["dAP_p_per_h_m"] == pytest.approx(offline["dAP_p_per_h"], rel=1e-9)
    assert track.over == [("P1", s["dAP_p_m"])] and s["dAP_p_m"] > 5e-5
    track.add("P1", t[0], err[0])                       # out of order: not counted
    track.add("", t[-1], err[0])
    track.add("P2", float("nan"), err[0])
    assert track.summary()["poses"].keys() == {"P1"}
    with pytest.raises(ValueError, match="drift window"):
        DriftTracker(window=0.0)
