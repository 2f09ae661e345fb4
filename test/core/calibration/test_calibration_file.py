"""The calibration file: it round-trips, and what it cannot hold is refused naming its field."""
import numpy as np
import pytest
import yaml

from helpers import example_urdf
from tolerance_ros.core.calibration.calibration_file import (CalibrationError, load_calibrated_model, load_calibration,
                                                             save_calibration)
from tolerance_ros.core.models import URDFChain


def test_calibration_file_round_trip(gao, gao_calibration, tmp_path):
    cal = gao_calibration
    path = save_calibration(cal, tmp_path / "calibration.yaml")
    doc = yaml.safe_load(path.read_text())
    assert doc["units"] == {"length": "mm", "angle": "mrad"} and doc["held"] == cal.held
    j = gao.param_index(["a2"])[0]
    assert doc["parameters"]["a2"]["error"] == pytest.approx(cal.dx[j] * 1e3, rel=1e-15)
    assert doc["validation"]["improvement"] == pytest.approx(cal.validation["improvement"])
    back = load_calibration(path, gao)
    np.testing.assert_allclose(back.dx, cal.dx, rtol=1e-15, atol=1e-20)
    np.testing.assert_allclose(back.std, cal.std, rtol=1e-15, atol=1e-20)
    np.testing.assert_allclose(back.base, cal.base, rtol=1e-15, atol=1e-20)
    np.testing.assert_allclose(back.T_tracker_base, cal.T_tracker_base, atol=1e-15)
    assert back.held == cal.held and back.aliases.keys() == cal.aliases.keys()
    assert back.aliases["base.z"]["d1"] == pytest.approx(cal.aliases["base.z"]["d1"], rel=1e-12)
    q = gao.sample_joints(10, 1)
    np.testing.assert_allclose(load_calibrated_model(path).fk(q), cal.fk(gao, q), atol=1e-12, rtol=0)


def test_calibration_file_errors_name_the_field(gao, gao_calibration, tmp_path):
    path = save_calibration(gao_calibration, tmp_path / "c.yaml")
    doc = yaml.safe_load(path.read_text())
    with pytest.raises(CalibrationError, match="not 'ur5'"):
        load_calibration(path, URDFChain(example_urdf("ur5_robot.urdf"), tip_link="tool0"))
    del doc["parameters"]["theta3"]
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump(doc))
    with pytest.raises(CalibrationError, match=r"missing \['theta3'\]"):
        load_calibration(bad, gao)
    bad.write_text("robot: gao2023_7dof\n")
    with pytest.raises(CalibrationError, match="format"):
        load_calibration(bad, gao)
    with pytest.raises(CalibrationError, match="file not found"):
        load_calibration(tmp_path / "none.yaml", gao)


@pytest.mark.parametrize("edit, message", [
    (lambda t: t.replace("units: {length: mm, angle: mrad}", "units: [mm, mrad]"),
     r": units: expected a mapping, got list"),
    (lambda t: t.replace("format: tolerance_ros.calibration/2", "format: tolerance_ros.calibration/2\nfit: 3"),
     r", line \d+: key 'fit' given twice in one mapping"),
    (lambda t: t + "junk: " + "[" * 5000 + "]" * 5000 + "\n", r", line \d+: nested deeper than 32 levels"),
    (lambda t: t.replace("rank: ", "rank: x, other: "), r": fit.rank: expected a number, got str"),
    (lambda t: t.replace("rank: ", "rank: .inf, other: "), r": fit.rank: expected a whole number, got inf"),
    (lambda t: t.replace("noise_per_axis_m: ", "noise_per_axis_m: " + "9" * 400 + ", other: "),
     r": fit.noise_per_axis_m: an integer of 400 digits is too large"),
])
def test_calibration_files_that_would_trace_back_are_the_calibrations_error(gao, gao_calibration, tmp_path, edit,
                                                                            message):
    path = save_calibration(gao_calibration, tmp_path / "c.yaml")
    path.write_text(edit(path.read_text()))
    with pytest.raises(CalibrationError, match=rf"^{path}{message}"):
        load_calibration(path, gao)
