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
    (lambda t: t.replace("format: tolerance_ros.calibration/3", "format: tolerance_ros.calibration/3\nfit: 3"),
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


def _edited(path, *pairs):
    """The text of the calibration file at ``path`` edited by hand: each (old, new) replaced, and its
    content_sha256 line deleted (what the docs say to do after an edit)."""
    import re
    text = path.read_text()
    for old, new in pairs:
        assert re.search(old, text), old
        text = re.sub(old, new, text, count=1)
    lines = [line for line in text.splitlines() if not line.strip().startswith("content_sha256:")]
    return "\n".join(lines) + "\n"


def test_a_hand_edit_needs_only_its_content_sha256_line_deleted(gao, gao_calibration, tmp_path):
    path = save_calibration(gao_calibration, tmp_path / "c.yaml")
    edited = tmp_path / "edited.yaml"
    edited.write_text(_edited(path, (r"a2: \{error: [-0-9.e]+", "a2: {error: 0.01")))
    cal = load_calibration(edited, gao)
    assert cal.dx[gao.param_index(["a2"])[0]] == pytest.approx(1e-5)
    assert cal.content_sha256 != load_calibration(path, gao).content_sha256


def test_a_calibration_is_refused_for_another_version_of_its_robot(gao, gao_calibration, tmp_path):
    """Its nominal tool points at its check postures tell the robot it was made for: the same name with a link
    10 mm longer is another robot."""
    from pathlib import Path
    from tolerance_ros.core.models import load_robot
    path = save_calibration(gao_calibration, tmp_path / "c.yaml")
    text = Path(gao.config_path).read_text()
    assert "d: 415, " in text
    (tmp_path / "longer.yaml").write_text(text.replace("d: 415, ", "d: 425, "))
    longer = load_robot(tmp_path / "longer.yaml")
    assert longer.name == gao.name
    with pytest.raises(CalibrationError, match=r"nominal: gao2023_7dof as given is not the robot this calibration was "
                                               r"made for: .* up to 10 mm"):
        load_calibration(path, longer)
    assert load_calibration(path, gao).nominal == gao_calibration.nominal


def test_an_elastic_term_the_robot_cannot_load_is_refused_when_loaded(gao, gao_calibration, tmp_path):
    """A compliance block in a D-H robot's calibration (no gravity load is known for its joints): refused at once,
    naming the block, instead of an AttributeError wherever it is used."""
    path = save_calibration(gao_calibration, tmp_path / "c.yaml")
    block = "{" + ", ".join(f"{j}: {{value: 1.0e-06, std: 0}}" for j in gao.joint_names) + "}"
    (tmp_path / "elastic.yaml").write_text(_edited(path, (r"compliance: null", f"compliance: {block}")))
    with pytest.raises(CalibrationError, match="compliance: an elastostatic term needs the gravity load of each joint"):
        load_calibration(tmp_path / "elastic.yaml", gao)


def test_a_number_that_is_not_finite_is_refused_and_never_written(gao, gao_calibration, tmp_path):
    import dataclasses
    import math
    path = save_calibration(gao_calibration, tmp_path / "c.yaml")
    (tmp_path / "nan.yaml").write_text(_edited(path, (r"improvement: [-0-9.e]+", "improvement: .nan")))
    with pytest.raises(CalibrationError, match=r"validation.improvement: not a finite number"):
        load_calibration(tmp_path / "nan.yaml", gao)
    (tmp_path / "inf.yaml").write_text(_edited(path, (r"noise_per_axis_m: [-0-9.e]+", "noise_per_axis_m: -.inf")))
    with pytest.raises(CalibrationError, match=r"fit.noise_per_axis_m: not a finite number"):
        load_calibration(tmp_path / "inf.yaml", gao)
    unknown = dataclasses.replace(gao_calibration, validation=dict(gao_calibration.validation, improvement=math.nan))
    back = load_calibration(save_calibration(unknown, tmp_path / "unknown.yaml"), gao)
    assert back.validation["improvement"] is None


def test_the_file_keeps_no_per_measurement_arrays_whatever_the_campaigns_size(gao, gao_calibration, tmp_path):
    """A validation of 500,000 measurements: their error arrays are the report's (calibration.json), not the
    calibration file's, which stays the size of the model (it failed above 4 MB before)."""
    import dataclasses
    many = {"before": np.zeros(500_000), "after": np.zeros(500_000)}
    big = dataclasses.replace(gao_calibration, validation=dict(gao_calibration.validation, position_error_m=many,
                                                               orientation_error_rad=many))
    path = save_calibration(big, tmp_path / "c.yaml")
    text = path.read_text()
    assert len(text) < 200_000 and "orientation_error_rad" not in text and "position_error_m" not in text
    assert load_calibration(path, gao).validation["improvement"] == pytest.approx(big.validation["improvement"])
