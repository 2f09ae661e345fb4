"""The command line's messages as a new user meets them (issue 49): each refusal one line naming its cause (no
numpy warning before it), the option or link it names the right one, a notice only where it tells something."""
import json
from pathlib import Path

import pytest

from helpers import run_cli as run
from tolerance_ros.cli import main

FANUC = Path(__file__).parent / "data" / "fanuc_r2000ic" / "fanuc_r2000ic_165f.urdf"
ZEROS = "0rad,0rad,0rad,0rad,0rad,0rad"


@pytest.fixture(scope="module")
def fanuc(tmp_path_factory):
    """A planned 20-pose campaign of the 6-axis FANUC and its simulated frames (orientation measured)."""
    d = tmp_path_factory.mktemp("fanuc")
    assert main(["plan-campaign", "--robot", str(FANUC), "--n", "20", "--candidates", "300", "--no-collision",
                 "--out", str(d / "plan.yaml"), "--quiet"]) == 0
    assert main(["simulate", "--robot", str(FANUC), "--campaign", str(d / "plan.yaml"), "--tolerances",
                 "uniform:0.1mm,0.5mrad", "--out", str(d / "m.csv"), "--quiet"]) == 0
    return d


def one_line(err) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    return lines[0]


def test_a_wrong_sensor_link_is_named_as_the_sensor_link(capsys):
    code, _, err = run(capsys, "jacobian", "--robot", FANUC, "--sensor-link", "link_3", "--joints", ZEROS)
    assert code == 2 and "--sensor-link: no link named 'link_3' in the URDF; did you mean 'link3'?" in one_line(err)
    assert "base_link" not in err


def test_a_sensor_on_a_link_fixed_to_the_tool_watches_a_marker_fixed_in_the_cell(capsys):
    """link6 carries the flange with no joint between: the sensor is on the tool, as with --sensor-link flange
    (it had been refused naming 'flange' as not moved against 'link6')."""
    outs = []
    for link in ("link6", "flange"):
        code, out, err = run(capsys, "jacobian", "--robot", FANUC, "--sensor-link", link, "--joints", ZEROS, "--json")
        assert code == 0, err
        assert f"the sensor on {link!r} measures a marker on 'base_link' (fixed in the cell): 6 joints" in err
        outs.append(json.loads(out))
    assert outs[0]["joint_names"] == outs[1]["joint_names"]
    code, _, err = run(capsys, "jacobian", "--robot", FANUC, "--sensor-link", "link3", "--tip-link", "base_link",
                       "--joints", "0rad,0rad,0rad")
    assert code == 0 and "measures a marker on 'base_link' (fixed in the cell): 3 joints" in err


def test_a_xacro_given_as_robot_is_named_with_the_command_that_expands_it(capsys, tmp_path):
    text = ('<?xml version="1.0"?>\n<robot name="r" xmlns:xacro="http://www.ros.org/wiki/xacro">\n'
            '  <xacro:property name="l" value="0.3"/>\n  <link name="a"/>\n</robot>\n')
    for name in ("arm.urdf.xacro", "arm.xml"):
        (tmp_path / name).write_text(text)
        code, _, err = run(capsys, "jacobian", "--robot", tmp_path / name, "--joints", "0rad")
        line = one_line(err)
        assert code == 2 and "a xacro file (URDF macros), not a URDF: expand it first" in line, line
        assert f"`xacro {tmp_path / name} > arm.urdf`" in line and "mapping" not in line
    (tmp_path / "fanuc.xml").write_text(FANUC.read_text())          # a URDF by its content, whatever its suffix
    code, _, err = run(capsys, "jacobian", "--robot", tmp_path / "fanuc.xml", "--joints", ZEROS)
    assert code == 0, err


def test_the_tip_link_notice_only_where_other_leaves_were_passed_over(capsys, tmp_path):
    code, _, err = run(capsys, "jacobian", "--robot", FANUC, "--joints", ZEROS)
    assert code == 0 and "tip link" not in err                      # the flange is the URDF's only leaf
    text = FANUC.read_text().replace("</robot>", '<link name="camera"/><joint name="camera_mount" type="fixed">'
                                     '<parent link="base_link"/><child link="camera"/></joint></robot>')
    (tmp_path / "with_camera.urdf").write_text(text)
    code, _, err = run(capsys, "jacobian", "--robot", tmp_path / "with_camera.urdf", "--joints", ZEROS)
    assert code == 0 and "tip link 'flange', the only leaf link the joints move (besides 'camera'" in err


def test_a_tip_link_short_of_the_measured_point_is_said(capsys, fanuc, tmp_path):
    """--tip-link link5 leaves the joint_6 column unused while it moves: with the orientations measured the
    refusal names it first (not 'degrees labelled radians'); with points (joint_6 turns the flange about its own
    point) and the flange's offset fitted, report and calibrate say so."""
    for argv in (["report"], ["calibrate", "--out", tmp_path / "c"]):
        code, _, err = run(capsys, argv[0], "--robot", FANUC, "--tip-link", "link5", "--measurements",
                           fanuc / "m.csv", *argv[1:], "--quiet")
        line = one_line(err)
        assert code == 2 and "joint column(s) joint_6 move links past the tip link 'link5'" in line, line
        assert line.index("joint_6") < line.index("units:")
    lines = (fanuc / "m.csv").read_text().splitlines()
    head = next(i for i, line in enumerate(lines) if line.startswith("stamp"))
    keep = [k for k, h in enumerate(lines[head].split(",")) if h.split("[")[0] not in ("roll", "pitch", "yaw")]
    points = tmp_path / "points.csv"
    points.write_text("\n".join(lines[:head] + [",".join(line.split(",")[k] for k in keep)
                                                for line in lines[head:]]) + "\n")
    code, out, err = run(capsys, "report", "--robot", FANUC, "--tip-link", "link5", "--measurements", points,
                         "--registration", "base+tool", "--json", "--quiet")   # the flange 215 mm past link5
    doc = json.loads(out)
    assert any("joint_6 move links past the tip link 'link5'" in n and "is --tip-link right?" in n
               for n in doc["notes"]), doc["notes"]
    code, out, err = run(capsys, "calibrate", "--robot", FANUC, "--tip-link", "link5", "--measurements", points,
                         "--registration", "base+tool", "--folds", "3", "--out", tmp_path / "c2", "--json", "--quiet")
    assert any("joint_6 move links past the tip link" in w for w in json.loads(out)["warnings"])
    code, out, _ = run(capsys, "report", "--robot", FANUC, "--measurements", points, "--json", "--quiet")
    assert not any("joint column" in n for n in json.loads(out)["notes"])     # the whole chain: nothing unused


def _rewritten(src, dst, line_of_data, column, value):
    lines = src.read_text().splitlines()
    head = next(i for i, line in enumerate(lines) if line.startswith("stamp"))
    row = lines[head + line_of_data].split(",")
    row[column] = value
    lines[head + line_of_data] = ",".join(row)
    dst.write_text("\n".join(lines) + "\n")
    return dst, head + line_of_data + 1


def test_a_coordinate_of_1e308_is_refused_naming_its_line_without_numpy_warnings(capsys, fanuc, tmp_path):
    path, line = _rewritten(fanuc / "m.csv", tmp_path / "far.csv", 5, 3, "1e308")
    for argv in (["report"], ["calibrate", "--out", tmp_path / "c"]):
        code, _, err = run(capsys, argv[0], "--robot", FANUC, "--measurements", path, *argv[1:], "--quiet")
        assert code == 2 and f"far.csv, line {line}: x: '1e308' lies 1e+305 m from the tracker's origin" in \
            one_line(err)
    code, out, err = run(capsys, "report", "--robot", FANUC, "--measurements", path, "--skip-bad", "--json",
                         "--quiet")
    assert json.loads(out)["skipped_rows"][0]["line"] == line


def test_header_only_streams_and_far_targets_are_one_line(capsys, tmp_path):
    """A header-only joint-states or tracker file, a tool target 1e300 mm away, a target offset and a contact
    plane as far: one line each, no numpy warning before it."""
    (tmp_path / "joints.csv").write_text("stamp[s],joint:joint1[rad],joint:joint2[rad],joint:joint3[rad],"
                                         "joint:joint4[rad],joint:joint5[rad],joint:joint6[rad],joint:joint7[rad]\n")
    (tmp_path / "points.csv").write_text("stamp[s],x[mm],y[mm],z[mm]\n")
    code, _, err = run(capsys, "path-report", "--robot", "gao2023_7dof", "--measurements", tmp_path / "points.csv",
                       "--joint-states", tmp_path / "joints.csv")
    assert code == 2 and "no measurements" in one_line(err)
    (tmp_path / "far.yaml").write_text("name: far\nunits: {length: mm, angle: deg}\nposes:\n"
                                       "- {name: T1, pose: {xyz: [1e300, 0, 0], rpy: [0, 0, 0]}}\n")
    code, _, err = run(capsys, "compensate", "--robot", "gao2023_7dof", "--calibration", "x.yaml", "--poses",
                       tmp_path / "far.yaml")
    assert code == 2 and one_line(err)     # the missing calibration first; the campaign's own refusal below
    from tolerance_ros.core.campaign import CampaignError, load_campaign
    with pytest.raises(CampaignError, match=r"poses\[0\]\.pose\.xyz\[0\]: 1e\+300 lies beyond 1e\+06 m"):
        load_campaign(tmp_path / "far.yaml")
    code, _, err = run(capsys, "simulate", "--robot", "gao2023_7dof", "--tolerances", "gao2023_delta2", "--campaign",
                       "gao2023_iso_cube", "--target-offset", "A=1e300mm,0mm,0mm", "--out", tmp_path / "s.csv")
    assert code == 2 and "--target-offset: 1e300mm lies beyond 1e+06 m" in one_line(err)
    code, _, err = run(capsys, "plan-campaign", "--robot", "gao2023_7dof", "--contact", "plane:a=0,0,1@1e300mm",
                       "--target", "A=0mm,0mm,0mm", "--n", "10", "--candidates", "100")
    assert code == 2 and "offset 1e300mm lies beyond 1e+06 m" in one_line(err)


def test_a_refusal_drops_what_numpy_said_on_the_way_and_a_success_keeps_it(capsys, monkeypatch):
    import warnings
    from tolerance_ros.cli import jacobian
    real = jacobian.run

    def noisy(args, fail):
        warnings.warn("overflow encountered in square", RuntimeWarning)
        if fail:
            from tolerance_ros.cli.common import CLIError
            raise CLIError("--joints: a refusal")
        return real(args)
    for fail in (True, False):
        monkeypatch.setattr(jacobian, "run", lambda args, fail=fail: noisy(args, fail))
        with warnings.catch_warnings(record=True) as shown:    # what the command passes on to the user
            warnings.simplefilter("always")
            code, _, err = run(capsys, "jacobian", "--robot", "gao2023_7dof", "--joints",
                               "0rad,0rad,0rad,0rad,0rad,0rad,0rad")
        said = [str(w.message) for w in shown if issubclass(w.category, RuntimeWarning)]
        if fail:
            assert code == 2 and one_line(err) == "tolerance-ros jacobian: error: --joints: a refusal"
            assert said == []
        else:
            assert code == 0 and said == ["overflow encountered in square"]
