"""The command line: tables, --json documents, plots and error messages."""
import json

import numpy as np
import pytest

from tolerance_ros.cli import main


def run(capsys, *argv):
    code = main(list(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


def test_jacobian_json_is_si_and_complete(capsys):
    code, out, _ = run(capsys, "jacobian", "--robot", "gao2023_7dof", "--joints", "0,0.1,0.2,0.3,0.4,0.5,0.6", "--json")
    assert code == 0
    doc = json.loads(out)
    assert doc["ok"] and doc["robot"] == "gao2023_7dof"
    J = np.array(doc["jacobian"])
    assert J.shape == (1, 6, 28) and doc["parameters"][14] == "alpha1" and doc["units"][0] == "m"
    assert np.array(doc["poses"]).shape == (1, 4, 4)


def test_jacobian_table_and_degrees(capsys, gao):
    code, out, _ = run(capsys, "jacobian", "--robot", "gao2023_7dof", "--joints", "0,10,20,30,40,50,60", "--deg")
    assert code == 0 and "theta7" in out and "tool position [mm]" in out
    code, out, _ = run(capsys, "jacobian", "--robot", "gao2023_7dof", "--joints", "0,10,20,30,40,50,60", "--deg",
                       "--json")
    doc = json.loads(out)
    q = np.radians([[0, 10, 20, 30, 40, 50, 60]])
    np.testing.assert_allclose(doc["joints"], q, atol=1e-15)
    np.testing.assert_allclose(doc["poses"], gao.fk(q), atol=1e-15)


def test_sensitivity_table_json_and_plot(capsys, tmp_path):
    code, out, err = run(capsys, "sensitivity", "--robot", "gao2023_7dof", "--samples", "300", "--limit", "1.4mm",
                         "--plot", str(tmp_path))
    assert code == 0 and "ceiling" in out and "a6" in out
    assert (tmp_path / "salience.png").stat().st_size > 1000
    code, out, _ = run(capsys, "sensitivity", "--robot", "gao2023_7dof", "--samples", "300", "--json",
                       "--limit", "1.4mm", "--quiet")
    doc = json.loads(out)
    assert doc["ceilings"]["a1"] == pytest.approx(1.4e-3)
    assert doc["ceilings"]["theta7"] is None  # unbounded: no effect on position
    assert sum(p["salience"] for p in doc["parameters"]) == pytest.approx(1.0)


def test_verify_with_bounds_and_histogram(capsys, tmp_path):
    code, out, err = run(capsys, "verify", "--robot", "gao2023_7dof", "--tolerances", "gao2023_delta2",
                         "--samples", "2000", "--errors", "fixed", "--bounds", "--plot", str(tmp_path))
    assert code == 0 and "pass rate" in out and "worst-case" in out
    assert "verify:" in err  # progress on stderr
    assert (tmp_path / "error_histogram.png").exists()
    code, out, _ = run(capsys, "verify", "--robot", "gao2023_7dof", "--tolerances", "gao2023_delta2",
                       "--samples", "2000", "--errors", "fixed", "--json", "--quiet", "--bounds")
    doc = json.loads(out)
    pos = doc["position_m"]
    assert pos["limit"] == pytest.approx(1.4e-3) and 0.99 <= pos["pass_rate"] <= 1.0
    assert doc["bounds_m"]["worst-case"]["max"] >= doc["bounds_m"]["paper"]["max"]


@pytest.mark.parametrize("argv, message", [
    (["jacobian", "--robot", "nope"], "no such file"),
    (["jacobian", "--robot", "gao2023_7dof", "--joints", "1,2,3"], "expected 7 values"),
    (["jacobian", "--robot", "gao2023_7dof", "--joints", "1,2,x,4,5,6,7"], "--joints[0]"),
    (["verify", "--robot", "gao2023_7dof", "--tolerances", "gao2023_delta1", "--limit", "1.4 furlong"], "--limit"),
    (["verify", "--robot", "gao2023_7dof", "--tolerances", "gao2023_delta1", "--limit=-1mm"], "must be > 0"),
    (["verify", "--robot", "gao2023_7dof", "--tolerances", "missing_budget"], "missing_budget"),
    (["paper", "smith1999"], "unknown paper"),
])
def test_errors_are_one_clear_line(capsys, argv, message):
    code, out, err = run(capsys, *argv)
    assert code == 2
    assert message in err and "Traceback" not in err


def test_errors_with_json_are_a_json_document(capsys):
    code, out, err = run(capsys, "jacobian", "--robot", "gao2023_7dof", "--joints", "1,2", "--json")
    assert code == 2
    doc = json.loads(out)
    assert doc["ok"] is False and "expected 7 values" in doc["error"]["message"]


def test_paper_command_prints_published_beside_reproduced(capsys, tmp_path):
    code, out, _ = run(capsys, "paper", "gao2023", "--poses", "3000", "--quiet", "--plot", str(tmp_path), "--no-synthesis")
    assert code == 0
    for needle in ("Table 3", "Table 4", "Table 5", "34459", "44736", "published", "reproduced", "Not reproduced"):
        assert needle in out
    assert len(list(tmp_path.glob("*.png"))) == 3


def test_robots_lists_the_shipped_configs(capsys):
    code, out, _ = run(capsys, "robots", "--json")
    assert code == 0
    assert any(r["name"] == "gao2023_7dof" and r["dof"] == 7 for r in json.loads(out)["robots"])


def test_allocate_writes_a_budget_that_verify_reads(capsys, tmp_path):
    out = tmp_path / "budget.yaml"
    code, text, err = run(capsys, "allocate", "--robot", "gao2023_7dof", "--limit", "1.4mm", "--out", str(out),
                          "--plot", str(tmp_path), "--mc-poses", "2000")
    assert code == 0, err
    assert "tolerance delta_j" in text and "free (no effect)" in text and "WARNING" in text
    assert (tmp_path / "convergence.png").exists() and (tmp_path / "error_histogram.png").exists()
    code, text, _ = run(capsys, "verify", "--robot", "gao2023_7dof", "--tolerances", str(out), "--errors", "fixed",
                        "--samples", "3000", "--json", "--quiet")
    doc = json.loads(text)
    assert code == 0 and doc["position_m"]["pass_rate"] == 1.0 and doc["position_m"]["limit"] == pytest.approx(1.4e-3)


def test_allocate_json_and_errors(capsys, tmp_path):
    code, text, _ = run(capsys, "allocate", "--robot", "gao2023_7dof", "--limit", "1.4mm", "--solver", "ga",
                        "--json", "--quiet", "--out", "-", "--mc-poses", "1000")
    doc = json.loads(text)
    assert code == 0 and doc["solver"] == "ga" and len(doc["parameters"]) == 28
    assert {"paper", "worst-case", "rss"} == set(doc["verification"]["supremum"])
    code, _, err = run(capsys, "allocate", "--robot", "gao2023_7dof", "--limit", "1.4mm", "--criterion", "worst-case",
                       "--out", "-")
    assert code == 2 and "infeasible" in err
    code, _, err = run(capsys, "allocate", "--robot", "gao2023_7dof", "--limit", "1.4mm", "--floor", "theta1=5mrad",
                       "--out", "-")
    assert code == 2 and "floors above ceilings: theta1" in err
    code, _, err = run(capsys, "allocate", "--robot", "gao2023_7dof", "--limit", "1.4mm", "--floor", "bogus=1mm",
                       "--out", "-")
    assert code == 2 and "bogus" in err
    code, _, err = run(capsys, "allocate", "--robot", "gao2023_7dof", "--limit", "0mm", "--out", "-")
    assert code == 2 and "--limit" in err


def _synthetic_campaign(tmp_path, gao):
    from tolerance_ros.core.accuracy.io import Measurements, write_csv
    from tolerance_ros.core.accuracy.simulate import as_built_errors, measure
    from tolerance_ros.core.budget import load_budget
    from tolerance_ros.core.geometry import transform
    delta = load_budget("gao2023_delta2", gao).vector_for(gao)
    q = gao.sample_joints(60, 1)
    T = measure(gao, q, as_built_errors(delta, 3), 1e-5, 1e-5, transform([1, 0, 0], [0, 0, 0.5]), seed=2)
    m = Measurements(np.arange(60.0), T, q, gao.joint_names, np.array([""] * 60, dtype=object), np.full(60, -1))
    return m, write_csv(tmp_path / "m.csv", m)


def test_report_from_csv_and_from_a_rosbag_agree(capsys, tmp_path, gao):
    from tolerance_ros.core.accuracy.io import write_rosbag
    m, csv_path = _synthetic_campaign(tmp_path, gao)
    write_rosbag(tmp_path / "bag", m, "mcap")
    docs = []
    for src in (csv_path, tmp_path / "bag"):
        code, out, err = run(capsys, "report", "--robot", "gao2023_7dof", "--measurements", str(src), "--budget",
                             "gao2023_delta2", "--json", "--out", str(tmp_path / ("r_" + src.stem)))
        assert code == 0, err
        docs.append(json.loads(out))
    a, b = docs
    assert a["summary"]["verdicts"] == b["summary"]["verdicts"]
    assert a["summary"]["position_error_m"]["mean"] == pytest.approx(b["summary"]["position_error_m"]["mean"], rel=1e-6)
    assert (tmp_path / "r_m" / "report.md").read_text().startswith("# Accuracy report")
    assert (tmp_path / "r_m" / "error_vs_bound.png").exists()


def test_report_bad_file_names_the_line(capsys, tmp_path):
    p = tmp_path / "bad.csv"
    p.write_text("stamp[s],x[mm],y[mm],z[mm],joint:joint1[rad]\n0,1,2,3,0\n")
    code, _, err = run(capsys, "report", "--robot", "gao2023_7dof", "--measurements", str(p))
    assert code == 2 and "joint columns: no value for joint(s) ['joint2'" in err


@pytest.mark.parametrize("name, content, message", [
    ("m.csv", "stamp[s],x[mm],y[mm],z[mm]\n0,1_000,2,3\n", "m.csv, line 2: x: '1_000' is not a number"),
    ("m.csv", b"# ok\nstamp[s],x[mm],y[mm],z[mm]\n0,1,\xff,3\n",
     "m.csv, line 3: y: byte 0xff at character 5 is not UTF-8"),
    ("m.csv", 'stamp[s],pose,x[mm],y[mm],z[mm]\n0,"' + "P" * 140_000 + '",1,2,3\n',
     "m.csv, line 2: pose: longer than 131072 characters"),
    ("m.csv", "stamp[s],x[mm],y[mm],z[mm],qx,qy,qz\n0,1,2,3,0,0,0\n", "m.csv, line 1: header: orientation needs all "
     "of qx, qy, qz, qw; missing column(s) ['qw']"),
    ("c.jsonl", "[1, 2]\n", "c.jsonl, line 1: expected a JSON object, got a JSON array"),
    ("c.jsonl", "[" * 100_000 + "]" * 100_000 + "\n", "c.jsonl, line 1: nested deeper than 64 levels"),
    ("c.jsonl", '{"event": "measurement", "seq": 0, "stamp": Infinity}\n',
     "c.jsonl, line 1: stamp: Infinity is not valid JSON (numbers must be finite)"),
])
def test_report_of_a_malformed_file_is_one_line_naming_it(capsys, tmp_path, name, content, message):
    p = tmp_path / name
    p.write_bytes(content if isinstance(content, bytes) else content.encode())
    code, out, err = run(capsys, "report", "--robot", "gao2023_7dof", "--measurements", str(p))
    assert code == 2 and out == "" and err == f"tolerance-ros report: error: {p.parent}/{message}\n"


def test_report_skip_bad_lists_what_it_skipped(capsys, tmp_path, gao):
    _, path = _synthetic_campaign(tmp_path, gao)
    lines = path.read_text().splitlines(keepends=True)
    for k in range(3, 15):  # twelve rows with an x that is not a number
        fields = lines[k].split(",")
        fields[3] = "NaN" if k % 2 else "1_000"
        lines[k] = ",".join(fields)
    path.write_text("".join(lines))
    code, out, err = run(capsys, "report", "--robot", "gao2023_7dof", "--measurements", str(path))
    assert code == 2 and err.strip().endswith("m.csv, line 4: x: 'NaN' is not a number")
    code, out, err = run(capsys, "report", "--robot", "gao2023_7dof", "--measurements", str(path), "--skip-bad",
                         "--budget", "gao2023_delta2")
    assert code == 0, err
    assert "budget: " in out
    assert f"48 measurements from {path}; 12 skipped:\n  line 4: x: 'NaN' is not a number\n" \
           "  line 5: x: '1_000' is not a number\n" in out
    assert "  line 13: x: '1_000' is not a number\n  ... and 2 more (all of them in skipped_rows of --json)" in out
    code, out, _ = run(capsys, "report", "--robot", "gao2023_7dof", "--measurements", str(path), "--skip-bad",
                       "--json")
    assert [s["line"] for s in json.loads(out)["skipped_rows"]] == list(range(4, 16))
    code, _, err = run(capsys, "report", "--robot", "gao2023_7dof", "--measurements", str(path), "--skip-bad",
                       "--stream")
    assert code == 2 and "--skip-bad: not available with --stream" in err


def test_the_3pups_robot_through_the_existing_subcommands(capsys, tmp_path):
    code, out, _ = run(capsys, "sensitivity", "--robot", "rong2018_3pups", "--samples", "200", "--quiet", "--json")
    doc = json.loads(out)
    assert code == 0 and len(doc["parameters"]) == 27
    code, out, _ = run(capsys, "verify", "--robot", "rong2018_3pups", "--tolerances", "rong2018_table1", "--samples",
                       "500", "--errors", "normal", "--quiet", "--json", "--plot", str(tmp_path))
    doc = json.loads(out)
    assert code == 0 and doc["position_m"]["limit"] == pytest.approx(4e-5) and (tmp_path / "error_histogram.png").exists()
    code, out, _ = run(capsys, "jacobian", "--robot", "rong2018_3pups", "--random", "2", "--json")
    assert code == 0 and np.array(json.loads(out)["jacobian"]).shape == (2, 6, 27)


def test_paper_rong2018_prints_the_studies(capsys, tmp_path):
    code, out, _ = run(capsys, "paper", "rong2018", "--no-synthesis", "--quiet", "--plot", str(tmp_path))
    assert code == 0 and "Fig. 3" in out and "Table 3" in out and "PE6" in out
    assert (tmp_path / "rong2018_fig3.png").exists()
