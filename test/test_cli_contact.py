"""Calibration without a tracker from the command line: simulate --contact, calibrate and validate on contacts."""
import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from helpers import run_cli as run

URDF = Path(__file__).resolve().parent / "data" / "fanuc_r2000ic" / "fanuc_r2000ic_165f.urdf"
PLANES = ["plane:floor=0,0,1@300mm", "plane:wall=1,0,0@1700mm", "plane:side=0,1,0@-900mm"]
MOVED = ["plane:floor=0,0.1,1@250mm", "plane:wall=1,0.05,0@1650mm", "plane:side=0,1,0.02@-800mm"]


def simulate(capsys, out, planes, session, touches=30):
    argv = ["simulate", "--robot", URDF, "--tolerances", "uniform:0.1mm,0.5mrad", "--target-offset",
            "A=12mm,-6mm,110mm", "--touches", touches, "--session", session, "--out", out, "--json", "--quiet"]
    for p in planes:
        argv += ["--contact", p]
    code, stdout, err = run(capsys, *argv)
    assert code == 0, err
    return json.loads(stdout)


def test_simulate_calibrate_and_validate_on_another_session(capsys, tmp_path):
    s1 = simulate(capsys, tmp_path / "s1.csv", PLANES, "s1")
    simulate(capsys, tmp_path / "s2.csv", MOVED, "s2", touches=20)
    assert s1["rows"] == 90 and Path(s1["rig"]).is_file()
    code, out, err = run(capsys, "calibrate", "--robot", URDF, "--measurements", tmp_path / "s1.csv", "--target",
                         "A=0mm,0mm,100mm", "--folds", 5, "--out", tmp_path / "cal", "--json", "--quiet")
    assert code == 0, err
    doc = json.loads(out)
    v = doc["validation"]
    assert doc["registration"] == "contact" and doc["model"]["parameters"] == "full"
    assert v["after"]["contact_rms_m"] < 20e-6 < 0.2e-3 < v["before"]["contact_rms_m"]
    assert doc["fit"]["contact_rms_m"] < 15e-6
    rig = doc["contact"]["rig"]
    assert [p["id"] for p in rig["planes"]] == ["floor", "wall", "side"] and rig["planes"][0]["offset_std_m"] > 0
    assert np.allclose(rig["targets"][0]["xyz_m"], [0.012, -0.006, 0.110], atol=2e-4)
    assert any(w.startswith("the overall scale") for w in doc["contact"]["held_why"].values())
    written = json.loads((tmp_path / "cal" / "calibration.json").read_text())
    assert written["validation"]["after"]["contact_rms_m"] == v["after"]["contact_rms_m"]
    assert yaml.safe_load((tmp_path / "cal" / "calibration.yaml").read_text())["registration"]["method"] == "contact"
    code, out, err = run(capsys, "validate", "--calibration", tmp_path / "cal" / "calibration.yaml", "--measurements",
                         tmp_path / "s2.csv", "--robot", URDF, "--json")
    assert code == 0, err
    res = json.loads(out)
    assert res["after"]["contact_rms_m"] < 20e-6 < 0.2e-3 < res["before"]["contact_rms_m"]
    assert {p["session"] for p in res["rig"]["planes"]} == {"s2"}
    code, out, err = run(capsys, "validate", "--calibration", tmp_path / "cal" / "calibration.yaml", "--measurements",
                         tmp_path / "s2.csv", "--robot", URDF)
    assert code == 0 and "contact RMS [mm]" in out and "reduced by" in out


def test_contact_input_errors_exit_2_with_the_reason(capsys, tmp_path):
    simulate(capsys, tmp_path / "s1.csv", PLANES, "s1", touches=10)
    base = ["calibrate", "--robot", URDF, "--out", tmp_path / "cal", "--quiet"]
    code, _, err = run(capsys, *base, "--measurements", tmp_path / "s1.csv")
    assert code == 2 and "target(s) ['A'] have no nominal place on the tool" in err
    code, _, err = run(capsys, *base, "--measurements", tmp_path / "s1.csv", "--target", "A=0,0,100")
    assert code == 2 and "--target" in err
    lines = (tmp_path / "s1.csv").read_text().splitlines()
    header = [i for i, line in enumerate(lines) if line.startswith("stamp")][0]
    labelled = lines[:header] + [lines[header].replace("[rad]", "[deg]")] + lines[header + 1:]
    (tmp_path / "deg.csv").write_text("\n".join(labelled) + "\n")     # radians labelled degrees: all within the limits
    code, _, err = run(capsys, *base, "--measurements", tmp_path / "deg.csv", "--target", "A=0mm,0mm,100mm")
    assert code == 2 and "look like radians labelled degrees" in err
    rows = [lines[header]] + [
        ",".join(f[:5] + [repr(float(v) * 180 / np.pi) for v in f[5:]])
        for f in (line.split(",") for line in lines[header + 1:])]
    (tmp_path / "rad.csv").write_text("\n".join(rows) + "\n")      # degrees labelled radians
    code, _, err = run(capsys, *base, "--measurements", tmp_path / "rad.csv", "--target", "A=0mm,0mm,100mm")
    assert code == 2 and "degrees labelled radians" in err
    code, _, err = run(capsys, *base, "--measurements", tmp_path / "s1.csv", "--target", "A=0mm,0mm,100mm",
                       "--registration", "base+tool")
    assert code == 2 and "do not apply" in err


def test_simulate_contact_options_are_checked(capsys, tmp_path):
    base = ["simulate", "--robot", URDF, "--tolerances", "uniform:0.1mm,0.5mrad", "--out", tmp_path / "x.csv",
            "--target-offset", "A=0mm,0mm,100mm"]
    code, _, err = run(capsys, *base, "--contact", "plane:t=0,0,1@300")
    assert code == 2 and "--contact" in err
    code, _, err = run(capsys, *base, "--contact", "sphere:t=0,0,1@300mm")
    assert code == 2 and "plane:ID=NX,NY,NZ@OFFSET or point:ID=X,Y,Z" in err
    code, _, err = run(capsys, *base, "--contact", "point:far=10m,0m,0m")
    assert code == 2 and "reach it within the joint limits" in err


def test_plan_campaign_for_contacts_writes_the_planned_postures(capsys, tmp_path):
    argv = ["plan-campaign", "--robot", URDF, "--target", "A=0mm,0mm,100mm", "--n", 36, "--candidates", 300,
            "--out", tmp_path / "c.yaml", "--quiet"]
    for p in PLANES:
        argv += ["--contact", p]
    code, out, err = run(capsys, *argv, "--json")
    assert code == 0, err
    doc = json.loads(out)
    assert doc["poses"] == 36 and set(doc["contacts"]) <= {"plane:floor", "plane:wall", "plane:side"}
    assert doc["observability"]["planned"]["condition"] < doc["observability"]["random"]["condition"]
    camp = yaml.safe_load((tmp_path / "c.yaml").read_text())
    assert len(camp["poses"]) == 36 and "plane:" in camp["description"]
    code, _, err = run(capsys, "plan-campaign", "--robot", URDF, "--contact", PLANES[0], "--quiet")
    assert code == 2 and "give both" in err


def test_report_on_a_contact_campaign_says_what_it_is(capsys, tmp_path):
    simulate(capsys, tmp_path / "s1.csv", PLANES[:1], "s1", touches=5)
    code, _, err = run(capsys, "report", "--robot", URDF, "--measurements", tmp_path / "s1.csv")
    assert code == 2 and "a contact campaign" in err and "calibrate and validate read it" in err


def test_simulate_flush_writes_the_targets_of_a_posture_as_rows_of_one_stamp_and_pose(capsys, tmp_path):
    code, _, err = run(capsys, "simulate", "--robot", URDF, "--tolerances", "uniform:0.1mm,0.5mrad", "--contact",
                       PLANES[0], "--target-offset", "A=0mm,0mm,100mm", "--target-offset", "B=30mm,0mm,100mm",
                       "--flush", "--touches", 5, "--out", tmp_path / "f.csv", "--quiet")
    assert code == 0, err
    from tolerance_ros.core.accuracy.io.contact_csv import read_contacts
    from tolerance_ros.core.models.urdf import URDFChain
    model = URDFChain(URDF)
    c = read_contacts(tmp_path / "f.csv", model.joint_names)
    assert len(c) == 10 and list(c.target[:2]) == ["A", "B"] and c.pose[0] == c.pose[1] and c.stamps[0] == c.stamps[1]
    T = model.fk(c.joints[:2])      # nominal: both on the floor within the as-built errors
    heights = [(T[i, :3, 3] + T[i, :3, :3] @ off)[2] for i, off in enumerate(([0, 0, 0.1], [0.03, 0, 0.1]))]
    assert np.allclose(heights, 0.3, atol=2e-3)


def test_a_target_given_as_a_urdf_link_is_that_links_origin_in_the_tool_frame():
    from tolerance_ros.cli.common import CLIError, target_options
    from tolerance_ros.core.models.urdf import URDFChain
    model = URDFChain(URDF)                                  # tip: the flange, 0.215 m beyond link6 along its x
    place = target_options(["W=link:link6", "A=1mm,2mm,3mm"], model)
    T = model.fk(model.sample_joints(1, 3))[0]
    import pinocchio as pin
    pin_model = model.pin_model
    data = pin_model.createData()
    pin.framesForwardKinematics(pin_model, data, model.pinocchio_configuration(model.sample_joints(1, 3)[0]))
    link6 = data.oMf[pin_model.getFrameId("link6")].translation
    assert np.allclose(T[:3, 3] + T[:3, :3] @ place["W"], link6, atol=1e-12)
    assert np.allclose(place["A"], [0.001, 0.002, 0.003])
    with pytest.raises(CLIError, match="moves against the tip link"):
        target_options(["B=link:link3"], model)
    with pytest.raises(CLIError, match="is not in the URDF"):
        target_options(["B=link:nowhere"], model)


def _relabelled(path, out, old, new, rows=None):
    """A copy of the contact CSV at ``path`` with ``old`` replaced by ``new`` in its header (rows None) or in the data
    rows of the indices ``rows``."""
    lines = Path(path).read_text().splitlines()
    header = [i for i, line in enumerate(lines) if line.startswith("stamp")][0]
    if rows is None:
        lines[header] = lines[header].replace(old, new)
    for i in rows or []:
        lines[header + 1 + i] = lines[header + 1 + i].replace(old, new)
    Path(out).write_text("\n".join(lines) + "\n")
    return out


def test_validate_refuses_a_session_in_the_wrong_unit_as_calibrate_does(capsys, tmp_path):
    simulate(capsys, tmp_path / "s1.csv", PLANES, "s1", touches=15)
    simulate(capsys, tmp_path / "s2.csv", MOVED, "s2", touches=10)
    code, _, err = run(capsys, "calibrate", "--robot", URDF, "--measurements", tmp_path / "s1.csv", "--target",
                       "A=12mm,-6mm,110mm", "--folds", 3, "--parameters", "joint-offsets", "--out", tmp_path / "cal",
                       "--quiet")
    assert code == 0, err
    deg = _relabelled(tmp_path / "s2.csv", tmp_path / "deg.csv", "[rad]", "[deg]")
    code, out, err = run(capsys, "validate", "--calibration", tmp_path / "cal" / "calibration.yaml", "--measurements",
                         deg, "--robot", URDF, "--json")
    assert code == 2 and not json.loads(out)["ok"] and "radians labelled degrees" in err and str(deg) in err


def test_a_plane_id_changed_mid_session_is_named(capsys, tmp_path):
    """Three contacts of the floor logged as plane:flor between floor contacts: the fit had taken them for a fourth
    plane lying on the floor (three contacts fit any plane exactly: they were lost); refused, both ids named."""
    simulate(capsys, tmp_path / "s1.csv", PLANES, "s1", touches=15)
    typo = _relabelled(tmp_path / "s1.csv", tmp_path / "typo.csv", "plane:floor", "plane:flor", rows=[5, 6, 7])
    base = ["calibrate", "--robot", URDF, "--target", "A=0mm,0mm,100mm", "--folds", 3, "--out", tmp_path / "cal",
            "--quiet"]
    code, _, err = run(capsys, *base, "--measurements", typo)
    assert code == 2 and "plane:flor (3 contact(s)" in err and "plane:floor of session 's1'" in err
    assert "line 8, line 9, line 10" in err
    other = _relabelled(tmp_path / "s1.csv", tmp_path / "other.csv", "plane:floor", "plane:flor", rows=range(15))
    code, _, err = run(capsys, *base, "--measurements", other)        # one id per plane, another name: fine
    assert code == 0, err


def test_the_targets_options_for_contacts(capsys, tmp_path):
    simulate(capsys, tmp_path / "s1.csv", PLANES, "s1", touches=15)
    base = ["calibrate", "--robot", URDF, "--measurements", tmp_path / "s1.csv", "--target", "A=0mm,0mm,100mm",
            "--folds", 3, "--parameters", "joint-offsets", "--json", "--quiet"]
    for extra, kind in ((["--target-prior", "20mm"], "prior"), (["--fit-targets"], "asked")):
        code, out, err = run(capsys, *base, *extra, "--out", tmp_path / kind)
        assert code == 0, err
        doc = json.loads(out)
        said = doc["contact"]["targets_why"]
        assert {w["kind"] for w in said.values()} == {kind} and all(w["fitted"] for w in said.values())
        assert np.allclose(doc["contact"]["rig"]["targets"][0]["xyz_m"], [0.012, -0.006, 0.110], atol=2e-4)
    code, _, err = run(capsys, *base, "--target-prior", "20mm", "--fit-targets", "--out", tmp_path / "x")
    assert code == 2 and "give one" in err
    code, _, err = run(capsys, *base, "--target-prior", "2", "--out", tmp_path / "x")
    assert code == 2 and "--target-prior" in err


def test_a_figaroh_session_file_becomes_a_contact_csv_with_every_joint(tmp_path):
    """Another table set-up's FIGAROH file (the training sessions' format; no shared data needed) is written as a
    contact CSV whose 32 joint columns give the chain and the rest of the posture."""
    from tolerance_ros.core.accuracy.io.contact_csv import read_contacts
    from tolerance_ros.testing import talos_contact as tc
    rng = np.random.default_rng(2)
    q = rng.uniform(-0.2, 0.2, (4, len(tc.JOINTS)))
    lines = ["gripper,talos/left_gripper,handle,table/contact_01,joint_states," + ",".join(repr(float(v)) for v in row)
             for row in q]
    src = tmp_path / "left_other.csv"
    src.write_text("header,shifted\n" + "\n".join(lines) + "\n")
    out = tc.write_campaign("left", tmp_path / "out.csv", source=src)
    chain = [j for j in tc.JOINTS if j.startswith("leg_left") or j.startswith("torso") or j.startswith("arm_left")]
    c = read_contacts(out, chain)
    assert len(c) == 12 and set(c.session) == {"left_other"} and len(c.other_names) == len(tc.JOINTS) - len(chain)
    k = tc.JOINTS.index(c.other_names[0])
    assert np.allclose(c.others[::3, 0], q[:, k]) and np.allclose(c.joints[::3, 0], q[:, tc.JOINTS.index(chain[0])])
