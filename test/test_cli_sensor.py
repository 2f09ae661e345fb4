"""A sensor on the robot (--sensor-link): a camera on the wrist watching a marker fixed in the cell, calibrated with
the chain's errors (hand-eye together with the chain), against the simulated truth."""
import json
from pathlib import Path

import numpy as np

from helpers import run_cli as run
from tolerance_ros.core.calibration.calibration_file import load_calibration
from tolerance_ros.core.geometry import rotation_error
from tolerance_ros.core.models.urdf import URDFChain

URDF = Path(__file__).resolve().parent / "data" / "fanuc_r2000ic" / "fanuc_r2000ic_165f.urdf"


def test_a_camera_on_the_wrist_watching_a_fixed_marker_gives_the_hand_eye_and_the_chain(capsys, tmp_path):
    chain = ["--robot", URDF, "--sensor-link", "flange"]
    code, _, err = run(capsys, "plan-campaign", *chain, "--n", 30, "--out", tmp_path / "plan.yaml", "--quiet")
    assert code == 0, err
    code, _, err = run(capsys, "simulate", *chain, "--tolerances", "uniform:0.1mm,0.5mrad", "--campaign",
                       tmp_path / "plan.yaml", "--out", tmp_path / "cam.csv", "--quiet")
    assert code == 0, err
    code, out, err = run(capsys, "calibrate", *chain, "--measurements", tmp_path / "cam.csv", "--campaign",
                         tmp_path / "plan.yaml", "--orientation-noise", "10urad", "--out", tmp_path / "cal", "--json")
    assert code == 0, err
    assert "the sensor on 'flange' measures a marker on 'base_link' (fixed in the cell)" in err
    doc = json.loads(out)
    assert doc["validation"]["after"]["position_rms_m"] < 3e-5 < 1e-3 < doc["validation"]["before"]["position_rms_m"]
    model = URDFChain(URDF, tip_link="base_link", base_link="flange")
    cal = load_calibration(tmp_path / "cal" / "calibration.yaml", model)
    truth = load_calibration(tmp_path / "cam.truth.yaml", model)
    q = model.sample_joints(50, 99)                                 # postures the campaign never visited
    seen, want = cal.T_tracker_base @ cal.fk(model, q), truth.T_tracker_base @ truth.fk(model, q)
    assert np.abs(seen[:, :3, 3] - want[:, :3, 3]).max() < 5e-5
    assert np.abs(rotation_error(seen[:, :3, :3], want[:, :3, :3])).max() < 5e-5
    # the hand-eye (the camera's placement on the flange) within the aliases of the held joint-6 parameters
    hand_eye, true_hand_eye = cal.T_tracker_base @ cal.B, truth.T_tracker_base @ truth.B
    assert np.linalg.norm(hand_eye[:3, 3] - true_hand_eye[:3, 3]) < 1e-3
    assert np.abs(rotation_error(hand_eye[None, :3, :3], true_hand_eye[None, :3, :3])).max() < 2e-3
    code, _, err = run(capsys, "calibrate", *chain, "--base-link", "link3", "--measurements", tmp_path / "cam.csv",
                       "--out", tmp_path / "x")
    assert code == 2 and "instead of --base-link" in err
