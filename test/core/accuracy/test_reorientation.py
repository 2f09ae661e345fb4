"""ISO 9283 path accuracy on reorientation against the as-built robot's truth."""
import numpy as np
import pytest

from tolerance_ros.core.accuracy.iso9283 import wrap
from tolerance_ros.core.accuracy.iso_paths import plan_path
from tolerance_ros.core.accuracy.reorientation import reorientation_report
from tolerance_ros.core.accuracy.simulate import as_built_errors, path_streams
from tolerance_ros.core.geometry import rpy_from_matrix, transform


@pytest.fixture(scope="module")
def turning(gao):
    jp, tp = plan_path(gao, "reorient", 0.5, 2.5, 0.5, 3, None, None, seed=0)
    dx = as_built_errors(np.where(np.array(gao.param_kinds) == "length", 5e-5, 2e-4), 0)
    return jp, tp, dx


def _report(gao, jp, dx, noise, A=None):
    st = path_streams(gao, jp, dx, A, 500, 1000, 0.008, noise, 3, noise_orientation=noise)
    T = np.tile(np.eye(4), (len(st.stamps), 1, 1))
    T[:, :3, :3], T[:, :3, 3] = st.rotations, st.points
    return reorientation_report(gao, st.stamps, T, st.joint_stamps, st.joints, A, 0.008)


def test_the_tool_point_and_its_orientation_against_the_as_built_robot(gao, turning):
    jp, tp, dx = turning
    # the truth: the as-built robot against the nominal one along the turn, the tool point held (no noise)
    t = 0.5 + np.linspace(0.0, 0.5 * (jp.period - 1.0), 4000)
    q = jp.at(t)
    Ta, Tn = gao.fk(q, dx), gao.fk(q)
    at_p = np.linalg.norm(Ta[:, :3, 3] - Tn[:, :3, 3], axis=1).max()
    at_ang = np.abs(wrap(rpy_from_matrix(Ta[:, :3, :3]) - rpy_from_matrix(Tn[:, :3, :3]))).max(axis=0)
    A = transform([1.5, -0.3, 0.2], [0.05, -0.02, 1.2])
    r = _report(gao, jp, dx, 10e-6, A)
    assert r["cycles"] == 3 and r["other_motions"] == 3 and r["turn_rad"] == pytest.approx(np.radians(60))
    assert np.ptp(gao.fk(jp.q)[:, :3, 3], axis=0).max() < 1e-6            # the command holds the point
    floor = 3 * 10e-6                                                        # the noise left in a mean of 3 cycles
    assert abs(r["AT_p_m"] - at_p) <= max(0.05 * at_p, floor)
    for i, ax in enumerate("abc"):
        assert abs(r[f"AT_{ax}_rad"] - at_ang[i]) <= max(0.05 * at_ang[i], floor)
    assert r["RT_p_m"] < 6 * 10e-6                                          # the cycles repeat: noise only
    exact = _report(gao, jp, dx, 0.0)
    assert exact["AT_p_m"] == pytest.approx(at_p, rel=0.01) and exact["RT_p_m"] < 1e-6


def test_a_command_that_never_moves_is_refused(gao, turning):
    jp, _, dx = turning
    st = path_streams(gao, jp, dx, None, 500, 1000, 0.008, 0.0, 3, noise_orientation=0.0)
    T = np.tile(np.eye(4), (len(st.stamps), 1, 1))
    still = np.repeat(st.joints[:1], len(st.joints), axis=0)
    with pytest.raises(ValueError, match="never moves"):
        reorientation_report(gao, st.stamps, T, st.joint_stamps, still)
