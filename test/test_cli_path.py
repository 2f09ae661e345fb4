"""The path commands end to end: plan-campaign --path writes a test path, simulate --trajectory drives it with
a tracker 8 ms late, path-report finds the latency and the ISO figures (JSON keys in SI, files), refuses what
it must (exit 3) and names bad input (exit 2)."""
import json
import re
from pathlib import Path

import pytest

from helpers import run_cli as run
from tolerance_ros.cli import main

CENTER = "0deg,45deg,0deg,60deg,0deg,30deg,0deg"


@pytest.fixture(scope="module")
def streams(tmp_path_factory):
    d = tmp_path_factory.mktemp("path")
    assert main(["plan-campaign", "--robot", "gao2023_7dof", "--path", "rectangle", "--speed", "0.2m/s", "--cycles",
                 "4", "--center-joints", CENTER, "--out", str(d / "rect.yaml"), "--quiet"]) == 0
    assert main(["simulate", "--robot", "gao2023_7dof", "--tolerances", "gao2023_delta2", "--trajectory",
                 str(d / "rect.yaml"), "--repeatability", "0.1mrad", "--out", str(d / "path.csv"), "--quiet"]) == 0
    return d


def test_plan_campaign_path_json(capsys, tmp_path):
    code, out, _ = run(capsys, "plan-campaign", "--robot", "gao2023_7dof", "--path", "circle", "--center-joints", CENTER,
                       "--side", "100mm", "--out", tmp_path / "c.yaml", "--json")
    doc = json.loads(out)
    assert code == 0 and doc["path"] == "circle" and doc["side_m"] == pytest.approx(0.1) and doc["corners"] == 0
    assert doc["length_m"] == pytest.approx(3.14159 * 0.08, rel=1e-3) and (tmp_path / "c.yaml").is_file()


def test_path_report_json_keys_latency_and_files(capsys, streams):
    code, out, err = run(capsys, "path-report", "--robot", "gao2023_7dof", "--measurements", streams / "path.csv",
                         "--joint-states", streams / "path.joints.csv", "--budget", "gao2023_delta2", "--out",
                         streams / "report", "--json")
    assert code == 0, err
    doc = json.loads(out)
    assert doc["ok"] and abs(doc["latency_s"] - 0.008) < 0.5e-3 and doc["cycles"] == 4
    assert len(doc["segments"]) == 4
    for seg in doc["segments"]:
        assert {"AT_p_m", "RT_p_m", "CR_m", "CO_m", "AV", "RV", "FV_m_s"} <= set(seg)
        assert 0 < seg["AT_p_m"] < 1e-3 and 0 < seg["RT_p_m"] < 1e-3
    for f in ("path_report.json", "path_report.md", "path.png", "along.png"):
        assert (streams / "report" / f).is_file(), f
    assert json.loads((streams / "report" / "path_report.json").read_text())["latency_s"] == doc["latency_s"]


def test_path_report_text(capsys, streams):
    code, out, _ = run(capsys, "path-report", "--robot", "gao2023_7dof", "--measurements", streams / "path.csv",
                       "--joint-states", streams / "path.joints.csv")
    latency = float(re.search(r"latency (\S+) ms \+- (\S+) ms", out).group(1))
    assert code == 0 and abs(latency - 8.0) < 0.1 and "AT_p mm" in out and "not on the test path:" in out


def test_the_trajectory_as_sent_is_found_on_the_tracker_clock(capsys, streams):
    code, out, err = run(capsys, "path-report", "--robot", "gao2023_7dof", "--measurements", streams / "path.csv",
                         "--trajectory", streams / "rect.yaml", "--json")
    assert code == 0, err
    doc = json.loads(out)
    assert doc["command"]["kind"] == "trajectory" and doc["command"]["start_s"] == pytest.approx(1000.008, abs=5e-4)


def test_a_limit_missed_wherever_the_latency_lies_fails_on_the_path_not_on_the_latency(capsys, streams, tmp_path):
    """A limit of 1 um: the latency's uncertainty moves the path by more than a share of it, but the path misses it
    at both ends of the latency's interval, so the verdict stands (exit 3 on AT_p), never a refusal."""
    text = (Path(__file__).resolve().parents[1] / "config" / "budgets" / "gao2023_delta2.yaml").read_text()
    tight = tmp_path / "tight.yaml"
    tight.write_text(text.replace("limit: {position: 1.4}", "limit: {position: 0.001}"))
    code, out, err = run(capsys, "path-report", "--robot", "gao2023_7dof", "--measurements", streams / "path.csv",
                         "--joint-states", streams / "path.joints.csv", "--budget", tight, "--json")
    doc = json.loads(out)
    assert code == 3 and not doc["ok"] and doc["refused"] is None and "FAILED: path accuracy AT_p" in err
    assert min(doc["budget"]["AT_p_at_latency_interval_m"]) > 1e-6


@pytest.mark.parametrize("extra, message", [
    (["--path", "weave", "--pitch", "1e-6mm"], "beyond the cap of 100,000"),     # had been a 1 TiB MemoryError
    (["--path", "weave", "--pitch", "0.01mm"], "1.39e+07 knots 0.5 mm apart"),   # had grown past 2.5 GB
    (["--path", "weave", "--pitch", "1mm", "--stroke", "0.2mm"], "a pitch of at least 3.95 mm"),
    (["--path", "weave", "--stroke", "1e-9mm"], "--stroke: 1e-9mm is out of range: expected at least 0.0001 m"),
    (["--path", "line", "--dwell", "-1s"], "--dwell: -1s is out of range: expected from 0 to 600 s"),
    (["--path", "line", "--dwell", "1e6s"], "--dwell: 1e6s is out of range"),
    (["--path", "line", "--side", "1e-6mm"], "--side: 1e-6mm is out of range: expected from 0.01 to 2.008 m"),
    (["--path", "line", "--speed", "1e9m/s"], "--speed: 1e9m/s is out of range: expected at most 10 m/s"),
    (["--path", "line", "--speed", "1e-9m/s"], "a cycle would last 2.771e+08 s, beyond 3600 s"),
    (["--path", "line", "--accel", "1e9m/s^2"], "--accel: 1e9m/s^2 is out of range: expected at most 100 m/s^2"),
    (["--path", "reorient", "--angular-speed", "100rad/s"], "--angular-speed: 100rad/s is out of range"),
    (["--path", "weave", "--iso9283"], "--path, --iso9283: one kind of campaign at a time"),
    (["--path", "weave", "--contact", "plane:a=0,0,1@0m", "--target", "A=0mm,0mm,0mm"],
     "--path, --contact: one kind of campaign at a time"),
    (["--iso9283", "--contact", "plane:a=0,0,1@0m", "--target", "A=0mm,0mm,0mm"],
     "--iso9283, --contact: one kind of campaign at a time"),
])
def test_plan_campaign_refuses_degenerate_paths_and_a_second_mode(capsys, tmp_path, extra, message):
    """Issue 49: each exits 2 with one line naming the option and the bound, and writes nothing."""
    code, out, err = run(capsys, "plan-campaign", "--robot", "gao2023_7dof", *extra, "--out", tmp_path / "p.yaml")
    assert code == 2 and message in err and len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "p.yaml").exists()


def test_a_reorientation_stores_its_angular_speed_under_its_own_key_and_old_files_still_read(capsys, tmp_path):
    import yaml
    from tolerance_ros.core.accuracy.iso_paths import read_trajectory
    from tolerance_ros.core.models import load_robot
    gao = load_robot("gao2023_7dof")
    code, _, err = run(capsys, "plan-campaign", "--robot", "gao2023_7dof", "--path", "reorient", "--angular-speed",
                       "0.4rad/s", "--cycles", "2", "--out", tmp_path / "r.yaml", "--quiet")
    doc = yaml.safe_load((tmp_path / "r.yaml").read_text())
    assert code == 0 and doc["speed_rad_s"] == 0.4 and "speed_m_s" not in doc, err
    assert read_trajectory(tmp_path / "r.yaml", gao).speed == 0.4
    doc["speed_m_s"] = doc.pop("speed_rad_s")                      # as written before issue 49
    (tmp_path / "old.yaml").write_text(yaml.safe_dump(doc))
    assert read_trajectory(tmp_path / "old.yaml", gao).speed == 0.4
    assert main(["plan-campaign", "--robot", "gao2023_7dof", "--path", "line", "--dwell", "0s", "--speed", "0.3m/s",
                 "--out", str(tmp_path / "l.yaml"), "--quiet"]) == 0
    line = yaml.safe_load((tmp_path / "l.yaml").read_text())
    assert line["speed_m_s"] == 0.3 and "speed_rad_s" not in line


@pytest.mark.parametrize("extra, message", [
    (["--latency", "8"], "--latency: '8' has no unit"),
    (["--stations", "1"], "--stations: expected 2"),
    (["--trajectory", "x.yaml"], "give one of them"),
])
def test_bad_options_exit_2(capsys, streams, extra, message):
    code, _, err = run(capsys, "path-report", "--robot", "gao2023_7dof", "--measurements", streams / "path.csv",
                       "--joint-states", streams / "path.joints.csv", *extra)
    assert code == 2 and message in err


def test_joint_states_without_a_joint_of_the_robot_exit_2(capsys, streams, tmp_path):
    lines = (streams / "path.joints.csv").read_text().splitlines()
    head = [i for i, l in enumerate(lines) if l.startswith("stamp")][0]
    bad = tmp_path / "j.csv"
    bad.write_text("\n".join(",".join(l.split(",")[:-1]) for l in lines[head:]) + "\n")
    code, _, err = run(capsys, "path-report", "--robot", "gao2023_7dof", "--measurements", streams / "path.csv",
                       "--joint-states", bad)
    assert code == 2 and "no column for joint(s) ['joint7']" in err
    deg = tmp_path / "d.csv"
    deg.write_text(lines[head].replace("joint:joint1[rad]", "joint:joint1[furlong]") + "\n" + "\n".join(lines[head + 1:]))
    code, _, err = run(capsys, "path-report", "--robot", "gao2023_7dof", "--measurements", streams / "path.csv",
                       "--joint-states", deg)
    assert code == 2 and "needs an angle unit" in err


def test_joints_in_degrees_labelled_radians_and_millimetres_labelled_metres_exit_2(capsys, streams, tmp_path):
    lines = (streams / "path.joints.csv").read_text().splitlines()
    head = [i for i, l in enumerate(lines) if l.startswith("stamp")][0]
    deg = tmp_path / "deg.csv"
    rows = [lines[head]] + [",".join([r.split(",")[0]] + [f"{float(v) * 57.29577951:.6f}" for v in r.split(",")[1:]])
                            for r in lines[head + 1:]]
    deg.write_text("\n".join(rows) + "\n")
    code, _, err = run(capsys, "path-report", "--robot", "gao2023_7dof", "--measurements", streams / "path.csv",
                       "--joint-states", deg)
    assert code == 2 and "degrees" in err
    pts = (streams / "path.csv").read_text().replace("x[mm],y[mm],z[mm]", "x[m],y[m],z[m]")
    (tmp_path / "m.csv").write_text(pts)
    code, _, err = run(capsys, "path-report", "--robot", "gao2023_7dof", "--measurements", tmp_path / "m.csv",
                       "--joint-states", streams / "path.joints.csv")
    assert code == 2 and "millimetres labelled metres" in err


def test_a_rosbag2_recording_of_both_streams_gives_the_csv_figures(capsys, streams, tmp_path):
    """The points (PointStamped) and joint states of a recording are read as they streamed, unpaired, so the
    latency between them is measured: the same report as from the two CSV files."""
    from tolerance_ros.core.accuracy.io.joint_states import read_joint_states, read_points
    from tolerance_ros.core.accuracy.io.rosbag import write_rosbag_streams
    from tolerance_ros.core.models import load_robot
    gao = load_robot("gao2023_7dof")
    stamps, points, _ = read_points(streams / "path.csv")
    tj, qj = read_joint_states(streams / "path.joints.csv", gao.joint_names, gao.joint_types)
    write_rosbag_streams(tmp_path / "bag", stamps, points, tj, qj, gao.joint_names)
    code, out, err = run(capsys, "path-report", "--robot", "gao2023_7dof", "--measurements", tmp_path / "bag", "--json")
    assert code == 0, err
    bag = json.loads(out)
    code, out, _ = run(capsys, "path-report", "--robot", "gao2023_7dof", "--measurements", streams / "path.csv",
                       "--joint-states", streams / "path.joints.csv", "--json")
    csv = json.loads(out)
    assert abs(bag["latency_s"] - 0.008) < 0.5e-3 and bag["latency_s"] == pytest.approx(csv["latency_s"], abs=1e-9)
    for a, b in zip(bag["segments"], csv["segments"]):
        assert a["AT_p_m"] == pytest.approx(b["AT_p_m"], rel=1e-6) and a["RT_p_m"] == pytest.approx(b["RT_p_m"], rel=1e-6)
    write_rosbag_streams(tmp_path / "points_only", stamps, points, [], [], gao.joint_names)
    code, out, err = run(capsys, "path-report", "--robot", "gao2023_7dof", "--measurements", tmp_path / "points_only")
    assert code == 2 and "no joint states recorded" in err


def test_a_target_off_the_tool_is_judged_at_its_offset_and_its_tube(capsys, streams):
    """A reflector 300 mm along the tool axis (simulate --trajectory --target-offset): path-report with the same
    --target-offset scores it like the tool point's stream (the path is the same, shifted); without it the
    as-built orientation errors along the path show as path error that is not there; the tube is the
    target's; a bare number is refused."""
    d = streams
    assert main(["simulate", "--robot", "gao2023_7dof", "--tolerances", "gao2023_delta2", "--trajectory",
                 str(d / "rect.yaml"), "--repeatability", "0.1mrad", "--target-offset", "R=0mm,0mm,300mm", "--out",
                 str(d / "target.csv"), "--quiet"]) == 0
    capsys.readouterr()
    base = ["path-report", "--robot", "gao2023_7dof", "--joint-states", d / "target.joints.csv", "--budget",
            "gao2023_delta2", "--json", "--measurements"]
    code, out, err = run(capsys, *base, d / "path.csv")
    assert code == 0, err
    tool = json.loads(out)
    code, out, err = run(capsys, *base, d / "target.csv", "--target-offset", "0mm,0mm,300mm")
    assert code == 0, err
    at = json.loads(out)
    code, out, err = run(capsys, *base, d / "target.csv")
    blind = json.loads(out)
    assert at["target_offset_m"] == pytest.approx([0.0, 0.0, 0.3]) and blind["target_offset_m"] is None
    assert abs(at["latency_s"] - 0.008) < 0.5e-3
    assert at["registration"]["residual_rms_m"] < blind["registration"]["residual_rms_m"]
    assert at["budget"]["bound_max_m"] != pytest.approx(tool["budget"]["bound_max_m"], rel=1e-3)
    code, _, err = run(capsys, *base, d / "target.csv", "--target-offset", "0,0,300mm")
    assert code == 2 and "--target-offset" in err and "unit" in err


def test_a_cycle_with_lost_tracker_points_is_not_judged_and_the_report_says_so(capsys, streams, tmp_path):
    """0.3 s of the tracker's points lost in the first cycle: the report judges the other three, counts the
    first's points as not judged, and names the gap and the cycle."""
    lines = (streams / "path.csv").read_text().splitlines()
    kept = [l for l in lines if not (l[:1].isdigit() and 1001.0 <= float(l.split(",")[0]) < 1001.3)]
    assert len(lines) - len(kept) == 300
    holed = tmp_path / "holed.csv"
    holed.write_text("\n".join(kept) + "\n")
    code, out, err = run(capsys, "path-report", "--robot", "gao2023_7dof", "--measurements", holed,
                         "--joint-states", streams / "path.joints.csv", "--json")
    assert code == 0, err
    doc = json.loads(out)
    assert doc["cycles"] == 3 and doc["stream_gaps"]["points"]["gaps"] == 1
    assert doc["stream_gaps"]["points"]["missing"] == 300 and doc["outside"]["not_judged"] > 3000
    assert len(doc["not_judged"]) == 1 and "the tracker's points" in doc["not_judged"][0]
    code, out, _ = run(capsys, "path-report", "--robot", "gao2023_7dof", "--measurements", holed,
                       "--joint-states", streams / "path.joints.csv")
    assert code == 0 and "points: 1 gap(s) in the stamps" in out and "was not judged" in out
    assert "in cycles not judged" in out


def test_a_static_campaigns_measurements_are_not_a_path_exit_2(capsys, tmp_path):
    """The rows of a static campaign (test poses measured at rest, named by pose) give no path to judge."""
    assert main(["plan-campaign", "--robot", "gao2023_7dof", "--n", "10", "--out", str(tmp_path / "c.yaml"),
                 "--quiet"]) == 0
    assert main(["simulate", "--robot", "gao2023_7dof", "--tolerances", "gao2023_delta2", "--campaign",
                 str(tmp_path / "c.yaml"), "--out", str(tmp_path / "m.csv"), "--quiet"]) == 0
    capsys.readouterr()
    code, _, err = run(capsys, "path-report", "--robot", "gao2023_7dof", "--measurements", tmp_path / "m.csv")
    assert code == 2 and "not a path" in err and "report" in err
    lines = (tmp_path / "m.csv").read_text().splitlines()     # the same rows without their pose names
    head = next(i for i, line in enumerate(lines) if not line.startswith("#"))
    cols = lines[head].split(",")
    keep = [k for k, c in enumerate(cols) if not c.startswith(("pose", "cycle"))]
    (tmp_path / "bare.csv").write_text("\n".join(",".join(r.split(",")[k] for k in keep) for r in lines[head:]) + "\n")
    code, _, err = run(capsys, "path-report", "--robot", "gao2023_7dof", "--measurements", tmp_path / "bare.csv")
    assert code == 2 and "not a path" in err and "s apart" in err


def test_a_loop_without_a_stop_logged_twice_and_late_is_judged_as_the_clean_one(capsys, tmp_path):
    """plan-campaign --dwell 0s: the line driven back and forth with no rest, the tracker 118 ms late, every joint
    state logged twice: 4 cycles found by repetition, the latency, the duplicates said."""
    assert main(["plan-campaign", "--robot", "gao2023_7dof", "--path", "line", "--speed", "0.2m/s", "--cycles", "4",
                 "--dwell", "0s", "--center-joints", CENTER, "--out", str(tmp_path / "line.yaml"), "--quiet"]) == 0
    assert main(["simulate", "--robot", "gao2023_7dof", "--tolerances", "gao2023_delta2", "--trajectory",
                 str(tmp_path / "line.yaml"), "--latency", "118ms", "--out", str(tmp_path / "p.csv"), "--quiet"]) == 0
    capsys.readouterr()
    code, out, err = run(capsys, "path-report", "--robot", "gao2023_7dof", "--measurements", tmp_path / "p.csv",
                         "--joint-states", tmp_path / "p.joints.csv", "--json")
    assert code == 0, err
    clean = json.loads(out)
    assert clean["cycles"] == 4 and clean["other_motions"] == 4 and clean["cycles_from"]["method"] == "repetition"
    assert abs(clean["latency_s"] - 0.118) < 0.5e-3
    lines = (tmp_path / "p.joints.csv").read_text().splitlines()
    head = next(i for i, line in enumerate(lines) if line.startswith("stamp"))
    (tmp_path / "twice.csv").write_text("\n".join(lines[:head + 1] + [r for r in lines[head + 1:] for _ in (0, 1)]) + "\n")
    code, out, err = run(capsys, "path-report", "--robot", "gao2023_7dof", "--measurements", tmp_path / "p.csv",
                         "--joint-states", tmp_path / "twice.csv")
    assert code == 0, err
    assert f"joint states: {len(lines) - head - 1:,} row(s) repeated a stamp" in out
    assert f"{clean['overall']['AT_p_m'] * 1e3:.4f}" in out
    code, _, err = run(capsys, "path-report", "--robot", "gao2023_7dof", "--measurements", tmp_path / "p.csv",
                       "--joint-states", tmp_path / "p.joints.csv", "--latency-window", "100ms")
    assert code == 2 and "edge of the search window -100.0 ms to +100.0 ms" in err


def test_joint_state_files_as_exported_say_what_is_wrong_or_read_past(capsys, streams, tmp_path):
    """A row with a field more, a semicolon-separated export: exit 2 naming the line or the separator; a column
    of a joint the robot does not have (a gripper's): read past and said."""
    lines = (streams / "path.joints.csv").read_text().splitlines()
    head = next(i for i, line in enumerate(lines) if line.startswith("stamp"))
    extra = lines[:head + 1] + lines[head + 1:head + 50] + [lines[head + 50] + ",0.0"] + lines[head + 51:]
    (tmp_path / "extra.csv").write_text("\n".join(extra) + "\n")
    code, _, err = run(capsys, "path-report", "--robot", "gao2023_7dof", "--measurements", streams / "path.csv",
                       "--joint-states", tmp_path / "extra.csv")
    assert code == 2 and f"line {head + 51}: expected 8 columns, got 9" in err
    (tmp_path / "semi.csv").write_text("\n".join(l.replace(",", ";") for l in lines[head:]) + "\n")
    code, _, err = run(capsys, "path-report", "--robot", "gao2023_7dof", "--measurements", streams / "path.csv",
                       "--joint-states", tmp_path / "semi.csv")
    assert code == 2 and "separated by semicolons" in err
    (tmp_path / "semi_points.csv").write_text((streams / "path.csv").read_text().replace(",", ";"))
    code, _, err = run(capsys, "path-report", "--robot", "gao2023_7dof", "--measurements", tmp_path / "semi_points.csv",
                       "--joint-states", streams / "path.joints.csv")
    assert code == 2 and "separated by semicolons" in err
    grip = [lines[head] + ",joint:gripper[rad]"] + [r + ",0.5" for r in lines[head + 1:]]
    (tmp_path / "grip.csv").write_text("\n".join(grip) + "\n")
    code, out, err = run(capsys, "path-report", "--robot", "gao2023_7dof", "--measurements", streams / "path.csv",
                         "--joint-states", tmp_path / "grip.csv")
    assert code == 0, err
    assert "columns of joints gao2023_7dof does not have, read past: gripper" in out


def test_a_trajectory_with_a_latency_window_is_still_placed_on_the_trackers_clock(capsys, streams):
    code, out, err = run(capsys, "path-report", "--robot", "gao2023_7dof", "--measurements", streams / "path.csv",
                         "--trajectory", streams / "rect.yaml", "--latency-window", "30ms", "--json")
    assert code == 0, err
    assert json.loads(out)["command"]["start_s"] == pytest.approx(1000.008, abs=5e-4)


def test_one_stamp_of_1e308_is_one_point_left_out_and_every_cycle_is_judged(capsys, streams, tmp_path):
    """Issue 49: the stray stamp had cut the tracker's stream into two epochs, and a whole cycle went unjudged."""
    lines = (streams / "path.csv").read_text().splitlines()
    rows = [i for i, line in enumerate(lines) if line[:1].isdigit()]
    k = rows[len(rows) // 3]
    lines[k] = "1e308," + lines[k].split(",", 1)[1]
    (tmp_path / "stray.csv").write_text("\n".join(lines) + "\n")
    docs = []
    for f in (streams / "path.csv", tmp_path / "stray.csv"):
        code, out, err = run(capsys, "path-report", "--robot", "gao2023_7dof", "--measurements", f,
                             "--joint-states", streams / "path.joints.csv", "--json", "--quiet")
        assert code == 0, err
        docs.append(json.loads(out))
    clean, stray = docs
    assert stray["cycles"] == clean["cycles"] == 4 and stray["not_judged"] == []
    points = stray["streams"]["points"]
    assert points["stray"] == 1 and points["epochs"] == 1 and points["jump_count"] == 0
    assert stray["outside"]["left_out"] == 1 and stray["outside"]["outside_joint_states"] == 0
