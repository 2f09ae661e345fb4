"""The ISO 9283 test report from the command line: plan-campaign --iso9283 --approach, simulate --backlash /
--thermal, iso9283 --out; its figures equal report's and path-report's for the same data."""
import json
import re

import numpy as np
import pytest
import yaml

from helpers import run_cli as run

ROBOT = "gao2023_7dof"
TOL = "uniform:0.05mm,0.2mrad"


def cli(capsys, *argv):
    code, out, err = run(capsys, *argv, "--quiet")
    assert code == 0, err
    return out


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    d = tmp_path_factory.mktemp("iso")
    from tolerance_ros.cli import main
    assert main(["plan-campaign", "--robot", ROBOT, "--iso9283", "--approach", "80mm", "--cycles", "10", "--out",
                 str(d / "iso.yaml"), "--quiet"]) == 0
    return d / "iso.yaml"


def test_the_planner_writes_each_test_pose_approached_along_three_axes(campaign):
    from tolerance_ros.core.campaign import load_campaign
    from tolerance_ros.core.models import load_robot
    model = load_robot(ROBOT)
    camp = load_campaign(campaign, model)
    assert camp.approaches() == {f"P{k}": [f"P{k}+x", f"P{k}+y", f"P{k}+z"] for k in range(1, 6)}
    by = {p.name: p for p in camp.poses}
    for k in range(1, 6):
        T = model.fk(np.array([by[f"P{k}"].joints] + [by[f"P{k}{d}"].via for d in ("+x", "+y", "+z")]))
        step = T[1:, :3, 3] - T[0, :3, 3]                      # each pre-pose 80 mm before the pose along its axis
        assert np.allclose(step, -0.08 * np.eye(3), atol=1e-6)
        assert np.allclose(T[1:, :3, :3], T[0, :3, :3], atol=1e-6)


def test_the_report_from_a_robot_with_backlash(capsys, tmp_path, campaign):
    cli(capsys, "simulate", "--robot", ROBOT, "--campaign", campaign, "--tolerances", TOL, "--backlash", "0.5mrad",
        "--out", tmp_path / "m.csv")
    doc = json.loads(cli(capsys, "iso9283", "--robot", ROBOT, "--campaign", campaign, "--measurements",
                         tmp_path / "m.csv", "--temperature", "20.5 C", "--out", tmp_path / "rep", "--json"))
    # backlash shows where an approach reverses a joint: at four of the five poses of the cube's configuration
    assert sum(doc["multidirectional"][f"P{k}"]["vAP_p"] > 0.02e-3 for k in range(1, 6)) >= 4
    assert doc["distance"]["between"] == ["P2", "P4"] and doc["distance"]["n"] == 10
    assert doc["conditions"]["temperature"] == "20.5 C" and doc["conditions"]["cycles"] == 10
    for f in ("report.md", "report.html", "iso9283.json", "vap.png"):
        assert (tmp_path / "rep" / f).is_file()
    md = (tmp_path / "rep" / "report.md").read_text()
    html = (tmp_path / "rep" / "report.html").read_text()
    v = doc["multidirectional"]["P3"]["vAP_p"]
    assert f"{v * 1e3:.4f}" in md and f"{v * 1e3:.4f}" in html
    # the same figures as report --campaign for the same data
    rep = json.loads(cli(capsys, "report", "--robot", ROBOT, "--campaign", campaign, "--measurements",
                         tmp_path / "m.csv", "--json"))
    for pose, v in doc["pose"].items():
        assert v["AP_p"] == rep["per_pose"][pose]["AP_p"] and v["RP_l"] == rep["per_pose"][pose]["RP_l"]
    printed = cli(capsys, "iso9283", "--robot", ROBOT, "--campaign", campaign, "--measurements", tmp_path / "m.csv")
    assert f"{doc['distance']['AD_p'] * 1e3:.4f}" in printed and "Not in this report" in printed
    # without backlash, the approaches agree to the noise
    cli(capsys, "simulate", "--robot", ROBOT, "--campaign", campaign, "--tolerances", TOL, "--out", tmp_path / "n.csv")
    flat = json.loads(cli(capsys, "iso9283", "--robot", ROBOT, "--campaign", campaign, "--measurements",
                          tmp_path / "n.csv", "--json"))
    assert max(flat["multidirectional"][f"P{k}"]["vAP_p"] for k in range(1, 6)) < 0.02e-3


def test_drift_and_exchangeability_and_the_path_in_one_report(capsys, tmp_path):
    cli(capsys, "plan-campaign", "--robot", ROBOT, "--iso9283", "--out", tmp_path / "cube.yaml")
    for seed, thermal in ((0, ["--thermal", "200ppm,2h"]), (1, [])):
        cli(capsys, "simulate", "--robot", ROBOT, "--campaign", tmp_path / "cube.yaml", "--cycles", "600",
            "--tolerances", TOL, "--seed", seed, "--out", tmp_path / f"r{seed}.csv", *thermal)
    cli(capsys, "plan-campaign", "--robot", ROBOT, "--path", "line", "--cycles", "3", "--out", tmp_path / "line.yaml")
    cli(capsys, "simulate", "--robot", ROBOT, "--trajectory", tmp_path / "line.yaml", "--tolerances", TOL,
        "--settling", "8Hz,0.2", "--out", tmp_path / "s.csv")
    truth = yaml.safe_load((tmp_path / "r0.truth.yaml").read_text())
    assert "warming up 200ppm,2h" in json.dumps(truth)
    argv = ["iso9283", "--robot", ROBOT, "--campaign", tmp_path / "cube.yaml", "--drift-window", "10min"]
    doc = json.loads(cli(capsys, *argv, "--measurements", tmp_path / "r0.csv", "--other", tmp_path / "r1.csv",
                         "--stream", tmp_path / "s.csv", "--joint-states", tmp_path / "s.joints.csv", "--latency",
                         "8ms", "--json"))
    cold = json.loads(cli(capsys, *argv, "--measurements", tmp_path / "r1.csv", "--json"))
    assert len(doc["drift"]["P1"]["windows"]) == 10                  # 600 cycles of 5 poses, 2 s each: 100 min
    assert all(doc["drift"][p]["dAP_p"] > 5 * cold["drift"][p]["dAP_p"] for p in doc["drift"])
    assert set(doc["exchangeability"]) == {"P1", "P2", "P3", "P4", "P5", "sources"}
    path = json.loads(cli(capsys, "path-report", "--robot", ROBOT, "--measurements", tmp_path / "s.csv",
                          "--joint-states", tmp_path / "s.joints.csv", "--latency", "8ms", "--json"))
    assert doc["path"]["overall"]["AT_p_m"] == path["overall"]["AT_p_m"]
    assert doc["path"]["stops"] == path["stops"] and path["stops"]["judged"] == 6      # 3 cycles out and back
    assert 0.05 < path["stops"]["stabilisation_time_s"]["mean"] < 0.15                # an 8 Hz robot ringing
    (move,) = path["stops"]["positioning"]                                             # one distance: the stroke
    assert move["moves"] == 6 and move["min_s"] > move["distance_m"] / 0.1
    missing = {m["characteristic"] for m in doc["missing"]}
    assert not missing & {"E (exchangeability)", "AT, RT, CR, CO, AV, RV, FV (path)",
                          "pose stabilisation time, pose overshoot, minimum positioning time"}


@pytest.mark.parametrize("argv, message", [
    (["--distance", "P2"], "--distance: expected two different test poses"),
    (["--distance", "P2,P9"], r"\['P9'\] are not in campaign"),
    (["--drift-window", "3600"], "--drift-window"),
    (["--drift-window", "1e-300s"], "--drift-window: expected 1s to 720h"),
    (["--joint-states", "x.csv"], "go with --stream"),
    (["--latency", "8ms"], "--latency: goes with --stream or --reorientation"),
    (["--reorientation", "x.csv"], "give --reorientation-joints"),
    (["--reorientation-joints", "x.csv"], "goes with --reorientation"),
])
def test_bad_options_are_refused(capsys, tmp_path, campaign, argv, message):
    cli(capsys, "simulate", "--robot", ROBOT, "--campaign", campaign, "--tolerances", TOL, "--out", tmp_path / "m.csv")
    code, out, err = run(capsys, "iso9283", "--robot", ROBOT, "--campaign", campaign, "--measurements",
                         tmp_path / "m.csv", *argv)
    assert code == 2 and re.search(message, err), err


def test_a_campaign_without_pose_names_is_refused(capsys, tmp_path, campaign):
    cli(capsys, "simulate", "--robot", ROBOT, "--campaign", campaign, "--tolerances", TOL, "--out", tmp_path / "m.csv")
    lines = (tmp_path / "m.csv").read_text().splitlines()
    head = [i for i, l in enumerate(lines) if not l.startswith("#")][0]
    cols = lines[head].split(",")
    k = cols.index("pose")
    rows = [",".join(c for j, c in enumerate(l.split(",")) if j != k) for l in lines[head:]]
    (tmp_path / "u.csv").write_text("\n".join(rows) + "\n")
    code, out, err = run(capsys, "iso9283", "--robot", ROBOT, "--campaign", campaign, "--measurements",
                         tmp_path / "u.csv")
    assert code == 2 and "no pose column" in err, err


def test_simulate_refuses_bad_backlash_thermal_and_settling(capsys, tmp_path, campaign):
    for argv, message in ((["--backlash", "1rad"], "--backlash"), (["--thermal", "100,1h"], "ppm"),
                          (["--cycles", "0"], "--cycles"), (["--settling", "8Hz,0.2"], "with --trajectory only")):
        code, out, err = run(capsys, "simulate", "--robot", ROBOT, "--campaign", campaign, "--tolerances", TOL,
                             "--out", tmp_path / "m.csv", *argv)
        assert code == 2 and message in err, err


def test_simulate_refuses_options_of_another_mode(capsys, tmp_path):
    code, _, err = run(capsys, "plan-campaign", "--robot", ROBOT, "--path", "line", "--cycles", "1", "--out",
                       tmp_path / "line.yaml")
    assert code == 0, err
    for argv, message in ((["--backlash", "1mrad"], "--backlash: with --campaign only"),
                          (["--thermal", "100ppm,1h"], "--thermal: with --campaign only"),
                          (["--settling", "8Hz"], "FREQUENCY,DAMPING")):
        code, out, err = run(capsys, "simulate", "--robot", ROBOT, "--trajectory", tmp_path / "line.yaml",
                             "--tolerances", TOL, "--out", tmp_path / "s.csv", *argv)
        assert code == 2 and message in err, err


def test_static_compliance_from_visits_under_load(capsys, tmp_path):
    cli(capsys, "plan-campaign", "--robot", ROBOT, "--iso9283", "--cycles", "2", "--out", tmp_path / "cube.yaml")
    for name, stiffness in (("soft", "20kNm/rad"), ("stiff", "80kNm/rad")):
        cli(capsys, "simulate", "--robot", ROBOT, "--campaign", tmp_path / "cube.yaml", "--tolerances", TOL, "--load",
            "200N", "--torque", "20Nm", "--joint-stiffness", stiffness, "--out", tmp_path / f"{name}.csv")
    soft, stiff = (json.loads(cli(capsys, "iso9283", "--robot", ROBOT, "--campaign", tmp_path / "cube.yaml",
                                  "--measurements", tmp_path / f"{n}.csv", "--json")) for n in ("soft", "stiff"))
    assert "loads of 200N and 20Nm on joints of 20kNm/rad" in json.dumps(yaml.safe_load(
        (tmp_path / "soft.truth.yaml").read_text()))
    for pose in ("P1", "P2", "P3", "P4", "P5"):
        c, k = soft["compliance"][pose]["compliance_m_per_N"], stiff["compliance"][pose]
        turn, kturn = soft["compliance"][pose]["compliance_rad_per_Nm"], k["compliance_rad_per_Nm"]
        for a in "xyz":          # four times as stiff, a quarter of the compliance (within the noise)
            assert k["compliance_m_per_N"][a] == pytest.approx(c[a] / 4, rel=0.1, abs=2e-8)
            assert kturn[a] == pytest.approx(turn[a] / 4, rel=0.1, abs=2e-7)
        assert soft["pose"][pose]["n"] == 2
    lines = (tmp_path / "stiff.csv").read_text().splitlines()       # the loads along +x, +y, +z only: not even
    push = [l for l in lines if l.startswith(("#", "stamp")) or min(map(float, l.split(",")[-6:])) >= 0]
    (tmp_path / "push.csv").write_text("\n".join(push) + "\n")
    both = json.loads(cli(capsys, "iso9283", "--robot", ROBOT, "--campaign", tmp_path / "cube.yaml",
                          "--measurements", tmp_path / "soft.csv", "--other", tmp_path / "push.csv", "--json"))
    # one as-built robot (seed 0, the same noise) twice: its unloaded visits agree; with the loaded ones pushing
    # one way, the other robot's barycentres moved by 25 to 47 um
    assert max(both["exchangeability"][p]["E"] for p in ("P1", "P2", "P3", "P4", "P5")) < 5e-6
    printed = cli(capsys, "report", "--robot", ROBOT, "--campaign", tmp_path / "cube.yaml", "--measurements",
                  tmp_path / "soft.csv")
    assert "NOTE: 120 measurement(s) were taken under a load at the tool" in printed     # 5 poses x 2 x 12 loads
    code, out, err = run(capsys, "simulate", "--robot", ROBOT, "--campaign", tmp_path / "cube.yaml", "--tolerances",
                         TOL, "--load", "200", "--out", tmp_path / "x.csv")
    assert code == 2 and "--load" in err and "has no unit" in err, err


def test_weaving_deviations_from_a_woven_path(capsys, tmp_path):
    cli(capsys, "plan-campaign", "--robot", ROBOT, "--path", "weave", "--stroke", "8mm", "--pitch", "15mm", "--cycles",
        "2", "--out", tmp_path / "weave.yaml")
    cli(capsys, "simulate", "--robot", ROBOT, "--trajectory", tmp_path / "weave.yaml", "--tolerances", TOL,
        "--settling", "8Hz,0.2", "--out", tmp_path / "w.csv")
    path = json.loads(cli(capsys, "path-report", "--robot", ROBOT, "--measurements", tmp_path / "w.csv",
                          "--joint-states", tmp_path / "w.joints.csv", "--latency", "8ms", "--json"))
    w = path["weaving"]
    assert w["S_c_m"] == pytest.approx(0.008, rel=0.02) and w["WS"] > 0.02 and abs(w["WF"]) < 0.01
    printed = cli(capsys, "path-report", "--robot", ROBOT, "--measurements", tmp_path / "w.csv", "--joint-states",
                  tmp_path / "w.joints.csv", "--latency", "8ms")
    assert f"(WS {w['WS'] * 100:+.2f} %)" in printed
    cli(capsys, "plan-campaign", "--robot", ROBOT, "--iso9283", "--cycles", "3", "--out", tmp_path / "cube.yaml")
    cli(capsys, "simulate", "--robot", ROBOT, "--campaign", tmp_path / "cube.yaml", "--tolerances", TOL, "--out",
        tmp_path / "m.csv")
    doc = json.loads(cli(capsys, "iso9283", "--robot", ROBOT, "--campaign", tmp_path / "cube.yaml", "--measurements",
                         tmp_path / "m.csv", "--stream", tmp_path / "w.csv", "--joint-states", tmp_path / "w.joints.csv",
                         "--latency", "8ms", "--json"))
    assert doc["path"]["weaving"] == w
    assert "WS, WF (weaving deviations)" not in {m["characteristic"] for m in doc["missing"]}
    code, _, err = run(capsys, "plan-campaign", "--robot", ROBOT, "--path", "line", "--stroke", "8mm")
    assert code == 2 and "--stroke, --pitch: go with --path weave" in err


def test_path_accuracy_on_reorientation_in_the_campaigns_registration(capsys, tmp_path):
    cli(capsys, "plan-campaign", "--robot", ROBOT, "--iso9283", "--cycles", "3", "--out", tmp_path / "cube.yaml")
    cli(capsys, "simulate", "--robot", ROBOT, "--campaign", tmp_path / "cube.yaml", "--tolerances", TOL, "--out",
        tmp_path / "m.csv")
    cli(capsys, "plan-campaign", "--robot", ROBOT, "--path", "reorient", "--angle", "20deg", "--cycles", "2", "--out",
        tmp_path / "reo.yaml")
    cli(capsys, "simulate", "--robot", ROBOT, "--trajectory", tmp_path / "reo.yaml", "--tolerances", TOL, "--out",
        tmp_path / "r.csv")
    from tolerance_ros.core.accuracy.io import read_measurements
    assert read_measurements(tmp_path / "r.csv").has_orientation          # a 6-DOF tracker's frames
    doc = json.loads(cli(capsys, "iso9283", "--robot", ROBOT, "--campaign", tmp_path / "cube.yaml", "--measurements",
                         tmp_path / "m.csv", "--reorientation", tmp_path / "r.csv", "--reorientation-joints",
                         tmp_path / "r.joints.csv", "--latency", "8ms", "--json"))
    r = doc["reorientation"]
    assert r["cycles"] == 2 and r["turn_rad"] == pytest.approx(np.radians(40), rel=1e-6)
    assert 1e-6 < r["AT_p_m"] < 0.5e-3 and r["excursion_m"] >= r["AT_p_m"]   # the point moves as the robot is built
    assert "path accuracy on reorientation" not in {m["characteristic"] for m in doc["missing"]}
    points = cli(capsys, "simulate", "--robot", ROBOT, "--campaign", tmp_path / "cube.yaml", "--tolerances", TOL,
                 "--target-offset", "A=0mm,0mm,50mm", "--out", tmp_path / "p.csv")
    assert "wrote" in points
    code, _, err = run(capsys, "iso9283", "--robot", ROBOT, "--campaign", tmp_path / "cube.yaml", "--measurements",
                       tmp_path / "m.csv", "--reorientation", tmp_path / "p.csv", "--reorientation-joints",
                       tmp_path / "r.joints.csv", "--latency", "8ms")
    assert code == 2 and "no orientation columns" in err, err


def test_minimum_positioning_time_over_the_programs_distances(capsys, tmp_path):
    cli(capsys, "plan-campaign", "--robot", ROBOT, "--path", "positioning", "--distances", "10mm,40mm", "--speed",
        "0.5m/s", "--accel", "5m/s^2", "--cycles", "2", "--out", tmp_path / "pos.yaml")
    cli(capsys, "simulate", "--robot", ROBOT, "--trajectory", tmp_path / "pos.yaml", "--tolerances", TOL, "--out",
        tmp_path / "p.csv")
    path = json.loads(cli(capsys, "path-report", "--robot", ROBOT, "--measurements", tmp_path / "p.csv",
                          "--joint-states", tmp_path / "p.joints.csv", "--latency", "8ms", "--json"))
    groups = path["stops"]["positioning"]
    assert [round(g["distance_m"], 6) for g in groups] == [0.01, 0.04] and [g["moves"] for g in groups] == [4, 4]
    for g in groups:                  # a robot that follows its command: the move's own time, out and back
        d, v, a = g["distance_m"], 0.5, 5.0
        move = 2 * np.sqrt(d / a) if d < v * v / a else d / v + v / a
        assert abs(g["min_s"] - move) <= 2.5e-3 and abs(g["mean_s"] - move) <= 2.5e-3
    code, _, err = run(capsys, "plan-campaign", "--robot", ROBOT, "--path", "positioning", "--distances", "5m")
    assert code == 2 and "positioning: expected distances up to" in err, err


def test_a_rosbag2_recording_streams_into_the_report_as_into_path_report(capsys, tmp_path):
    from tolerance_ros.core.accuracy.io.joint_states import read_joint_states, read_points
    from tolerance_ros.core.accuracy.io.rosbag import write_rosbag_streams
    from tolerance_ros.core.models import load_robot
    gao = load_robot(ROBOT)
    cli(capsys, "plan-campaign", "--robot", ROBOT, "--iso9283", "--cycles", "3", "--out", tmp_path / "cube.yaml")
    cli(capsys, "simulate", "--robot", ROBOT, "--campaign", tmp_path / "cube.yaml", "--tolerances", TOL, "--out",
        tmp_path / "m.csv")
    cli(capsys, "plan-campaign", "--robot", ROBOT, "--path", "line", "--cycles", "2", "--out", tmp_path / "line.yaml")
    cli(capsys, "simulate", "--robot", ROBOT, "--trajectory", tmp_path / "line.yaml", "--tolerances", TOL, "--out",
        tmp_path / "s.csv")
    stamps, points, _ = read_points(tmp_path / "s.csv")
    tj, qj = read_joint_states(tmp_path / "s.joints.csv", gao.joint_names, gao.joint_types)
    write_rosbag_streams(tmp_path / "bag", stamps, points, tj, qj, gao.joint_names)
    doc = json.loads(cli(capsys, "iso9283", "--robot", ROBOT, "--campaign", tmp_path / "cube.yaml", "--measurements",
                         tmp_path / "m.csv", "--stream", tmp_path / "bag", "--json"))
    path = json.loads(cli(capsys, "path-report", "--robot", ROBOT, "--measurements", tmp_path / "bag", "--json"))
    assert doc["path"]["overall"]["AT_p_m"] == path["overall"]["AT_p_m"] and doc["path"]["cycles"] == 2


def test_every_report_says_where_its_base_frame_comes_from(capsys, tmp_path):
    """The frame (issue 47): fitted on the test poses by default, said with the word 'lower bound' and the count of
    coordinates absorbed; --registration-from a calibration of the same set-up gives AP within 10 % + 10 um of the
    truth in the frame any measurement of the robot can find (here the simulated truth file itself: the mounting
    frame, noise-free data); --registration-poses fits on other poses; tracker-frame data with --registration none
    is refused; so is a registration measurement of the test poses themselves."""
    from tolerance_ros.core.accuracy.io import read_measurements
    from tolerance_ros.core.accuracy.iso9283 import pose_characteristics
    from tolerance_ros.core.calibration.calibration_file import load_calibration
    from tolerance_ros.core.campaign import load_campaign
    from tolerance_ros.core.models import load_robot
    model = load_robot(ROBOT)
    cli(capsys, "plan-campaign", "--robot", ROBOT, "--iso9283", "--cycles", "5", "--out", tmp_path / "cube.yaml")
    cli(capsys, "plan-campaign", "--robot", ROBOT, "--n", "20", "--out", tmp_path / "cal.yaml")
    sim = ("simulate", "--robot", ROBOT, "--tolerances", "uniform:0.1mm,0.5mrad", "--seed", "3")
    cli(capsys, *sim, "--campaign", tmp_path / "cube.yaml", "--noise", "0um", "--orientation-noise", "0rad",
        "--out", tmp_path / "iso.csv")
    cli(capsys, *sim, "--campaign", tmp_path / "cal.yaml", "--out", tmp_path / "cal.csv")
    iso = ("iso9283", "--robot", ROBOT, "--campaign", tmp_path / "cube.yaml", "--measurements", tmp_path / "iso.csv")
    fitted = json.loads(cli(capsys, *iso, "--json", "--out", tmp_path / "rep"))
    f = fitted["frame"]
    assert f["source"] == "test poses" and f["lower_bound"] and (f["absorbed"], f["coordinates"]) == (6, 30)
    md = (tmp_path / "rep" / "report.md").read_text()
    assert "fitted on the test poses" in md and "lower bound" in md and "6 of the 30 coordinates" in md
    assert "lower bound" in (tmp_path / "rep" / "report.html").read_text()
    truth = load_calibration(tmp_path / "iso.truth.yaml", model)
    given = json.loads(cli(capsys, *iso, "--registration-from", tmp_path / "iso.truth.yaml", "--json"))
    assert given["frame"]["source"] == "calibration" and not given["frame"]["lower_bound"]
    m = read_measurements(tmp_path / "iso.csv", joint_names=model.joint_names)
    cube = load_campaign(tmp_path / "cube.yaml", model)
    T = np.linalg.inv(truth.T_tracker_base) @ m.T
    for p, qp in zip(cube.names, model.fk(cube.joints_for(model))):
        expect = pose_characteristics(qp, T[m.pose == p], True).AP_p
        assert abs(given["pose"][p]["AP_p"] - expect) <= 0.1 * expect + 1e-5
    assert max(given["pose"][p]["AP_p"] - fitted["pose"][p]["AP_p"] for p in cube.names) > 0.1e-3  # flattered
    printed = cli(capsys, *iso, "--registration-from", tmp_path / "iso.truth.yaml")
    assert "base frame: the tracker placement and base correction of the calibration" in printed
    other = json.loads(cli(capsys, *iso, "--registration-poses", tmp_path / "cal.csv", "--json"))
    assert other["frame"]["source"] == "poses" and "apart from the test poses" in other["frame"]["words"]
    code, _, err = run(capsys, *iso, "--registration-poses", tmp_path / "iso.csv")
    assert code == 2 and "every pose of the registration measurement is a test pose" in err
    code, _, err = run(capsys, *iso, "--registration", "none")
    assert code == 2 and "not in the robot's base frame" in err
    code, _, err = run(capsys, *iso, "--registration", "none", "--registration-from", tmp_path / "iso.truth.yaml")
    assert code == 2 and "one source of the base frame" in err


def test_the_path_figures_of_a_stream_alone(capsys, tmp_path):
    """iso9283 --stream without a campaign (issue 47): the path figures and the stops, every pose characteristic
    named missing with what it needs; the campaign without its measurements, or --other without them, refused."""
    cli(capsys, "plan-campaign", "--robot", ROBOT, "--path", "line", "--cycles", "3", "--out", tmp_path / "line.yaml")
    cli(capsys, "simulate", "--robot", ROBOT, "--trajectory", tmp_path / "line.yaml", "--tolerances", TOL, "--out",
        tmp_path / "s.csv")
    argv = ("iso9283", "--robot", ROBOT, "--stream", tmp_path / "s.csv", "--joint-states", tmp_path / "s.joints.csv")
    doc = json.loads(cli(capsys, *argv, "--json", "--out", tmp_path / "rep"))
    path = json.loads(cli(capsys, "path-report", "--robot", ROBOT, "--measurements", tmp_path / "s.csv",
                          "--joint-states", tmp_path / "s.joints.csv", "--json"))
    assert doc["campaign"] is None and doc["pose"] == {} and doc["frame"]["source"] == "stream"
    assert doc["path"]["overall"]["AT_p_m"] == path["overall"]["AT_p_m"]
    missing = {m["characteristic"]: m["needs"] for m in doc["missing"]}
    assert "--campaign, --measurements" in missing["AP, RP (pose accuracy and repeatability)"]
    assert "the stream" in (tmp_path / "rep" / "report.md").read_text().splitlines()[0]
    for extra, message in ((["--campaign", tmp_path / "line.yaml"], "give both"),
                           (["--other", tmp_path / "s.csv"], "--other: goes with the campaign")):
        code, _, err = run(capsys, *argv, *extra)
        assert code == 2 and message in err
    code, _, err = run(capsys, "iso9283", "--robot", ROBOT)
    assert code == 2 and "nothing to report" in err


def test_every_iso_input_is_checked_like_reports(capsys, tmp_path):
    """Issue 47: loads in N labelled kN, the robot's own file as --other, the joint states of another path as a
    reorientation's, and an output named like an input are each refused (exit 2) naming the cause."""
    cli(capsys, "plan-campaign", "--robot", ROBOT, "--iso9283", "--cycles", "2", "--out", tmp_path / "cube.yaml")
    cli(capsys, "simulate", "--robot", ROBOT, "--campaign", tmp_path / "cube.yaml", "--tolerances", TOL, "--load",
        "200N", "--out", tmp_path / "loaded.csv")
    text = (tmp_path / "loaded.csv").read_text()
    assert "load:fx[N]" in text
    (tmp_path / "kn.csv").write_text(text.replace("load:fx[N]", "load:fx[kN]").replace("load:fy[N]", "load:fy[kN]")
                                     .replace("load:fz[N]", "load:fz[kN]"))
    iso = ("iso9283", "--robot", ROBOT, "--campaign", tmp_path / "cube.yaml")
    code, _, err = run(capsys, *iso, "--measurements", tmp_path / "kn.csv")
    assert code == 2 and "beyond any robot's payload" in err and "N labelled kN?" in err
    code, _, err = run(capsys, *iso, "--measurements", tmp_path / "loaded.csv", "--other", tmp_path / "loaded.csv")
    assert code == 2 and "the same measurements as" in err
    (tmp_path / "copy.csv").write_text(text)
    code, _, err = run(capsys, *iso, "--measurements", tmp_path / "loaded.csv", "--other", tmp_path / "copy.csv")
    assert code == 2 and "--other" in err and "the same measurements" in err
    for kind in ("line", "reorient"):
        cli(capsys, "plan-campaign", "--robot", ROBOT, "--path", kind, "--cycles", "2", "--out", tmp_path / "p.yaml")
        cli(capsys, "simulate", "--robot", ROBOT, "--trajectory", tmp_path / "p.yaml", "--tolerances", TOL, "--out",
            tmp_path / f"{kind}.csv")
    code, _, err = run(capsys, *iso, "--measurements", tmp_path / "loaded.csv", "--reorientation",
                       tmp_path / "reorient.csv", "--reorientation-joints", tmp_path / "line.joints.csv", "--latency",
                       "8ms")
    assert code == 2 and "the joint states of another path?" in err, err
    (tmp_path / "rep").mkdir()
    (tmp_path / "rep" / "report.html").write_text(text)
    code, _, err = run(capsys, *iso, "--measurements", tmp_path / "rep" / "report.html", "--out", tmp_path / "rep")
    assert code == 2 and "would write report.html over the input --measurements" in err
    assert (tmp_path / "rep" / "report.html").read_text() == text


def test_orientations_in_degrees_labelled_radians_are_refused_where_the_tool_hardly_turns(capsys, tmp_path):
    """The ISO cube's poses share one orientation, so their turns from one measurement to the next show nothing;
    after the registration, orientations read in the wrong unit lie radians from the robot's: refused (exit 2) by
    iso9283 and report alike."""
    cli(capsys, "plan-campaign", "--robot", ROBOT, "--iso9283", "--cycles", "3", "--out", tmp_path / "cube.yaml")
    cli(capsys, "simulate", "--robot", ROBOT, "--campaign", tmp_path / "cube.yaml", "--tolerances", TOL, "--out",
        tmp_path / "m.csv")
    text = (tmp_path / "m.csv").read_text()
    assert "roll[deg],pitch[deg],yaw[deg]" in text
    (tmp_path / "rad.csv").write_text(text.replace("roll[deg],pitch[deg],yaw[deg]", "roll[rad],pitch[rad],yaw[rad]"))
    for command in ("iso9283", "report"):
        code, _, err = run(capsys, command, "--robot", ROBOT, "--campaign", tmp_path / "cube.yaml", "--measurements",
                           tmp_path / "rad.csv")
        assert code == 2 and "degrees labelled radians" in err and "after the registration" in err, (command, err)
        assert run(capsys, command, "--robot", ROBOT, "--campaign", tmp_path / "cube.yaml", "--measurements",
                   tmp_path / "m.csv", "--quiet")[0] == 0


def test_a_reflector_off_the_flange_gives_the_report_of_its_test_poses(capsys, tmp_path, campaign):
    """A named target (a reflector 30, -20, 80 mm off the flange) on an approached campaign: the characteristics
    keyed by test pose (the report had died of a KeyError on the approaches' keys, name@target)."""
    cli(capsys, "simulate", "--robot", ROBOT, "--campaign", campaign, "--tolerances", TOL, "--target-offset",
        "R=30mm,-20mm,80mm", "--out", tmp_path / "r.csv")
    doc = json.loads(cli(capsys, "iso9283", "--robot", ROBOT, "--campaign", campaign, "--measurements",
                         tmp_path / "r.csv", "--registration-from", tmp_path / "r.truth.yaml", "--json"))
    assert {"P1", "P5", "P1+x"} <= set(doc["pose"]) and doc["multidirectional"]["P3"]["vAP_p"] >= 0
    assert doc["distance"]["between"] == ["P2", "P4"]
