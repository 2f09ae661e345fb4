"""Calibration as real campaigns need it: targets at unknown offsets up to 1 m, a tracker placed anywhere,
several targets per pose, an elastostatic term, outliers, and refusals of what cannot be right."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from tolerance_ros.core.accuracy.simulate import as_built_errors, measure_targets
from tolerance_ros.core.targets import Targets
from tolerance_ros.core.budget import load_budget
from tolerance_ros.core.calibration.calibrate import calibrate_measurements
from tolerance_ros.core.calibration.elastic import DeflectedChain, gravity_loads, has_inertials
from tolerance_ros.core.calibration.validation import predict_measurements
from tolerance_ros.core.calibration.calibration_file import load_calibration, save_calibration
from tolerance_ros.core.geometry import transform

NOISE = 1e-5


def _placement(seed):
    A = transform(np.random.default_rng(seed).uniform(-4, 4, 3), [0, 0, 0])
    A[:3, :3] = Rotation.random(random_state=seed).as_matrix()
    return A


def _campaign(model, dx, targets, seed, poses=30, repeats=2, deflection=None, points=True):
    q = np.repeat(model.sample_joints(poses, seed), repeats, axis=0)
    labels = [f"P{i // repeats}" for i in range(len(q))]
    return measure_targets(model, q, dx, targets, NOISE, 1e-5, _placement(seed), seed=seed + 1, labels=labels,
                           points=points, deflection=None if deflection is None else deflection(q))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_three_reflectors_up_to_1m_out_and_any_tracker_placement_calibrate_to_the_noise_floor(gao, seed):
    rng = np.random.default_rng(seed)
    off = rng.normal(size=(3, 3))
    off *= rng.uniform(0.2, 1.0, (3, 1)) / np.linalg.norm(off, axis=1, keepdims=True)
    tg = Targets.from_offsets(["A", "B", "C"], off)
    dx = as_built_errors(load_budget("gao2023_delta2", gao).vector_for(gao), seed)
    meas = _campaign(gao, dx, tg, seed)
    cal = calibrate_measurements(gao, meas, registration="base+tool", sigma_position=NOISE)
    v = cal.validation
    assert cal.model["parameters"] == "full" and cal.plausibility["ok"]
    assert v["after"]["position_rms_m"] < 2.0 * np.sqrt(3) * NOISE < v["before"]["position_rms_m"] / 10
    rep = cal.repeatability
    assert rep["scatter_m"] == pytest.approx(np.sqrt(3) * NOISE, rel=0.3) and rep["unexplained_m"] < 1.5 * NOISE
    assert np.abs(cal.targets.offsets - off).max() < 5e-4    # up to what the arm's own errors move them


def test_a_calibration_predicts_another_campaign_and_refits_only_a_tracker_that_moved(gao):
    tg = Targets.from_offsets(["A", "B"], [[0.3, 0.0, 0.1], [0.0, -0.4, 0.1]])
    dx = as_built_errors(load_budget("gao2023_delta2", gao).vector_for(gao), 4)
    cal = calibrate_measurements(gao, _campaign(gao, dx, tg, 4), registration="base+tool", sigma_position=NOISE)
    other = _campaign(gao, dx, tg, 4, poses=15, repeats=1)            # same tracker placement, other poses
    moved = _campaign(gao, dx, tg, 9, poses=15, repeats=1)            # the tracker moved
    same = predict_measurements(cal, gao, other)
    assert same["after"]["position_rms_m"] < 3 * NOISE and same["improvement"] > 0.85
    assert set(same["by_target"]) == {"A", "B"}
    stale = predict_measurements(cal, gao, moved)
    refit = predict_measurements(cal, gao, moved, reregister=True)
    assert stale["after"]["position_rms_m"] > 0.1 and refit["after"]["position_rms_m"] < 3 * NOISE


def test_outliers_are_rejected_and_listed(gao):
    dx = as_built_errors(load_budget("gao2023_delta2", gao).vector_for(gao), 5)
    meas = _campaign(gao, dx, None, 5)
    bad = [7, 31]
    meas.T[bad, :3, 3] += [[0.02, 0, 0], [0, -0.005, 0.003]]
    cal = calibrate_measurements(gao, meas, sigma_position=NOISE)
    assert [r["row"] for r in cal.rejected] == bad and all("exceeds" in r["reason"] for r in cal.rejected)
    v = cal.validation
    assert cal.rejected[0]["pose"] == "P3" and v["after_kept"]["position_rms_m"] < 3 * NOISE
    assert v["kept_measurements"] == v["measurements"] - 2 and v["excluded"] == bad
    assert v["after"]["position_rms_m"] > 10 * NOISE        # every measurement is scored, the outliers too
    kept = calibrate_measurements(gao, meas, sigma_position=NOISE, robust=False)
    assert not kept.rejected and kept.validation["after"]["position_rms_m"] > 10 * NOISE


def test_metres_labelled_millimetres_are_refused_before_any_fit(gao):
    from tolerance_ros.core.accuracy.checks import CheckError
    meas = _campaign(gao, None, None, 6)
    meas.T[:, :3, 3] *= 1e-3                    # the file said mm where it held m
    with pytest.raises(CheckError, match="metres labelled millimetres"):
        calibrate_measurements(gao, meas, sigma_position=NOISE)


def test_the_elastic_term_is_kept_where_the_arm_bends_and_recovers_the_compliance(ur5):
    """A UR5 whose shoulder and elbow sag 2e-4 rad per N m of gravity load: the elastostatic candidate
    predicts best and finds the compliances; a stiff arm keeps the geometric model."""
    assert has_inertials(ur5)
    c = np.zeros(ur5.dof)
    c[1], c[2] = 2e-4, 3e-4
    sag = lambda q: gravity_loads(ur5, q) * c  # noqa: E731
    delta = np.array([1e-4 if k == "length" else 5e-4 for k in ur5.param_kinds])
    dx = as_built_errors(delta, 2)
    cal = calibrate_measurements(ur5, _campaign(ur5, dx, None, 2, poses=40, deflection=sag),
                                 sigma_position=NOISE)
    assert cal.model["parameters"] == "full+elastic"
    assert cal.compliance[1:3] == pytest.approx(c[1:3], rel=0.1)
    stiff = calibrate_measurements(ur5, _campaign(ur5, dx, None, 2, poses=40), sigma_position=NOISE)
    assert stiff.model["parameters"] == "full"
    chain = cal.mechanism(ur5)
    assert isinstance(chain, DeflectedChain)


def test_gravity_loads_are_the_force_of_gravity_minus_the_gradient_of_the_potential_energy(ur5):
    import pinocchio as pin
    q = ur5.sample_joints(3, 1)
    g = gravity_loads(ur5, q)
    data = ur5.pin_model.createData()
    h = 1e-6
    for i in range(3):
        for j in range(ur5.dof):
            up, down = q[i].copy(), q[i].copy()
            up[j] += h
            down[j] -= h
            U = [pin.computePotentialEnergy(ur5.pin_model, data, ur5.pinocchio_configuration(x)) for x in (up, down)]
            assert -(U[0] - U[1]) / (2 * h) == pytest.approx(g[i, j], abs=1e-5)


def test_targets_and_compliance_survive_the_calibration_file(ur5, tmp_path):
    c = np.zeros(ur5.dof)
    c[1] = 2e-4
    tg = Targets.from_offsets(["A", "B"], [[0.1, 0.0, 0.05], [0.0, 0.1, 0.05]])
    meas = _campaign(ur5, None, tg, 3, poses=30, deflection=lambda q: gravity_loads(ur5, q) * c)
    cal = calibrate_measurements(ur5, meas, registration="base+tool", sigma_position=NOISE,
                                 parameters="full+elastic")
    back = load_calibration(save_calibration(cal, tmp_path / "calibration.yaml"), ur5)
    assert back.targets.names == ("A", "B") and np.allclose(back.targets.X, cal.targets.X, atol=1e-12)
    assert np.allclose(back.compliance, cal.compliance, rtol=1e-12)
    assert np.allclose(back.nominal_registration["T_tracker_base"], cal.nominal_registration["T_tracker_base"])
    q = ur5.sample_joints(5, 9)
    idx = np.array([0, 1, 0, 1, 0])
    assert np.allclose(back.fk(ur5, q, idx), cal.fk(ur5, q, idx), atol=1e-12)
    assert back.model["parameters"] == "full+elastic" and back.training["joint_ranges"] == cal.training["joint_ranges"]
    assert back.compliance[1] > 0     # the shoulder yields to its load


def test_a_format_2_file_is_read_with_its_compliances_turned(ur5, tmp_path):
    """Format 2 signed the compliances against the potential energy's gradient (a joint that yields had a negative
    one); its files are read in today's sign, so that they deflect the robot as they did."""
    c = np.zeros(ur5.dof)
    c[1] = 2e-4
    meas = _campaign(ur5, None, None, 3, poses=30, deflection=lambda q: gravity_loads(ur5, q) * c)
    cal = calibrate_measurements(ur5, meas, sigma_position=NOISE, parameters="full+elastic")
    path = save_calibration(cal, tmp_path / "calibration.yaml")
    text = path.read_text().replace("format: tolerance_ros.calibration/3", "format: tolerance_ros.calibration/2")
    lines = [line for line in text.splitlines() if "content_sha256" not in line]
    in_block = False
    for i, line in enumerate(lines):
        if line.startswith("compliance:"):
            in_block = True
        elif in_block and line.startswith("  ") and "value: " in line:
            name, rest = line.split(": {value: ")
            value, tail = rest.split(",", 1)
            lines[i] = f"{name}: {{value: {-float(value)!r},{tail}"
        elif in_block:
            in_block = False
    old = tmp_path / "old.yaml"
    old.write_text("\n".join(lines) + "\n")
    back = load_calibration(old, ur5)
    assert np.allclose(back.compliance, cal.compliance, rtol=1e-12) and back.compliance[1] > 0
