"""A laser-tracker campaign of the shape of a real industrial one (issue 27), simulated on the FANUC R-2000iC URDF
(no inertials, origins at pitch +-pi/2): 21 configurations at one joint-1 angle and 3 at others, three
reflectors, a 3 mrad non-perpendicularity of axes 1 and 2, a lumped joint compliance, 40 um noise. The truth
is an edited URDF measured by pinocchio (``simulate.edited_urdf``), not the error model under test."""
from pathlib import Path

import numpy as np
import pytest

from tolerance_ros.core.accuracy.io import Measurements
from tolerance_ros.core.accuracy.simulate import PinocchioArm, edited_urdf
from tolerance_ros.core.calibration.calibrate import FitOptions, calibrate_measurements
from tolerance_ros.core.calibration.elastic import Load
from tolerance_ros.core.geometry import transform
from tolerance_ros.core.models import URDFChain

URDF = Path(__file__).resolve().parents[2] / "data" / "fanuc_r2000ic" / "fanuc_r2000ic_165f.urdf"
JOINTS = ("joint_1", "joint_2", "joint_3", "joint_4", "joint_5", "joint_6")
REFLECTORS = np.array([[0.03, 0.09, 0.0], [0.03, -0.045, 0.078], [0.03, -0.045, -0.078]])
NOISE = 40e-6
MASS = 120.0
COMPLIANCE = np.array([0.0, 0.2e-6, 0.2e-6, 0.2e-6, 0.2e-6, 0.0])   # rad/(N m): 0.2 mrad per kN m
T_TRACKER = transform([3.2, -1.1, 0.4], [0.01, -0.02, 2.4])


def _truth(seed=1):
    rng = np.random.default_rng(seed)
    edits = {j: (rng.normal(0, 0.15e-3, 3), rng.normal(0, 0.15e-3, 3), rng.normal(0, 0.5e-3)) for j in JOINTS}
    edits["joint_2"] = (edits["joint_2"][0], np.array([-3.0e-3, 0.1e-3, -0.1e-3]), edits["joint_2"][2])
    return edits


def _configurations(n, seed=0):
    rng = np.random.default_rng(seed)
    lo, hi = np.array([0.0, -0.6, -0.7, -2.0, -1.6, -2.5]), np.array([0.0, 0.9, 0.8, 2.0, 1.6, 2.5])
    q = lo + rng.random((n, 6)) * (hi - lo)
    q[21:24, 0] = (0.45, -0.5, 0.9)   # the only configurations where joint 1 moves
    return q


def campaign(repeats=3, seed=0, shift=None):
    """Measurements of the as-built robot (``shift``: {pose index: (3,) m added to its points}) and its arm."""
    arm = PinocchioArm(edited_urdf(URDF.read_text(), _truth()), "flange")
    q = _configurations(24)
    rng = np.random.default_rng(seed + 100)
    Ts, qs, labels, targets = [], [], [], []
    for _ in range(repeats):
        q_read = q + rng.normal(0, 2e-6, q.shape)
        pts = arm.points(q_read + arm.point_mass_torques(q_read, MASS) * COMPLIANCE, REFLECTORS)
        pts += rng.normal(0, NOISE, pts.shape)
        for i, s in (shift or {}).items():
            pts[i] += s
        for i in range(len(q)):
            for k in range(3):
                T = np.eye(4)
                T[:3, 3] = T_TRACKER[:3, :3] @ pts[i, k] + T_TRACKER[:3, 3]
                Ts.append(T)
                qs.append(q_read[i])
                labels.append(f"P{i + 1}")
                targets.append(f"R{k + 1}")
    n = len(Ts)
    return Measurements(np.arange(n, dtype=float), np.array(Ts), np.array(qs), JOINTS, np.array(labels, object),
                        np.full(n, -1), False, "simulated", [], np.array(targets, object)), arm


@pytest.fixture(scope="module")
def fanuc():
    return URDFChain(URDF)


@pytest.fixture(scope="module")
def calibrated(fanuc):
    meas, arm = campaign()
    return calibrate_measurements(fanuc, meas, registration="base+tool", sigma_position=1e-5), meas, arm


def test_every_pose_is_kept_and_held_out_poses_are_predicted_at_the_noise_floor(calibrated):
    """The three poses where joint 1 moves are the informative ones, not outliers: nothing is rejected, every
    measurement is scored, the held-out 3-D RMS is within 1.2x the simulated noise floor, the fit converged."""
    cal, meas, _ = calibrated
    assert cal.rejected == [] and cal.suspect == []
    v = cal.validation
    assert v["measurements"] == len(meas) and v["excluded"] == [] and "after_kept" not in v
    floor = np.sqrt(3) * NOISE
    assert v["after"]["position_rms_m"] < 1.2 * floor < v["before"]["position_rms_m"] / 10
    assert cal.position_rms < 1.2 * floor and cal.position_max >= cal.position_rms
    assert cal.convergence["converged"] and cal.convergence["stop"] in ("gradient", "step")
    assert cal.model["parameters"] == "full+elastic"


def test_the_errors_come_back_within_their_reported_deviations(calibrated, fanuc):
    """The non-perpendicularity of axes 1 and 2 (a turn of joint_2's origin about its own z, the direction that
    roll/pitch/yaw lose at pitch -pi/2) and the compliances (times the lumped 1 kg's stand-in for 120 kg)."""
    cal, _, _ = calibrated
    j = fanuc.param_names.index("joint_2.rz")
    assert "joint_2.rz" not in cal.held and abs(cal.dx[j] - 3.0e-3) < 3 * cal.std[j] + 2e-5
    assert cal.load["model"] == "point-mass" and "lumped" in cal.load["description"]
    for k in (1, 2):   # joints 2 and 3 carry the arm; 4 and 5 are weakly loaded by a mass on the flange's axis
        assert abs(cal.compliance[k] - COMPLIANCE[k] * MASS) < 3 * cal.compliance_std[k] + 0.02 * COMPLIANCE[k] * MASS


def test_the_calibrated_model_predicts_the_as_built_robot_at_new_configurations(calibrated, fanuc):
    """Beyond the measured poses: new configurations, joint 1 anywhere, the calibrated model's reflector points
    (in the tracker frame) against pinocchio's points of the as-built robot, within a few noise sigmas."""
    cal, _, arm = calibrated
    rng = np.random.default_rng(9)
    q = fanuc.sample_joints(50, rng)
    q[:, 1:3] = rng.uniform([-0.5, -0.6], [0.8, 0.7], (50, 2))
    truth = arm.points(q + arm.point_mass_torques(q, MASS) * COMPLIANCE, REFLECTORS) @ T_TRACKER[:3, :3].T \
        + T_TRACKER[:3, 3]
    tool = cal.mechanism_chain(fanuc).fk(q, cal.dx)
    model = cal.T_tracker_base @ cal.B @ tool
    for k in range(3):
        pts = model[:, :3, :3] @ cal.targets.offsets[k] + model[:, :3, 3]
        assert np.sqrt(np.mean(np.sum((pts - truth[:, k]) ** 2, axis=1))) < 3 * NOISE


def test_a_rejection_that_would_change_what_is_identifiable_is_not_made_silently(fanuc):
    """The three joint-1 poses shifted by 2 mm: under the flexible model they are beyond the threshold, but they
    alone tell joint_2's non-perpendicularity from the base; they are kept and listed as suspect, with a
    warning, never dropped without a word."""
    meas, _ = campaign(shift={21: (0.002, 0, 0), 22: (0, 0.002, 0), 23: (0, 0, 0.002)})
    cal = calibrate_measurements(fanuc, meas, registration="base+tool", sigma_position=1e-5, parameters="full")
    assert cal.suspect and not cal.rejected
    assert {r["pose"] for r in cal.suspect} <= {"P22", "P23", "P24"}
    assert all("identifiable" in r["reason"] for r in cal.suspect)
    assert any("suspect" in w for w in cal.warnings) and "joint_2.rz" not in cal.held


def test_the_options_object_refuses_unknown_options_and_bad_values():
    with pytest.raises(TypeError, match="sigma_positon"):
        FitOptions().updated(sigma_positon=1e-5)
    with pytest.raises(ValueError, match="registration"):
        FitOptions(registration="tool")
    assert FitOptions().updated(folds=4).folds == 4


def test_a_point_mass_loads_the_joints_with_minus_m_g_dz_dq(fanuc):
    """The lumped load's torques against central differences of the tool point's height (-m g dz/dq); an offset
    point is carried by the tool frame; the default of a URDF without inertials is 1 kg at the tool origin."""
    q = fanuc.sample_joints(6, 2)
    point = np.array([0.1, -0.05, 0.2])
    load = Load("point-mass", 7.0, tuple(point))
    h = 1e-6
    fd = np.empty_like(q)
    for j in range(fanuc.dof):
        dq = np.zeros(fanuc.dof)
        dq[j] = h
        z = [(fanuc.fk(q + s * dq)[:, :3, :3] @ point + fanuc.fk(q + s * dq)[:, :3, 3])[:, 2] for s in (1, -1)]
        fd[:, j] = -(z[0] - z[1]) / (2 * h) * 7.0 * 9.81
    np.testing.assert_allclose(load.torques(fanuc, q), fd, atol=1e-6)
    assert Load.for_model(fanuc) == Load("point-mass", 1.0, (0.0, 0.0, 0.0)) and Load.for_model(fanuc).lumped
    assert Load.for_model(fanuc, (165.0, (0.0, 0.0, 0.2))).mass == 165.0
