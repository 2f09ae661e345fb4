"""The ISO 9283 test paths: their geometry in the cube's diagonal plane, the speed profile, and joint
trajectories whose nominal tool path is the planned one."""
import numpy as np
import pytest

from tolerance_ros.core.accuracy.iso_paths import (JointPath, plan_path, read_trajectory, tool_path,
                                                   trapezoid_times)
from tolerance_ros.core.accuracy.path import arc_length, corners


def test_the_three_paths_lie_in_the_diagonal_plane_with_their_sizes():
    c, side = np.array([0.5, 0.1, 0.6]), 0.3
    normal = np.array([1.0, -1.0, 0.0]) / np.sqrt(2)
    line = tool_path("line", c, side)
    assert arc_length(line.moves[0])[-1] == pytest.approx(0.8 * side * np.sqrt(3))
    assert len(line.moves) == 2 and np.allclose(line.moves[1], line.moves[0][::-1])
    circle = tool_path("circle", c, side).moves[0]
    assert np.linalg.norm(circle - c, axis=1) == pytest.approx(0.4 * side)
    rect = tool_path("rectangle", c, side).moves[0]
    assert np.allclose(rect[0], rect[-1])
    for p in (line.moves[0], circle, rect):
        assert np.abs((p - c) @ normal).max() < 1e-12
    h = side / 2
    assert corners(rect) == pytest.approx(np.cumsum([0.8 * h * 2 * np.sqrt(2), 1.6 * h, 0.8 * h * 2 * np.sqrt(2)]),
                                          abs=1e-4)
    with pytest.raises(ValueError, match="line, circle, rectangle"):
        tool_path("spiral", c, side)


def test_trapezoid_reaches_its_speed_and_rests_at_both_ends():
    s = np.linspace(0, 0.5, 5001)
    t = trapezoid_times(s, 0.2, 1.0)
    v = np.diff(s) / np.diff(t)
    assert v.max() == pytest.approx(0.2, rel=1e-3) and v[0] < 0.02 and v[-1] < 0.02
    assert t[-1] == pytest.approx(0.5 / 0.2 + 0.2 / 1.0)      # L / v + v / a


def test_joint_trajectory_follows_the_planned_tool_path(gao, tmp_path):
    jp, tp = plan_path(gao, "rectangle", speed=0.2, cycles=2, q_center=np.radians([0, 45, 0, 60, 0, 30, 0]))
    T = gao.fk(jp.q)
    d = np.min(np.linalg.norm(T[:, None, :3, 3] - tp.moves[0][None, ::4], axis=2), axis=1)
    assert d.max() < 1e-3 and np.allclose(T[:, :3, :3], tp.R, atol=1e-6)
    assert jp.duration == pytest.approx(2 * jp.period)
    assert np.allclose(jp.at([0.0, jp.period]), jp.q[0])
    import yaml
    f = tmp_path / "rect.yaml"
    f.write_text(yaml.safe_dump(jp.to_dict()))
    back = read_trajectory(f, gao)
    assert isinstance(back, JointPath) and back.cycles == 2 and np.allclose(back.q, jp.q) and back.kind == "rectangle"


def test_a_path_out_of_reach_is_refused(gao):
    with pytest.raises(ValueError, match="carries the circle path"):
        plan_path(gao, "circle", side=5.0, q_center=np.radians([0, 45, 0, 60, 0, 30, 0]))


@pytest.mark.parametrize("profile", ["trapezoid", "raised-cosine", "minimum-jerk"])
@pytest.mark.parametrize("L", [0.002, 0.3])
def test_each_speed_profile_keeps_its_speed_and_acceleration_and_inverts_to_times(profile, L):
    """profile_distance from rest to rest within the speed and acceleration asked (one of them reached), and
    profile_times its inverse at arc lengths (the knots' times of a planned path)."""
    from tolerance_ros.core.accuracy.iso_paths import profile_distance, profile_duration, profile_times
    v, a = 0.5, 5.0
    T = profile_duration(L, v, a, profile)
    t = np.linspace(0.0, T, 200001)
    s = profile_distance(t, L, v, a, profile)
    assert s[0] == 0.0 and s[-1] == pytest.approx(L, abs=1e-15)
    speed = np.gradient(s, t)
    accel = np.gradient(speed, t)
    assert speed.min() > -1e-9 and speed.max() <= v * (1 + 1e-6) and np.abs(accel[5:-5]).max() <= a * (1 + 1e-3)
    assert speed.max() >= v * (1 - 1e-3) or np.abs(accel[5:-5]).max() >= a * (1 - 1e-2)
    assert abs(speed[-1]) < 1e-3 * v and abs(speed[0]) < 1e-3 * v
    knots = np.linspace(0.0, L, 101)
    back = profile_distance(profile_times(knots, v, a, profile), L, v, a, profile)
    assert np.abs(back - knots).max() < 1e-6 * L
