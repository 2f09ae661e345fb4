"""The tracker's latency on simulated streams with a known one: found within 0.5 ms, the same as a brute-force
scan of the same objective, its uncertainty covering the error; and what pairing by stamp without it costs."""
import numpy as np
import pytest

from tolerance_ros.core.accuracy.latency import coarse_offset, estimate_latency, residual_sum
from tolerance_ros.core.accuracy.path_report import command_points

LATENCY = 0.008


def test_latency_within_half_a_millisecond_and_as_a_brute_force_scan(rect_run):
    model, st = rect_run
    pc = command_points(model, st.joints)
    lat = estimate_latency(st.stamps, st.points, st.joint_stamps, pc, window=0.05)
    assert abs(lat.latency_s - LATENCY) < 0.5e-3
    sub = slice(None, None, 7)
    grid = np.arange(0.0, 0.016, 2e-5)
    S = [residual_sum(x, st.stamps[sub], st.points[sub], st.joint_stamps, pc) for x in grid]
    assert lat.latency_s == pytest.approx(grid[int(np.argmin(S))], abs=5e-5)


def test_pairing_by_stamp_without_the_latency_is_wrong_by_speed_times_latency(rect_run):
    model, st = rect_run
    pc = command_points(model, st.joints)
    at = lambda t: np.column_stack([np.interp(t, st.joint_stamps, pc[:, k]) for k in range(3)])  # noqa: E731
    base = (st.points - st.T_tracker_base[:3, 3]) @ st.T_tracker_base[:3, :3]
    v = np.linalg.norm(np.gradient(st.true_points, st.true_times, axis=0), axis=1)
    cruise = np.abs(v - 0.2) < 0.002
    truth = st.true_points - at(st.true_times)                 # the as-built robot's real error
    by_stamp = np.linalg.norm(base - at(st.stamps) - truth, axis=1)
    aligned = np.linalg.norm(base - at(st.stamps - LATENCY) - truth, axis=1)
    assert np.median(by_stamp[cruise]) == pytest.approx(0.2 * LATENCY, rel=0.05)   # 1.6 mm at 0.2 m/s
    assert np.median(aligned[cruise]) < 3 * st.noise                               # the tracker's noise


def test_coarse_offset_finds_a_large_shift(rect_run):
    model, st = rect_run
    pc = command_points(model, st.joints)
    assert coarse_offset(st.stamps + 3.7, st.points, st.joint_stamps, pc) == pytest.approx(3.7 + LATENCY, abs=0.02)


def test_streams_that_do_not_overlap_are_refused(rect_run):
    model, st = rect_run
    pc = command_points(model, st.joints)
    with pytest.raises(ValueError, match="do not overlap"):
        estimate_latency(st.stamps + 1e4, st.points, st.joint_stamps, pc)
