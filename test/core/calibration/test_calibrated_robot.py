"""The calibrated robot's files: written files load and give the calibrated FK, and a URDF keeps every byte but
the corrected origins."""
import re

import numpy as np
import pytest
import yaml

from helpers import pin_fk, random_dh
from tolerance_ros.core.identification import base_matrix
from tolerance_ros.core.accuracy.simulate import as_built_errors
from tolerance_ros.core.calibration.calibrate import calibrated_mechanism
from tolerance_ros.core.calibration.calibrated_robot import (calibrated_dh_yaml, calibrated_urdf_text,
                                                             write_calibrated_robot)
from tolerance_ros.core.models import URDFChain, load_robot

BASE = np.array([2e-4, -1e-4, 3e-4, 1e-4, -2e-4, 5e-4])


def test_calibrated_dh_yaml_loads_and_gives_the_calibrated_fk(gao, gao_calibration, tmp_path):
    cal = gao_calibration
    files = write_calibrated_robot(gao, cal, tmp_path)
    model = load_robot(files["robot"])
    q = gao.sample_joints(50, 9)
    np.testing.assert_allclose(model.fk(q), base_matrix(cal.base) @ gao.fk(q, cal.dx), atol=1e-12, rtol=0)
    data = yaml.safe_load(open(files["robot"]))
    original = yaml.safe_load(open(gao.config_path))
    assert data["units"] == {"length": "mm", "angle": "rad"} and set(data) == set(original) | {"base"}
    for j, (new, old) in enumerate(zip(data["joints"], original["joints"])):
        assert new["limits"] == old["limits"] and new["name"] == old["name"]
    assert data["joints"][0]["d"] == 0  # d1 is held at nominal: written as it was
    assert data["joints"][1]["d"] == pytest.approx(177 + cal.dx[gao.param_index(["d2"])[0]] * 1e3, abs=1e-12)


def test_dh_yaml_of_a_model_without_file_with_prismatic_joints(tmp_path):
    rng = np.random.default_rng(4)
    chain = random_dh(rng, dof=6)
    assert "prismatic" in chain.joint_types
    dx = as_built_errors(np.full(chain.n_params, 1e-3), 3)
    path = tmp_path / "r.yaml"
    path.write_text(calibrated_dh_yaml(chain, dx, BASE))
    q = chain.sample_joints(30, 1)
    np.testing.assert_allclose(load_robot(path).fk(q), base_matrix(BASE) @ chain.fk(q, dx), atol=1e-12, rtol=0)


def test_calibrated_urdf_matches_pinocchio_and_changes_only_the_corrected_origins(ur5, ur5_delta, tmp_path):
    dx = as_built_errors(ur5_delta * 5, 7)
    dx[ur5.param_index(["elbow_joint." + f for f in ("x", "y", "z", "rx", "ry", "rz", "offset")])] = 0.0
    text = open(ur5.source).read()
    new = calibrated_urdf_text(ur5, text, dx, BASE)
    q = ur5.sample_joints(20, 3)
    np.testing.assert_allclose(pin_fk(new, ur5.tip_link, ur5, q), base_matrix(BASE) @ ur5.fk(q, dx), atol=1e-12,
                               rtol=0)
    def blank(t):
        return re.sub(r"<origin\b[^>]*>", lambda m: re.sub(r'\b(xyz|rpy)="[^"]*"', r'\1=""', m.group()), t)

    assert blank(new) == blank(text)
    changed = [a for a, b in zip(text.splitlines(), new.splitlines()) if a != b]
    assert len(new.splitlines()) == len(text.splitlines()) and len(changed) == ur5.dof - 1  # elbow untouched
    assert all(line.strip().startswith("<origin") for line in changed)
    files = write_calibrated_robot(ur5, calibrate_stub(ur5, dx), tmp_path)
    assert files["urdf"].endswith("ur5_robot_calibrated.urdf") and files["robot"].endswith("ur5_calibrated.yaml")
    np.testing.assert_allclose(load_robot(files["robot"]).fk(q), base_matrix(BASE) @ ur5.fk(q, dx), atol=1e-12,
                               rtol=0)   # the robot file names the chain's tip link, which the URDF alone cannot


def calibrate_stub(model, dx):
    """A Calibration with these errors and BASE (the writers only read dx and base)."""
    from tolerance_ros.core.calibration.calibrate import Calibration
    p = model.n_params
    return Calibration(model.name, model.param_names, model.param_kinds, dx, np.zeros(p), BASE, np.eye(4), None, [],
                       [], {}, 1.0, 1.0, p + 6, p + 6, 1e-5, 0.0, 0.0, 1, 1, 3)


PRISMATIC_URDF = """<?xml version="1.0"?>
<!-- a test arm: <joint name="slide" type="prismatic"> in a comment must not be edited -->
<robot name="slider">
  <link name="base"/>
  <link name="l1"/>
  <link name="l2"/>
  <joint name="turn" type="revolute">
    <parent link="base"/>
    <child link="l1"/>
    <axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/>
  </joint>
  <joint name="slide" type="prismatic">
    <parent link="l1"/>
    <child link="l2"/>
    <origin xyz="0.3 0 0.1"/>
    <axis xyz="1 0 0"/>
    <limit lower="-0.2" upper="0.4" effort="1" velocity="1"/>
  </joint>
</robot>
"""


def test_urdf_without_origin_or_rpy_and_a_prismatic_offset(tmp_path):
    path = tmp_path / "slider.urdf"
    path.write_text(PRISMATIC_URDF)
    chain = URDFChain(path)
    dx = np.linspace(1e-4, 1e-3, chain.n_params)
    new = calibrated_urdf_text(chain, PRISMATIC_URDF, dx, BASE)
    assert "<!-- a test arm: <joint name=\"slide\" type=\"prismatic\"> in a comment" in new
    assert new.count("<origin") == 2 and 'rpy="' in new.split('name="slide"')[2]
    q = chain.sample_joints(10, 1)
    np.testing.assert_allclose(pin_fk(new, chain.tip_link, chain, q), base_matrix(BASE) @ chain.fk(q, dx),
                               atol=1e-12, rtol=0)
    np.testing.assert_allclose(calibrated_mechanism(chain, dx, BASE).fk(q), base_matrix(BASE) @ chain.fk(q, dx),
                               atol=1e-12, rtol=0)
