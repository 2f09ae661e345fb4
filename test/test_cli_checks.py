"""The command line's answers that cannot be fooled or misread (issue 28): `simulate` with the truth beside,
refusals whose last line is the reason, options checked before any work, figures reproducible from one command
to another, files without representation noise."""
import json

import numpy as np
import pytest
import yaml

from helpers import XARM7_URDF, example_urdf, run_cli as run
from tolerance_ros.cli import main


@pytest.fixture(scope="module")
def xarm_campaign(tmp_path_factory):
    """A planned 12-pose campaign of the xArm7 (3 cycles; no collision check: the vendored URDF has no meshes)
    and its simulated measurements."""
    tmp = tmp_path_factory.mktemp("xarm")
    urdf = XARM7_URDF
    assert main(["plan-campaign", "--robot", str(urdf), "--n", "12", "--cycles", "3", "--candidates", "300",
                 "--no-collision", "--out", str(tmp / "plan.yaml"), "--quiet"]) == 0
    assert main(["simulate", "--robot", str(urdf), "--campaign", str(tmp / "plan.yaml"), "--tolerances",
                 "uniform:0.1mm,0.5mrad", "--noise", "20um", "--out", str(tmp / "m.csv"), "--quiet"]) == 0
    return urdf, tmp


def test_simulate_writes_the_measurements_and_the_truth_in_the_calibration_format(capsys, xarm_campaign):
    urdf, tmp = xarm_campaign
    truth = yaml.safe_load((tmp / "m.truth.yaml").read_text())
    assert truth["format"] == "tolerance_ros.calibration/3" and truth["model"]["parameters"] == "truth"
    assert truth["sources"]["joint_names"] == [f"joint{i}" for i in range(1, 8)]   # a list, not its text
    assert truth["sources"]["measurements"] == "m.csv" and truth["sources"]["campaign"] == "plan.yaml"  # beside it
    errors = [p["error"] for p in truth["parameters"].values()]
    assert any(e != 0 for e in errors) and max(abs(e) for e in errors) <= 0.5 + 1e-12   # mm and mrad, within
    code, out, err = run(capsys, "validate", "--calibration", tmp / "m.truth.yaml", "--measurements", tmp / "m.csv",
                         "--json")
    doc = json.loads(out)
    assert code == 0 and doc["after"]["position_rms_m"] < 3 * np.sqrt(3) * 20e-6 < doc["before"]["position_rms_m"]


def test_simulate_reflectors_and_its_errors(capsys, xarm_campaign, tmp_path):
    urdf, tmp = xarm_campaign
    code, out, err = run(capsys, "simulate", "--robot", urdf, "--campaign", tmp / "plan.yaml", "--tolerances",
                         "uniform:0.1mm,0.5mrad", "--out", tmp_path / "r.csv", "--target-offset", "R1=30mm,60mm,0mm",
                         "--target-offset", "R2=0mm,-60mm,40mm", "--json")
    doc = json.loads(out)
    assert code == 0 and doc["targets"] == ["R1", "R2"] and doc["rows"] == 2 * doc["visits"]
    head = next(line for line in (tmp_path / "r.csv").read_text().splitlines() if line.startswith("stamp"))
    assert ",target," in head and "roll" not in head
    for argv, message in (
            (["--noise", "20"], "--noise: '20' has no unit"),
            (["--target-offset", "R1=30,60,0"], "--target-offset: '30' has no unit"),
            (["--campaign", tmp_path / "none.yaml"], "none.yaml"),
            (["--out", tmp_path / "m.txt"], "--out: the measurements are a CSV file")):
        args = {"--campaign": tmp / "plan.yaml", "--out": tmp_path / "x.csv", **dict(zip(argv[::2], argv[1::2]))}
        code, out, err = run(capsys, "simulate", "--robot", urdf, "--tolerances", "uniform:0.1mm,0.5mrad", "--quiet",
                             *[a for kv in args.items() for a in kv])
        assert code == 2 and message in err and "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    code, out, err = run(capsys, "simulate", "--robot", example_urdf("ur5_robot.urdf"), "--campaign",
                         tmp / "plan.yaml", "--tolerances", "uniform:0.1mm,0.5mrad", "--out", tmp_path / "u.csv")
    assert code == 2 and "--tip-link" in err and "ee_link" in err


def test_measurements_in_the_wrong_unit_are_refused_as_bad_input_with_the_reason_last(capsys, xarm_campaign,
                                                                                      tmp_path):
    urdf, tmp = xarm_campaign
    lines = (tmp / "m.csv").read_text().splitlines()
    i = next(k for k, line in enumerate(lines) if line.startswith("stamp"))
    cols = lines[i].split(",")
    pos = [cols.index(c) for c in ("x[mm]", "y[mm]", "z[mm]")]
    body = []
    for line in lines[i + 1:]:
        f = line.split(",")
        for k in pos:
            f[k] = repr(float(f[k]) / 1000)
        body.append(",".join(f))
    (tmp_path / "metres.csv").write_text("\n".join(lines[:i + 1] + body) + "\n")
    code, out, err = run(capsys, "calibrate", "--robot", urdf, "--measurements", tmp_path / "metres.csv",
                         "--out", tmp_path / "cal", "--quiet", "--folds", "3")
    assert code == 2 and "metres labelled millimetres" in err.strip().splitlines()[-1]


def test_orientation_noise_on_points_is_said(capsys, xarm_campaign, tmp_path):
    urdf, tmp = xarm_campaign
    assert main(["simulate", "--robot", str(urdf), "--campaign", str(tmp / "plan.yaml"), "--tolerances",
                 "uniform:0.1mm,0.5mrad", "--out", str(tmp_path / "p.csv"), "--target-offset", "R=0mm,0mm,0mm",
                 "--quiet"]) == 0
    capsys.readouterr()
    code, out, err = run(capsys, "calibrate", "--robot", urdf, "--measurements", tmp_path / "p.csv", "--registration",
                         "base+tool", "--orientation-noise", "10urad", "--parameters", "joint-offsets", "--folds", "3",
                         "--out", tmp_path / "cal", "--quiet")
    assert code == 0 and "WARNING: the measurements are points: the orientation noise given (10 urad)" in out


def test_options_are_checked_before_any_work(capsys):
    code, out, err = run(capsys, "verify", "--robot", "gao2023_7dof", "--tolerances", "gao2023_delta2", "--seed", "-1")
    assert code == 2 and "--seed" in err
    code, out, err = run(capsys, "sensitivity", "--robot", "gao2023_7dof", "--samples", "1000000000")
    assert code == 2 and "cap of 50000" in err


def test_allocates_monte_carlo_is_verifys_with_the_same_seed(capsys, tmp_path):
    budget = tmp_path / "b.yaml"
    code, out, err = run(capsys, "allocate", "--robot", "gao2023_7dof", "--limit", "2mm", "--seed", "3",
                         "--mc-poses", "2000", "--out", budget, "--json", "--quiet")
    assert code == 0, err
    mc = json.loads(out)["verification"]["monte_carlo"]
    code, out, err = run(capsys, "verify", "--robot", "gao2023_7dof", "--tolerances", budget, "--samples", "2000",
                         "--seed", "3", "--errors", mc["distribution"], "--json")
    ver = json.loads(out)["position_m"]
    assert ver["max"] == pytest.approx(mc["position_m"]["max"], rel=1e-12)
    assert ver["pass_rate"] == mc["position_m"]["pass_rate"]
    text = budget.read_text()
    assert "99999999" not in text and "00000000" not in text   # no conversion noise in the written values


def test_the_failed_line_of_a_report_reads_as_words(capsys, tmp_path):
    budget = tmp_path / "tight.yaml"
    budget.write_text("robot: gao2023_7dof\nunits: {length: mm, angle: rad}\ncriterion: worst-case\n"
                      "limit: {position: 0.001}\ntolerances: {a1: 0.0001}\ndefault: 0\n")
    assert main(["plan-campaign", "--robot", "gao2023_7dof", "--n", "12", "--cycles", "2", "--candidates", "200",
                 "--out", str(tmp_path / "plan.yaml"), "--quiet"]) == 0
    assert main(["simulate", "--robot", "gao2023_7dof", "--campaign", str(tmp_path / "plan.yaml"), "--tolerances",
                 "gao2023_delta2", "--out", str(tmp_path / "m.csv"), "--quiet"]) == 0
    capsys.readouterr()
    code, out, err = run(capsys, "report", "--robot", "gao2023_7dof", "--measurements", tmp_path / "m.csv", "--budget",
                         budget)
    assert code == 3 and "24 of 24 measurements over the design limit (24 over the position limit" in err


def test_a_limit_or_budget_implausible_for_the_robot_exits_2(capsys, tmp_path):
    """--limit 1e300m, and a budget written in m where it meant mm: refused before any work (exit 2)."""
    from helpers import run_cli
    from tolerance_ros.core.resources import resolve
    code, out, err = run_cli(capsys, "allocate", "--robot", "gao2023_7dof", "--limit", "1e300m")
    assert code == 2 and "--limit: the position limit" in err and "FAILED" not in out + err
    text = resolve("budgets", "gao2023_delta2", suffixes=(".yaml",)).read_text()
    (tmp_path / "m.yaml").write_text(text.replace("length: mm", "length: m"))
    for argv in (["verify", "--robot", "gao2023_7dof", "--tolerances", tmp_path / "m.yaml"],
                 ["sensitivity", "--robot", "gao2023_7dof", "--limit", "3m", "--samples", "50"]):
        code, _, err = run_cli(capsys, *argv)
        assert code == 2 and "a length unit off" in err, err


@pytest.fixture(scope="module")
def gao_cal(tmp_path_factory):
    """A calibration of the paper's arm made by `calibrate` from a simulated campaign."""
    tmp = tmp_path_factory.mktemp("gao_cal")
    with_out = ["--quiet"]
    assert main(["plan-campaign", "--robot", "gao2023_7dof", "--n", "20", "--candidates", "300", "--out",
                 str(tmp / "plan.yaml"), *with_out]) == 0
    assert main(["simulate", "--robot", "gao2023_7dof", "--tolerances", "gao2023_delta2", "--campaign",
                 str(tmp / "plan.yaml"), "--out", str(tmp / "m.csv"), *with_out]) == 0
    assert main(["calibrate", "--robot", "gao2023_7dof", "--measurements", str(tmp / "m.csv"), "--campaign",
                 str(tmp / "plan.yaml"), "--folds", "3", "--out", str(tmp / "cal"), *with_out]) == 0
    return tmp


def test_compensate_applies_the_envelope_and_the_robot_check_as_the_nodes_do(capsys, gao_cal, tmp_path):
    """A calibration edited by hand to a 50 mrad error (its hash line deleted): refused by its envelope, no correction
    printed (exit 2); a robot file of the same name with a link 10 mm longer: refused as another robot."""
    import re
    from pathlib import Path
    from tolerance_ros.core.models import load_robot
    capsys.readouterr()
    text = (gao_cal / "cal" / "calibration.yaml").read_text()
    text = re.sub(r"(theta2: \{error: )[-0-9.e]+", r"\g<1>50.0", text)
    text = "\n".join(line for line in text.splitlines() if not line.strip().startswith("content_sha256:")) + "\n"
    (tmp_path / "big.yaml").write_text(text)
    code, out, err = run(capsys, "compensate", "--robot", "gao2023_7dof", "--calibration", tmp_path / "big.yaml",
                         "--poses", "gao2023_iso_cube")
    assert code == 2 and "outside the envelope" in err and "joint2 by up to 50" in err and "P1" not in out
    code, out, err = run(capsys, "compensate", "--robot", "gao2023_7dof", "--calibration", tmp_path / "big.yaml",
                         "--poses", "gao2023_iso_cube", "--max-joint-correction", "100mrad", "--max-tool-correction",
                         "60mm")
    assert code == 0 and "P1" in out, err
    robot = Path(load_robot("gao2023_7dof").config_path).read_text()
    (tmp_path / "longer.yaml").write_text(robot.replace("d: 415, ", "d: 425, "))
    for command in (["compensate", "--poses", "gao2023_iso_cube"], ["validate", "--measurements", gao_cal / "m.csv"]):
        code, _, err = run(capsys, command[0], "--robot", tmp_path / "longer.yaml", "--calibration",
                           gao_cal / "cal" / "calibration.yaml", *command[1:])
        assert code == 2 and "is not the robot this calibration was made for" in err, err


@pytest.mark.parametrize("extra, message", [
    (["--parameters", "full", "--payload", "5kg@0m,0m,0.1m"], "--payload: only the elastostatic term"),
    (["--payload", "2000000kg@0m,0m,0.1m"], "more than any robot arm carries"),
    (["--payload", "5kg@0m,0m,100m"], "lies more than 20 m from the tool frame"),
])
def test_calibrate_refuses_a_payload_it_would_ignore_or_that_no_arm_carries(capsys, gao_cal, extra, message):
    code, _, err = run(capsys, "calibrate", "--robot", "gao2023_7dof", "--measurements", gao_cal / "m.csv", "--out",
                       gao_cal / "unused", *extra)
    assert code == 2 and message in err, err


def test_a_urdf_in_millimetres_is_refused_at_design_time(capsys, tmp_path):
    """Every length of a UR5's URDF written in millimetres (a link 425 m long): no arm is that large."""
    import re
    text = example_urdf("ur5_robot.urdf").read_text()
    mm = re.sub(r'xyz="([^"]*)"', lambda m: 'xyz="' + " ".join(str(float(v) * 1e3) for v in m.group(1).split()) + '"',
                text)
    (tmp_path / "ur5_mm.urdf").write_text(mm)
    for argv in (["jacobian", "--joints", "0rad,0rad,0rad,0rad,0rad,0rad"], ["sensitivity", "--samples", "20"]):
        code, _, err = run(capsys, argv[0], "--robot", tmp_path / "ur5_mm.urdf", "--tip-link", "tool0", *argv[1:])
        assert code == 2 and "lengths in millimetres where metres were meant" in err, err


def _rewrite(src, dst, fix_row=None, fix_header=None):
    """A copy of the measurement CSV ``src`` with each data row's fields passed through ``fix_row`` and the header's
    through ``fix_header``."""
    lines = src.read_text().splitlines()
    head = next(i for i, line in enumerate(lines) if not line.startswith("#"))
    header = lines[head].split(",")
    rows = [line.split(",") for line in lines[head + 1:]]
    if fix_header:
        header = fix_header(header)
    if fix_row:
        rows = [fix_row(header, r) for r in rows]
    dst.write_text("\n".join(lines[:head] + [",".join(header)] + [",".join(r) for r in rows]) + "\n")
    return dst


def test_calibrate_and_validate_refuse_what_report_refuses_with_exit_2(capsys, gao_cal, tmp_path):
    """Radians labelled degrees in the orientation columns, or degrees labelled radians (issue 49: they turn as far
    as the tool on the whole, but by unrelated angles), the points in metres labelled millimetres, x and y
    swapped, another campaign with the same pose names: report, calibrate and validate all refuse them as bad
    input (exit 2) with the cause, before any fit."""
    m = gao_cal / "m.csv"
    ori = ("roll", "pitch", "yaw")

    def radians(header, row):
        return [f"{float(v) * np.pi / 180:.9f}" if header[k].split("[")[0] in ori else v for k, v in enumerate(row)]

    def swap_xy(header):
        return [{"x[mm]": "y[mm]", "y[mm]": "x[mm]"}.get(h, h) for h in header]
    cases = {
        "radians labelled degrees": _rewrite(m, tmp_path / "rad.csv", fix_row=radians),
        "degrees labelled radians": _rewrite(m, tmp_path / "deg.csv", fix_header=lambda header: [
            h.replace("[deg]", "[rad]") if h.split("[")[0] in ori else h for h in header]),
        "metres labelled millimetres": _rewrite(m, tmp_path / "m_mm.csv", fix_row=lambda h, r: [
            f"{float(v) / 1000:.9f}" if h[k] in ("x[mm]", "y[mm]", "z[mm]") else v for k, v in enumerate(r)]),
        "cannot be judged against gao2023_7dof": _rewrite(m, tmp_path / "swapped.csv", fix_header=swap_xy),
    }
    for cause, path in cases.items():
        for argv in (["report", "--measurements", path], ["calibrate", "--measurements", path, "--out", tmp_path / "c"],
                     ["validate", "--calibration", gao_cal / "cal" / "calibration.yaml", "--measurements", path]):
            code, out, err = run(capsys, argv[0], *(["--robot", "gao2023_7dof"] if argv[0] != "validate" else []),
                                 *argv[1:])
            assert code == 2 and cause in err, (argv[0], cause, err)
            assert "calibrate again" not in out + err
    other = tmp_path / "other.yaml"
    assert main(["plan-campaign", "--robot", "gao2023_7dof", "--n", "20", "--candidates", "300", "--seed", "9",
                 "--out", str(other), "--quiet"]) == 0
    capsys.readouterr()
    for argv in (["report", "--campaign", other], ["calibrate", "--campaign", other, "--out", tmp_path / "c2"]):
        code, _, err = run(capsys, argv[0], "--robot", "gao2023_7dof", "--measurements", m, *argv[1:])
        assert code == 2 and "campaign" in err, (argv[0], err)


def test_calibrate_names_a_rejected_row_by_its_file_line_as_report_does(capsys, gao_cal, tmp_path):
    m = gao_cal / "m.csv"
    lines = m.read_text().splitlines()
    head = next(i for i, line in enumerate(lines) if not line.startswith("#"))
    k = head + 21                                   # the file's line k + 1
    fields = lines[k].split(",")
    fields[3] = f"{float(fields[3]) + 40.0:.6f}"    # x 40 mm off
    lines[k] = ",".join(fields)
    (tmp_path / "off.csv").write_text("\n".join(lines) + "\n")
    code, out, err = run(capsys, "calibrate", "--robot", "gao2023_7dof", "--measurements", tmp_path / "off.csv",
                         "--campaign", gao_cal / "plan.yaml", "--folds", "3", "--out", tmp_path / "c")
    assert f"rejected: line {k + 1} (pose" in out, out


def test_a_pose_name_is_bounded(capsys, gao_cal, tmp_path):
    lines = (gao_cal / "m.csv").read_text().splitlines()
    head = next(i for i, line in enumerate(lines) if not line.startswith("#"))
    fields = lines[head + 1].split(",")
    fields[lines[head].split(",").index("pose")] = "P" * 200_000
    lines[head + 1] = ",".join(fields)
    (tmp_path / "long.csv").write_text("\n".join(lines) + "\n")
    code, _, err = run(capsys, "calibrate", "--robot", "gao2023_7dof", "--measurements", tmp_path / "long.csv",
                       "--out", tmp_path / "c")
    assert code == 2 and f"line {head + 2}: pose: a name of 200,000 characters" in err and len(err) < 1000, err


def test_calibrate_names_measured_poses_its_campaign_does_not_have_as_report_does(capsys, gao_cal, tmp_path):
    """Issue 49: C1-C20 measured, the ISO cube's P1-P5 given: both commands warn naming the poses and the
    likely cause; calibrate fits them at their own joint columns (nothing dropped)."""
    m = gao_cal / "m.csv"
    code, out, _ = run(capsys, "calibrate", "--robot", "gao2023_7dof", "--measurements", m, "--campaign",
                       "gao2023_iso_cube", "--folds", "3", "--out", tmp_path / "c", "--json", "--quiet")
    doc = json.loads(out)
    said = [w for w in doc["warnings"] if "is in campaign 'gao2023_iso_cube': the wrong campaign?" in w]
    assert code == 0 and len(said) == 1 and "none of the 20 poses measured (C1, C10" in said[0]
    assert doc["fit"]["measurements"] == sum(1 for line in m.read_text().splitlines() if not line.startswith("#")) - 1
    code, out, _ = run(capsys, "report", "--robot", "gao2023_7dof", "--measurements", m, "--campaign",
                       "gao2023_iso_cube", "--json", "--quiet")
    assert any("none of the 20 poses measured" in w for w in json.loads(out)["warnings"])


def test_the_registration_is_chosen_from_the_data_by_calibrate_and_report(capsys, gao_cal, tmp_path):
    """Issue 49: a reflector 30, -20, 80 mm off the flange: --registration auto (the default) chooses base+tool by
    its held-out RMS and says so (base alone is refused); on the flange, base is kept."""
    off = tmp_path / "off.csv"
    assert main(["simulate", "--robot", "gao2023_7dof", "--tolerances", "gao2023_delta2", "--campaign",
                 str(gao_cal / "plan.yaml"), "--target-offset", "A=30mm,-20mm,80mm", "--out", str(off),
                 "--quiet"]) == 0
    capsys.readouterr()
    for path, chosen in ((off, "base+tool"), (gao_cal / "m.csv", "base")):
        code, out, err = run(capsys, "calibrate", "--robot", "gao2023_7dof", "--measurements", path, "--campaign",
                             gao_cal / "plan.yaml", "--folds", "3", "--out", tmp_path / f"c_{chosen}", "--json",
                             "--quiet")
        assert code == 0, err
        doc = json.loads(out)
        choice = doc["model"]["registration"]
        rms = {c["registration"]: c["cv_position_rms_m"] for c in choice["candidates"]}
        assert doc["registration"] == choice["chosen"] == chosen and set(rms) == {"base", "base+tool"}
        assert (rms["base+tool"] < 0.01 * rms["base"]) if chosen == "base+tool" else (rms["base"] < 1.2 * rms[
            "base+tool"])
        code, out, err = run(capsys, "report", "--robot", "gao2023_7dof", "--measurements", path, "--json", "--quiet")
        reg = json.loads(out)["registration"]
        assert code == 0 and reg["method"] == chosen == reg["choice"]["chosen"], err
        code, out, err = run(capsys, "calibrate", "--robot", "gao2023_7dof", "--measurements", path, "--campaign",
                             gao_cal / "plan.yaml", "--folds", "3", "--out", tmp_path / f"t_{chosen}", "--quiet")
        assert f"registration '{chosen}' chosen from the data (held-out position RMS of the nominal robot: base" in out
    np.testing.assert_allclose(doc_targets(tmp_path / "c_base+tool" / "calibration.json"), [0.03, -0.02, 0.08],
                               atol=2e-3)
    code, _, err = run(capsys, "report", "--robot", "gao2023_7dof", "--measurements", off, "--registration", "base")
    assert code == 2 and "with --registration base+tool" in err


def doc_targets(path):
    """The first target's offset (m, tool frame) of a calibration.json."""
    doc = json.loads(path.read_text())
    return doc["targets"][0]["xyz_m"]
