"""The command line: tables, --json documents, plots and error messages."""
import json
import re
from pathlib import Path

import numpy as np
import pytest

from helpers import run_cli as run
from tolerance_ros.cli import main
from tolerance_ros.cli.main import kernel_needs


@pytest.fixture
def small_arm(tmp_path_factory):
    """A 3-DOF arm file (mm, deg): allocations in a second, where a test needs one but not the paper's arm."""
    path = tmp_path_factory.mktemp("robots") / "small_arm.yaml"
    path.write_text("name: small_arm\nkind: dh\nunits: {length: mm, angle: deg}\njoints:\n"
                    "  - {name: j1, type: revolute, a: 0, alpha: 90, d: 300, theta: 0, limits: [-170, 170]}\n"
                    "  - {name: j2, type: revolute, a: 400, alpha: 0, d: 0, theta: 0, limits: [-120, 120]}\n"
                    "  - {name: j3, type: revolute, a: 300, alpha: 0, d: 0, theta: 0, limits: [-150, 150]}\n")
    return str(path)


def test_jacobian_json_is_si_and_complete(capsys):
    code, out, _ = run(capsys, "jacobian", "--robot", "gao2023_7dof", "--joints", "0rad,0.1rad,0.2rad,0.3rad,0.4rad,0.5rad,0.6rad",
                         "--json")
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
    assert (tmp_path / "verify_error_histogram.png").exists()
    code, out, _ = run(capsys, "verify", "--robot", "gao2023_7dof", "--tolerances", "gao2023_delta2",
                       "--samples", "2000", "--errors", "fixed", "--json", "--quiet", "--bounds")
    doc = json.loads(out)
    pos = doc["position_m"]
    assert pos["limit"] == pytest.approx(1.4e-3) and 0.99 <= pos["pass_rate"] <= 1.0
    assert doc["bounds_m"]["worst-case"]["max"] >= doc["bounds_m"]["paper"]["max"]


@pytest.mark.parametrize("argv, message", [
    (["jacobian", "--robot", "nope"], "no such file"),
    (["jacobian", "--robot", "gao2023_7dof", "--joints", "1rad,2rad,3rad"], "expected 7 values"),
    (["jacobian", "--robot", "gao2023_7dof", "--joints", "1rad,2rad,xrad,4rad,5rad,6rad,7rad"], "--joints[0]"),
    (["jacobian", "--robot", "gao2023_7dof", "--joints", "0,0.1,0.2,0.3,0.4,0.5,0.6"], "has no unit"),
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
    code, text, err = run(capsys, "allocate", "--robot", "gao2023_7dof", "--limit", "1.4mm", "--criterion", "paper",
                          "--out", str(out), "--plot", str(tmp_path), "--mc-poses", "2000")
    assert code == 0, err
    assert "tolerance delta_j" in text and "free (no effect)" in text
    # the paper's criterion meets 1.4 mm; the worst case over every error sign does not, and the run says so
    assert re.search(r"against the limit 1\.4 mm: worst case [2-9]\.\d{4} mm \(EXCEEDS THE LIMIT\), RSS \d\.\d{4} mm, "
                     r"Monte Carlo pass 100\.00 % of 2000 poses \('fixed' errors\)", text), text
    assert re.search(r"^WARNING: meets the limit only because errors of opposite effect are assumed to cancel", text, re.M)
    assert f"budget saved: {out}" in text
    assert (tmp_path / "allocate_convergence.png").exists() and (tmp_path / "allocate_error_histogram.png").exists()
    code, text, _ = run(capsys, "verify", "--robot", "gao2023_7dof", "--tolerances", str(out), "--errors", "fixed",
                        "--samples", "3000", "--json", "--quiet")
    doc = json.loads(text)
    assert code == 0 and doc["position_m"]["pass_rate"] == 1.0 and doc["position_m"]["limit"] == pytest.approx(1.4e-3)


def test_allocate_json_and_errors(capsys, tmp_path):
    code, text, err = run(capsys, "allocate", "--robot", "gao2023_7dof", "--limit", "1.4mm", "--solver", "ga",
                          "--json", "--quiet", "--mc-poses", "1000")
    doc = json.loads(text)
    assert doc["solver"] == "ga" and len(doc["parameters"]) == 28
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
    assert "budget (paper bound): " in out
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
    assert doc["position_m"]["limit"] == pytest.approx(4e-5) and (tmp_path / "verify_error_histogram.png").exists()
    assert code == (0 if doc["position_m"]["pass_rate"] == 1.0 else 3)
    code, out, _ = run(capsys, "jacobian", "--robot", "rong2018_3pups", "--random", "2", "--json")
    assert code == 0 and np.array(json.loads(out)["jacobian"]).shape == (2, 6, 27)


def test_paper_rong2018_prints_the_studies(capsys, tmp_path):
    code, out, _ = run(capsys, "paper", "rong2018", "--no-synthesis", "--quiet", "--plot", str(tmp_path))
    assert code == 0 and "Fig. 3" in out and "Table 3" in out and "PE6" in out
    assert (tmp_path / "rong2018_fig3.png").exists()


# ---------------------------------------------------------------- mistakes that must not pass silently


@pytest.mark.parametrize("argv", [
    ["verify", "--robot", "gao2023_7dof", "--tolerances", "gao2023_delta1", "--limit", "1.4"],
    ["allocate", "--robot", "gao2023_7dof", "--limit", "1.4", "--out", "-"],
    ["allocate", "--robot", "gao2023_7dof", "--limit", "1.4mm", "--floor-length", "0.05", "--out", "-"],
    ["sensitivity", "--robot", "gao2023_7dof", "--limit", "0.002"],
])
def test_a_bare_number_is_refused_with_the_accepted_forms_before_any_work(capsys, argv, monkeypatch):
    from tolerance_ros.core import synthesis
    monkeypatch.setattr(synthesis, "allocate", lambda *a, **k: pytest.fail("an allocation ran"))
    code, out, err = run(capsys, *argv)
    assert code == 2 and "has no unit; write it with its unit, e.g. 1.4mm or 0.0014m" in err
    assert len(err.strip().splitlines()) == 1 and not out


def test_a_negative_value_reaches_the_options_own_check(capsys):
    code, _, err = run(capsys, "verify", "--robot", "gao2023_7dof", "--tolerances", "gao2023_delta1", "--limit", "-1.4mm")
    assert code == 2 and "--limit: must be > 0, got '-1.4mm'" in err and "usage" not in err.lower()


def test_argument_errors_with_json_are_a_json_document_with_a_stable_code(capsys):
    code, out, err = run(capsys, "allocate", "--robot", "gao2023_7dof", "--limit", "--json")
    assert code == 2 and json.loads(out) == {"ok": False, "error": {"code": "invalid_request", "message": err.split(
        "error: ", 1)[1].strip()}}
    code, out, _ = run(capsys, "jacobian", "--robot", "no_such_robot", "--json")
    assert json.loads(out)["error"]["code"] == "unknown_robot"
    code, out, _ = run(capsys, "verify", "--robot", "gao2023_7dof", "--tolerances", "gao2023_delta1", "--limit",
                       "2 furlong", "--json")
    assert json.loads(out)["error"]["code"] == "invalid_request"


def test_messages_keep_their_quotes_and_a_directory_is_not_a_missing_file(capsys, tmp_path):
    code, _, err = run(capsys, "jacobian", "--robot", "gao2023_7dof", "--joints", "0rad,'a',0.2rad,0.3rad,0.4rad,0.5rad,0.6rad")
    assert "cannot read \"'a'\" as an angle" in err
    code, _, err = run(capsys, "jacobian", "--robot", str(tmp_path))
    assert code == 2 and "is a directory" in err and "no such file" not in err


def test_a_budget_missing_a_parameter_names_its_file(capsys, tmp_path):
    import yaml
    from tolerance_ros.core.resources import config_dir
    data = yaml.safe_load((config_dir() / "budgets" / "gao2023_delta1.yaml").read_text())
    data["tolerances"].pop("a3")
    path = tmp_path / "short.yaml"
    path.write_text(yaml.safe_dump(data))
    code, _, err = run(capsys, "verify", "--robot", "gao2023_7dof", "--tolerances", str(path), "--samples", "10")
    assert code == 2 and f"{path}: tolerances: no tolerance for ['a3']" in err


def test_urdf_chains_are_chosen_on_the_command_line(capsys, tmp_path):
    from helpers import example_urdf
    panda = str(example_urdf("panda.urdf"))
    code, _, err = run(capsys, "jacobian", "--robot", panda, "--random", "1")
    assert code == 2 and "panda_leftfinger" in err and "--tip-link" in err
    code, out, err = run(capsys, "jacobian", "--robot", panda, "--tip-link", "panda_hand", "--base-link", "panda_link0",
                         "--json")
    doc = json.loads(out)
    assert code == 0 and len(doc["joint_names"]) == 7 and np.array(doc["jacobian"]).shape == (1, 6, 49)
    code, _, err = run(capsys, "jacobian", "--robot", "gao2023_7dof", "--tip-link", "tool0")
    assert code == 2 and "only for URDF robots" in err


# ---------------------------------------------------------------- outputs that must say what is so


@pytest.fixture
def figures(monkeypatch):
    """Every figure the plots module saves, as (file name, [(x label, y label, legend entries), ...])."""
    from tolerance_ros.render import plots
    saved, real = [], plots._save

    def keep(fig, plt, path):
        axes = [(ax.get_xlabel(), ax.get_ylabel(), [t.get_text() for t in (ax.get_legend().get_texts()
                                                                             if ax.get_legend() else [])])
                for ax in fig.axes]
        saved.append((Path(path).name, axes))
        return real(fig, plt, path)

    monkeypatch.setattr(plots, "_save", keep)
    return saved


def test_report_names_the_bound_that_failed_and_plots_both(capsys, tmp_path, figures):
    code, out, _ = run(capsys, "report", "--robot", "rong2018_3pups", "--measurements",
                       "config/data/rong2018_pe_measurements.csv", "--budget", "rong2018_table1", "--campaign",
                       "rong2018_pe", "--out", str(tmp_path))
    assert code == 0 and "5 over it, 0 over the design limit; exceeded: orientation bound 5" in out
    assert "exceeded: orientation bound 5" in (tmp_path / "report.md").read_text()
    plot = dict(figures)["error_vs_bound.png"]
    assert [a[:2] for a in plot] == [("predicted position bound [mm]", "measured position error [mm]"),
                                     ("predicted orientation bound [mrad]", "measured orientation error [mrad]")]
    assert "over the bound (5)" in plot[1][2] and "over the bound (0)" in plot[0][2]
    rows = (tmp_path / "measurements.csv").read_text().splitlines()
    assert sum(r.endswith(",orientation bound") or ",orientation bound," in r for r in rows[1:]) == 5


def test_every_plot_axis_says_what_and_its_unit(capsys, tmp_path, figures, small_arm):
    run(capsys, "sensitivity", "--robot", "gao2023_7dof", "--samples", "200", "--quiet", "--plot", str(tmp_path))
    run(capsys, "allocate", "--robot", small_arm, "--limit", "1.4mm", "--quiet", "--plot", str(tmp_path),
        "--mc-poses", "500")
    run(capsys, "verify", "--robot", "gao2023_7dof", "--tolerances", "gao2023_delta2", "--samples", "500", "--quiet",
        "--plot", str(tmp_path))
    run(capsys, "paper", "rong2018", "--no-synthesis", "--quiet", "--plot", str(tmp_path))
    names = [n for n, _ in figures]
    assert {"salience.png", "allocate_convergence.png", "allocate_error_histogram.png", "verify_error_histogram.png",
            "rong2018_fig3.png"} <= set(names)
    for name, axes in figures:
        for xlabel, ylabel, _ in axes:
            assert xlabel or ax_shares_x(axes), name
            assert ylabel and ylabel != "value" and ("[" in ylabel or "poses" in ylabel), (name, ylabel)
    fig3 = dict(figures)["rong2018_fig3.png"]
    assert [len(a[2]) for a in fig3] == [3, 3] and fig3[0][1] == "platform position error [um]"


def ax_shares_x(axes):
    return len(axes) > 1 and bool(axes[-1][0])


def test_plots_of_two_commands_in_one_folder_do_not_replace_each_other(capsys, tmp_path, small_arm):
    run(capsys, "verify", "--robot", "gao2023_7dof", "--tolerances", "gao2023_delta2", "--samples", "300", "--quiet",
        "--plot", str(tmp_path))
    first = (tmp_path / "verify_error_histogram.png").read_bytes()
    run(capsys, "allocate", "--robot", small_arm, "--limit", "1.4mm", "--quiet", "--plot", str(tmp_path),
        "--mc-poses", "300")
    assert (tmp_path / "verify_error_histogram.png").read_bytes() == first
    assert (tmp_path / "allocate_error_histogram.png").exists()


def test_allocate_writes_a_budget_only_where_asked(capsys, tmp_path, monkeypatch, small_arm):
    monkeypatch.chdir(tmp_path)
    code, out, _ = run(capsys, "allocate", "--robot", small_arm, "--limit", "1.4mm", "--quiet", "--mc-poses", "300")
    assert code == 0 and "budget not saved (give --out FILE.yaml to save it)" in out
    assert list(tmp_path.iterdir()) == []


def test_allocate_holds_the_worst_case_over_every_error_sign_by_default(capsys, small_arm):
    from tolerance_ros.core import errors
    from tolerance_ros.core.models import load_robot
    code, text, _ = run(capsys, "allocate", "--robot", small_arm, "--limit", "1.4mm", "--quiet", "--mc-poses", "300",
                        "--json")
    doc = json.loads(text)
    assert code == 0 and doc["problem"]["criterion"] == "worst-case" and doc["limit_check"]["worst_case_within"]
    arm = load_robot(small_arm)
    delta = np.array([r["tolerance"] or 0.0 for r in doc["parameters"]])
    q = arm.sample_joints(20000, seed=7)  # not the allocation's own sample
    assert errors.worst_case_bound(arm.error_jacobian(q).position, delta).max() <= 1.4e-3 * (1 + 1e-6)
    code, text, _ = run(capsys, "allocate", "--robot", small_arm, "--limit", "1.4mm", "--quiet", "--mc-poses", "300")
    assert re.search(r"criterion worst-case, limit 1\.4 mm", text)
    assert re.search(r"against the limit 1\.4 mm: worst case 1\.4000 mm \(within\), RSS 0\.\d{4} mm, Monte Carlo "
                     r"pass 100\.00 % of 300 poses \('extreme' errors\)", text), text


def test_an_allocation_that_misses_its_limit_exits_3_and_says_so(capsys, tmp_path):
    import yaml
    out = tmp_path / "ga.yaml"
    code, text, err = run(capsys, "allocate", "--robot", "gao2023_7dof", "--limit", "1.4mm", "--solver", "ga", "--json",
                          "--quiet", "--mc-poses", "2000", "--out", str(out))
    doc = json.loads(text)
    assert code == 3 and doc["ok"] is False and doc["shortfalls"]
    assert doc["failed"][0].startswith("allocation does not meet its limit: the position error reaches")
    assert "FAILED: allocation does not meet its limit" in err.splitlines()[-1]
    meta = yaml.safe_load(out.read_text())["meta"]
    assert meta["success"] is False and any("Monte Carlo poses" in w for w in meta["warnings"])


def test_verification_figures_over_the_limit_are_warnings():
    from tolerance_ros.core.synthesis import _warnings
    from types import SimpleNamespace
    problem = SimpleNamespace(limit=1.4e-3, criterion="paper")
    sup = {c: {"position": {"value": v, "limit": 1.4e-3, "pass": v <= 1.4e-3}}
           for c, v in (("paper", 1.39e-3), ("worst-case", 2.0e-3), ("rss", 1.0e-3))}
    mc = {"distribution": "fixed", "position_m": {"n": 100, "failures": 0, "pass_rate": 1.0, "limit": 1.4e-3, "max": 1e-3},
          "orientation_rad": {"n": 100, "max": 1e-3}}
    ctl = {"n": 100, "failures": 3, "pass_rate": 0.97, "max": 1.4169e-3, "limit": 1.4e-3}
    warns = _warnings(problem, None, {"supremum": sup, "monte_carlo": mc, "sign_control": {"position_m": ctl}})
    assert any("opposite effect" in w for w in warns)
    assert any("sign control" in w and "1.4169 mm" in w and "3 of 100" in w for w in warns)


def test_paper_table3_and_report_agree_when_they_use_the_same_registration(capsys):
    code, out, _ = run(capsys, "paper", "rong2018", "--no-synthesis", "--quiet", "--json")
    table3 = {r["pose"]: r["iso9283"]["AP_p"] for r in json.loads(out)["table3"]["rows"]}
    assert json.loads(out)["table3"]["registration"].startswith("none: ")
    code, out, _ = run(capsys, "report", "--robot", "rong2018_3pups", "--measurements",
                       "config/data/rong2018_pe_measurements.csv", "--campaign", "rong2018_pe", "--registration",
                       "none", "--json")
    report = json.loads(out)
    assert report["registration"]["method"] == "none"
    for pose, ap in table3.items():
        assert report["per_pose"][pose]["AP_p"] == pytest.approx(ap, rel=1e-9)


def _simulated_csv(path, model, campaign_path, delta, seed=0):
    """Tracker readings (10 um, 10 urad) of a campaign on a robot drawn within delta; the CSV path."""
    from tolerance_ros.core.accuracy.io import Measurements, write_csv
    from tolerance_ros.core.accuracy.simulate import measure
    from tolerance_ros.core.campaign import load_campaign
    from tolerance_ros.core.geometry import transform
    from tolerance_ros.services.tracker import SimulatedTracker
    camp = load_campaign(campaign_path, model)
    T_tb = transform([1.5, -0.3, 0.2], [0.05, -0.02, 1.2])
    dx = SimulatedTracker(model, delta, seed, 1e-5, 1e-5, T_tb).dx
    seq = camp.sequence()
    q = camp.joints_for(model)[[i for i, _ in seq]]
    T = measure(model, q, dx, 1e-5, 1e-5, T_tb, seed=seed + 1)
    labels = np.array([camp.names[i] for i, _ in seq], dtype=object)
    return write_csv(path, Measurements(np.arange(len(q)) * 1.0, T, q, model.joint_names, labels,
                                        np.array([c for _, c in seq])))


def test_plan_calibrate_compensate_closes_the_loop(capsys, tmp_path, gao):
    from tolerance_ros.core.budget import load_budget
    from tolerance_ros.core.campaign import load_campaign
    from tolerance_ros.core.models import load_robot
    planned = tmp_path / "planned.yaml"
    code, out, err = run(capsys, "plan-campaign", "--robot", "gao2023_7dof", "--n", "24", "--candidates", "300",
                         "--cycles", "2", "--out", str(planned), "--plot", str(tmp_path), "--json", "--quiet")
    assert code == 0, err
    doc = json.loads(out)
    obs = doc["observability"]
    assert obs["planned"]["O1"] > obs["random"]["O1"] and obs["iso_cube"]["rank"] < len(doc["unknowns"])
    assert (tmp_path / "singular_values.png").exists() and load_campaign(planned, gao).cycles == 2
    csv_path = _simulated_csv(tmp_path / "m.csv", gao, planned, load_budget("gao2023_delta2", gao).vector_for(gao))
    code, out, err = run(capsys, "calibrate", "--robot", "gao2023_7dof", "--measurements", str(csv_path),
                         "--campaign", str(planned), "--noise", "10um", "--orientation-noise", "10urad",
                         "--folds", "4", "--out", str(tmp_path / "cal"), "--json", "--quiet")
    assert code == 0, err
    cal = json.loads(out)
    assert cal["validation"]["improvement"] > 0.9 and cal["held"] == ["d1", "theta1"]
    assert cal["validation"]["after"]["orientation_rms_rad"] < 0.1 * cal["validation"]["before"]["orientation_rms_rad"]
    for name in ("gao2023_7dof_calibrated.yaml", "calibration.yaml", "calibration.md", "calibration.json",
                 "validation.png", "parameters.png"):
        assert (tmp_path / "cal" / name).exists(), name
    assert load_robot(tmp_path / "cal" / "gao2023_7dof_calibrated.yaml").name == "gao2023_7dof"
    from tolerance_ros.core.calibration.provenance import file_sha256, generate_key_pair
    from tolerance_ros.core.calibration.calibration_file import load_calibration
    made = load_calibration(tmp_path / "cal" / "calibration.yaml", gao)
    assert made.provenance["made_by"] == "tolerance-ros calibrate" and made.signature is None
    assert made.provenance["log_sha256"] == file_sha256(csv_path) and made.provenance["log"] == str(csv_path.resolve())
    key_id = generate_key_pair(tmp_path / "k.key", tmp_path / "k.pub")
    code, out, err = run(capsys, "calibrate", "--robot", "gao2023_7dof", "--measurements", str(csv_path),
                         "--campaign", str(planned), "--out", str(tmp_path / "cal_text"), "--signing-key",
                         str(tmp_path / "k.key"))
    assert code == 0 and "position error RMS (3-D, every measurement) reduced by" in out and "held at nominal" in out
    assert load_calibration(tmp_path / "cal_text" / "calibration.yaml", gao).signature["key_id"] == key_id
    assert "alpha6" in out and "converged in" in out and "in-sample position RMS (3-D)" in out
    compensated = tmp_path / "iso_compensated.yaml"
    code, out, err = run(capsys, "compensate", "--robot", "gao2023_7dof", "--calibration",
                         str(tmp_path / "cal" / "calibration.yaml"), "--poses", "gao2023_iso_cube",
                         "--out", str(compensated), "--json")
    assert code == 0, err
    comp = json.loads(out)
    assert [t["name"] for t in comp["poses"]] == ["P1", "P2", "P3", "P4", "P5"]
    assert all(t["reached"] and t["residual_position_m"] < 1e-9 for t in comp["poses"])
    back = load_campaign(compensated, gao).joints_for(gao)
    np.testing.assert_allclose(back, [t["joints"] for t in comp["poses"]], atol=1e-12)
    code, out, err = run(capsys, "compensate", "--robot", "gao2023_7dof", "--calibration",
                         str(tmp_path / "cal" / "calibration.yaml"), "--targets", "gao2023_iso_cube")
    assert code == 0 and "P5" in out and "correction" in out and "--targets is now --poses" in err


def test_calibrate_without_improvement_exits_3(capsys, tmp_path, gao):
    """A robot built exactly to nominal: the fit only adds estimation noise to the held-out predictions."""
    from tolerance_ros.core.calibration.planning import campaign_dict
    import yaml
    camp = tmp_path / "c.yaml"
    camp.write_text(yaml.safe_dump(campaign_dict(gao, gao.sample_joints(20, 4), "c", cycles=2)))
    csv_path = _simulated_csv(tmp_path / "m.csv", gao, camp, np.zeros(gao.n_params))
    code, out, err = run(capsys, "calibrate", "--robot", "gao2023_7dof", "--measurements", str(csv_path),
                         "--campaign", str(camp), "--out", str(tmp_path / "cal"), "--json", "--quiet")
    doc = json.loads(out)
    assert code == 3 and doc["ok"] is False and "does not reduce" in doc["failed"][0]
    assert doc["plausibility"]["ok"] is False and doc["model"]["parameters"] == "registration"
    assert (tmp_path / "cal" / "calibration.refused.yaml").exists()
    assert not (tmp_path / "cal" / "calibration.yaml").exists() and not list((tmp_path / "cal").glob("*_calibrated*"))


@pytest.mark.parametrize("argv, message", [
    (["calibrate", "--robot", "gao2023_7dof", "--measurements", "m.csv", "--out", "x", "--noise", "10"], "--noise"),
    (["calibrate", "--robot", "gao2023_7dof", "--measurements", "m.csv", "--out", "x", "--folds", "1"], "--folds"),
    (["plan-campaign", "--robot", "gao2023_7dof", "--n", "5", "--candidates", "50"], "plan at least"),
    (["plan-campaign", "--robot", "gao2023_7dof", "--orientation-noise", "1e-5"], "--orientation-noise"),
    (["compensate", "--robot", "gao2023_7dof", "--calibration", "missing.yaml", "--poses", "gao2023_iso_cube"],
     "file not found"),
])
def test_calibration_commands_report_bad_input_in_one_line(capsys, argv, message):
    code, _, err = run(capsys, *argv)
    assert code == 2 and message in err and "Traceback" not in err


def test_calibrate_a_urdf_robot_writes_a_urdf(capsys, tmp_path):
    from helpers import example_urdf
    from tolerance_ros.core.calibration.planning import campaign_dict
    from tolerance_ros.core.models import URDFChain
    import yaml
    ur5 = URDFChain(example_urdf("ur5_robot.urdf"), tip_link="tool0")
    camp = tmp_path / "c.yaml"
    camp.write_text(yaml.safe_dump(campaign_dict(ur5, ur5.sample_joints(24, 3), "c", cycles=2)))
    delta = np.array([1e-4 if k == "length" else 5e-4 for k in ur5.param_kinds])
    csv_path = _simulated_csv(tmp_path / "m.csv", ur5, camp, delta)
    code, out, err = run(capsys, "calibrate", "--robot", str(example_urdf("ur5_robot.urdf")), "--tip-link", "tool0",
                         "--measurements", str(csv_path), "--campaign", str(camp), "--folds", "3", "--out",
                         str(tmp_path / "cal"), "--json", "--quiet")
    assert code == 0, err
    doc = json.loads(out)
    urdf = tmp_path / "cal" / "ur5_robot_calibrated.urdf"
    assert doc["files"]["urdf"] == str(urdf) and doc["validation"]["improvement"] > 0.9
    assert doc["files"]["robot"] == str(tmp_path / "cal" / "ur5_calibrated.yaml")
    q = ur5.sample_joints(5, 9)
    from tolerance_ros.core.calibration.calibration_file import calibration_robot, load_calibration
    from tolerance_ros.core.models import load_robot
    cal = load_calibration(tmp_path / "cal" / "calibration.yaml")
    np.testing.assert_allclose(load_robot(doc["files"]["robot"]).fk(q), cal.fk(ur5, q), atol=1e-12)
    np.testing.assert_allclose(URDFChain(urdf, tip_link="tool0").fk(q), cal.fk(ur5, q), atol=1e-12)
    assert calibration_robot(tmp_path / "cal" / "calibration.yaml").tip_link == "tool0"


def test_version_and_an_unknown_option_before_a_missing_one(capsys):
    with pytest.raises(SystemExit) as done:
        main(["--version"])
    assert done.value.code == 0 and capsys.readouterr().out.startswith("tolerance-ros ")
    assert main(["allocate", "--robot", "gao2023_7dof", "--limt", "1.4mm"]) == 2
    err = capsys.readouterr().err
    assert "unrecognized arguments: --limt (did you mean --limit?)" in err and "required" not in err


def test_compensate_writes_a_flagged_target_with_its_nominal_joints_unless_accepted(capsys, tmp_path, gao):
    """The arm stretched out (all joints 0) is near a singularity, where the correction reaches 15 degrees, beyond
    the 20 mrad envelope: --out writes its nominal joints and names it in the notes; --accept-flagged writes the
    correction."""
    import yaml
    from tolerance_ros.core.accuracy.simulate import as_built_errors, measure
    from tolerance_ros.core.budget import load_budget
    from tolerance_ros.core.calibration.calibrate import calibrate
    from tolerance_ros.core.calibration.planning import campaign_dict
    from tolerance_ros.core.calibration.calibration_file import save_calibration
    from tolerance_ros.core.campaign import load_campaign
    q = gao.sample_joints(30, 5)
    dx = as_built_errors(load_budget("gao2023_delta2", gao).vector_for(gao), 1)
    cal = save_calibration(calibrate(gao, q, measure(gao, q, dx, 1e-5, 0.0, None, seed=2), folds=3),
                           tmp_path / "calibration.yaml")
    targets = tmp_path / "targets.yaml"
    targets.write_text(yaml.safe_dump(campaign_dict(gao, [[0.0] * 7, [0.3, 0.5, 0.4, 1.0, 0.6, 0.8, 0.2]], "t")))
    for accept in (False, True):
        out_file = tmp_path / f"out_{accept}.yaml"
        code, out, err = run(capsys, "compensate", "--robot", "gao2023_7dof", "--calibration", str(cal), "--poses",
                             str(targets), "--out", str(out_file), "--json", *(["--accept-flagged"] if accept else []))
        assert code == 0, err
        doc = json.loads(out)
        home, bent = doc["poses"]
        assert home["near_singularity"] and not bent["near_singularity"]
        assert np.abs(home["correction"]).max() > 0.1                       # rad: what would have been written
        written = load_campaign(out_file, gao).joints_for(gao)
        np.testing.assert_allclose(written[1], bent["joints"], atol=1e-12)
        if accept:
            np.testing.assert_allclose(written[0], home["joints"], atol=1e-12)
            assert home["written"] == "compensated" and "notes" not in yaml.safe_load(out_file.read_text())
        else:
            np.testing.assert_allclose(written[0], home["nominal_joints"], atol=1e-12)
            assert home["written"] == "nominal" and bent["written"] == "compensated"
            # the envelope held per pose, as the trajectory node holds every point (issue 49)
            assert "C1 (near singularity, beyond the envelope: joint change" in yaml.safe_load(
                out_file.read_text())["notes"]
            assert any(f.startswith("beyond the envelope") and "max_joint_correction 0.02 rad" in f
                       for f in home["flags"]) and bent["flags"] == []
            assert "written with their nominal joints" in err


def test_every_option_of_every_command_says_what_it_does():
    import argparse
    from tolerance_ros.cli import build_parser
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    silent = [f"{name} {'/'.join(a.option_strings)}" for name, p in sub.choices.items() for a in p._actions
              if a.option_strings and not a.help and a.help != argparse.SUPPRESS]
    assert not silent, silent


def test_plan_campaign_writes_only_with_out_as_allocate(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, out, err = run(capsys, "plan-campaign", "--robot", "gao2023_7dof", "--n", "12", "--candidates", "100",
                         "--quiet")
    assert code == 0, err
    assert "campaign not saved (give --out FILE.yaml to save it)" in out and not list(tmp_path.iterdir())
    code, out, err = run(capsys, "plan-campaign", "--robot", "gao2023_7dof", "--n", "12", "--candidates", "100",
                         "--quiet", "--json")
    assert code == 0 and json.loads(out)["campaign_file"] is None and not list(tmp_path.iterdir())


@pytest.mark.parametrize("argv, needle", [
    (["sensitivity", "--robot", "gao2023_7dof", "--plot", "{file}"], "--plot {file}: is a file, not a folder"),
    (["verify", "--robot", "gao2023_7dof", "--tolerances", "gao2023_delta1", "--plot", "{file}/sub"],
     "--plot {file}/sub: {file} is a file, so no folder can be made there"),
    (["allocate", "--robot", "gao2023_7dof", "--limit", "2mm", "--out", "{dir}"],
     "--out {dir}: is a folder; give the name of the file to write"),
    (["plan-campaign", "--robot", "gao2023_7dof", "--out", "{file}/deeper/x.yaml"],
     "--out {file}/deeper/x.yaml: {file} is a file, so no folder can be made there"),
    (["calibrate", "--robot", "gao2023_7dof", "--measurements", "m.csv", "--out", "{file}"],
     "--out {file}: is a file, not a folder"),
])
def test_an_output_that_cannot_be_written_is_refused_before_any_work(capsys, tmp_path, argv, needle):
    (tmp_path / "a_file").write_text("x")
    names = {"file": str(tmp_path / "a_file"), "dir": str(tmp_path)}
    code, out, err = run(capsys, *[a.format(**names) for a in argv], "--json")
    assert code == 2 and needle.format(**names) in err and "Errno" not in err
    assert json.loads(out)["error"]["code"] == "invalid_request"


def test_an_operating_system_error_is_said_in_words_with_its_file(capsys, tmp_path):
    from tolerance_ros.cli.common import os_error_message
    exc = FileExistsError(17, "File exists", str(tmp_path / "x"))
    assert os_error_message(exc) == f"{tmp_path / 'x'}: file exists"
    code, _, err = run(capsys, "import", "--input", str(tmp_path), "--out", str(tmp_path / "t.csv"), "--point",
                       "x,y,z[mm]", "--joint", "j1[deg]")
    assert code == 2 and f"{tmp_path}: is a folder, not a file" in err


@pytest.fixture(scope="module")
def ur10_urdf():
    from helpers import example_urdf
    return str(example_urdf("ur10_robot.urdf"))


def test_plan_campaign_ur10_keeps_the_joint_range_and_floor_in_every_pose_and_in_its_file(capsys, tmp_path,
                                                                                          ur10_urdf):
    import yaml
    from tolerance_ros.core.campaign import CampaignError, load_campaign
    from tolerance_ros.core.models import load_robot
    out = tmp_path / "planned.yaml"
    code, text, err = run(capsys, "plan-campaign", "--robot", ur10_urdf, "--tip-link", "tool0", "--n", "10",
                          "--candidates", "150", "--joint-range", "shoulder_lift_joint=-180deg:0deg",
                          "--floor-plane", "0m",
                          "--out", str(out), "--json", "--quiet")
    assert code == 0, err
    doc = json.loads(text)
    q = np.array(doc["joints"])
    ur10 = load_robot(ur10_urdf, "tool0")
    assert q.shape == (10, 6) and np.all((q[:, 1] >= -np.pi) & (q[:, 1] <= 0)) and ur10.fk(q)[:, 2, 3].min() >= 0
    r = doc["restrictions"]
    assert r["joint_range"] == ["shoulder_lift_joint=-180deg:0deg"] and r["above_plane"] == ["0,0,1@0m"]
    assert r["collision_checked"] and r["kept"] == 150 and r["drawn"] == 150 + sum(r["rejected"].values())
    assert np.allclose(r["limits"][1], [-np.pi, 0]) and doc["compare_violations"] == []
    data = yaml.safe_load(out.read_text())
    assert data["restrictions"] == {"joint_range": ["shoulder_lift_joint=-180deg:0deg"], "above_plane": ["0,0,1@0m"],
                                    "collision": True}
    assert "restrictions: joint range shoulder_lift_joint=-180deg:0deg; above plane 0,0,1@0m" in data["description"]
    assert len(load_campaign(out, ur10).poses) == 10
    data["poses"][3]["joints"] = [0, 90, 0, 0, 0, 0]  # shoulder_lift +90 deg: within the URDF's limits, below the floor
    out.write_text(yaml.safe_dump(data))
    with pytest.raises(CampaignError, match=r"1 of 10 poses break the restrictions the campaign was planned under "
                                            r"\(.*\): C4: joint range \(shoulder_lift_joint\)$"):
        load_campaign(out, ur10)
    data["restrictions"].pop("joint_range")
    out.write_text(yaml.safe_dump(data))
    with pytest.raises(CampaignError, match=r": C4: tool below a plane \(0,0,1@0m\)$"):
        load_campaign(out, ur10)


def test_plan_campaign_flags_compared_poses_in_collision_or_through_the_floor(capsys, tmp_path, ur10_urdf):
    import yaml
    camp = tmp_path / "cube.yaml"
    camp.write_text(yaml.safe_dump({"robot": "ur10", "units": {"angle": "deg"}, "poses": [
        {"name": "P1", "joints": [0, -90, 0, 0, 0, 0]}, {"name": "P2", "joints": [0, -90, 180, 0, 0, 0]},
        {"name": "P3", "joints": [0, 90, 0, 0, 0, 0]}, {"name": "P4", "joints": [0, -90, 45, 0, 0, 0]},
        {"name": "P5", "joints": [0, -45, 45, 0, 0, 0]}]}))
    args = ["plan-campaign", "--robot", ur10_urdf, "--tip-link", "tool0", "--n", "10", "--candidates", "120",
            "--floor-plane", "0m", "--compare", str(camp), "--quiet"]
    code, text, err = run(capsys, *args)
    assert code == 0, err
    lines = text.splitlines()
    assert lines[0] == "restrictions: above plane 0,0,1@0m; no self-collision or link through a plane"
    assert lines[1].startswith("kept 120 of ") and "self-collision (most often " in lines[1]
    assert (f"warning: 2 of 5 poses of {camp} break the restrictions: P2: self-collision "
            f"(shoulder_link-forearm_link); P3: tool below a plane (0,0,1@0m)") in lines
    code, text, err = run(capsys, *args, "--json")
    assert json.loads(text)["compare_violations"] == ["P2: self-collision (shoulder_link-forearm_link)",
                                                      "P3: tool below a plane (0,0,1@0m)"]
    code, text, err = run(capsys, *args, "--no-collision", "--json")
    doc = json.loads(text)
    assert doc["compare_violations"] == ["P3: tool below a plane (0,0,1@0m)"]
    assert doc["restrictions"]["collision_note"] == "collisions not checked (--no-collision)"


@pytest.mark.parametrize("extra, message", [
    (["--floor-plane", "0"], "--floor-plane: '0' has no unit; write it with its unit"),
    (["--joint-range", "shoulder_lift=-180deg:0deg"], "no joint 'shoulder_lift' (closest: 'shoulder_lift_joint'"),
    (["--joint-range", "elbow_joint=-190deg:0deg"], "elbow_joint: -190deg:0deg is outside the joint's limits"),
    (["--inside-box", "1.2m:1.21m,0m:0.01m,0m:0.01m"], "too few candidates for 10 poses: kept 0 of 1,200 candidates "
                                                        "drawn: 1,200 tool outside the box"),
])
def test_plan_campaign_restrictions_that_cannot_be_read_or_met_are_one_line(capsys, ur10_urdf, extra, message):
    code, _, err = run(capsys, "plan-campaign", "--robot", ur10_urdf, "--tip-link", "tool0", "--n", "10",
                       "--candidates", "120", "--quiet", *extra)
    assert code == 2 and message in err and "Traceback" not in err and len(err.strip().splitlines()) == 1, err


def test_plan_campaign_says_when_fewer_candidates_pass_than_asked_for(capsys, ur10_urdf):
    code, text, err = run(capsys, "plan-campaign", "--robot", ur10_urdf, "--tip-link", "tool0", "--n", "10",
                          "--candidates", "100", "--inside-box", "-2m:2m,-2m:2m,1.2m:2m", "--quiet")
    assert code == 0, err
    kept = int(text.splitlines()[1].split()[1])
    assert 10 <= kept < 100 and text.splitlines()[1].startswith(f"kept {kept} of 1,000 candidates drawn: ")
    assert f"only {kept} of the 100 candidates asked for passed in 1,000 draws" in text
    assert f"over {kept} candidates" in text


def test_signing_key_writes_a_pair_and_never_overwrites_it(capsys, tmp_path):
    import os
    from tolerance_ros.core.calibration.provenance import load_public_keys, load_signing_key
    assert main(["signing-key", "--out", str(tmp_path / "keys"), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert oct(os.stat(doc["private_key"]).st_mode & 0o777) == "0o600"
    assert list(load_public_keys([doc["public_key"]])) == [doc["key_id"]]
    load_signing_key(doc["private_key"])
    assert main(["signing-key", "--out", str(tmp_path / "keys")]) == 2
    assert "exists; a key is never overwritten" in capsys.readouterr().err


def test_keystore_without_ros2_says_what_to_source(capsys, tmp_path, monkeypatch):
    monkeypatch.setenv("PATH", str(tmp_path))
    assert main(["keystore", "--out", str(tmp_path / "ks")]) == 2
    assert "`ros2` is not on PATH; source ROS 2 Jazzy with sros2 first" in capsys.readouterr().err
    assert not (tmp_path / "ks").exists()


@pytest.mark.parametrize("argv, needs", [
    (["allocate", "--robot", "gao2023_7dof", "--limit", "2mm"], (("zonotope",), ("dh",))),
    (["paper", "gao2023"], (("zonotope", "dh"), ())),
    (["paper", "rong2018"], (("pups", "zonotope"), ())),
    (["report", "--robot=robot.urdf", "poses.csv"], (("zonotope",), ("urdf",))),
    (["allocate", "--robot", "gao2023_7dof", "--criterion", "rss", "--limit", "2mm"], (("dh",), ())),
    (["allocate", "--robot", "gao2023_7dof", "--criterion=paper", "--limit", "2mm"], (("dh",), ())),
    (["calibrate", "--robot", "arm.URDF", "poses.csv"], (("urdf",), ())),
    (["jacobian", "--robot", "gao2023_7dof", "--q", "0,0,0,0,0,0,0"], (("dh",), ())),
])
def test_a_cold_start_compiles_first_what_the_command_waits_for(argv, needs):
    """The exact worst case first (2 s against the chain's 5 s, and its numpy path is the slower), the chain
    next; the chain alone for a command that bounds no budget or a criterion without the worst case; a
    paper's reproduction waits for both, the worst case first but for the 3-PUPS platform (its numpy path
    costs the most)."""
    assert kernel_needs(argv) == needs


def test_a_yaml_robot_of_urdf_kind_needs_the_urdf_kernels(tmp_path):
    robot = tmp_path / "arm.yaml"
    robot.write_text("kind: urdf\nurdf: arm.urdf\n")
    assert kernel_needs(["allocate", "--robot", str(robot), "--limit", "1mm"]) == (("zonotope",), ("urdf",))
    robot.write_text("kind: dh\n")
    assert kernel_needs(["allocate", "--robot", str(robot), "--limit", "1mm"]) == (("zonotope",), ("dh",))


def _commands():
    from tolerance_ros.cli.main import COMMANDS
    return [c.NAME for c in COMMANDS]


@pytest.mark.parametrize("command", _commands())
def test_every_commands_help_prints(capsys, command):
    """argparse formats each help with %: a bare % in a help text (``100 % of rated``) breaks --help."""
    from tolerance_ros.cli.main import build_parser
    with pytest.raises(SystemExit) as done:
        build_parser().parse_args([command, "--help"])
    assert done.value.code == 0 and f"tolerance-ros {command}" in capsys.readouterr().out


def test_report_exits_3_only_on_a_part_proven_out_and_names_it(capsys, tmp_path, gao):
    """A part 10x its tolerance is proven out (exit 3, named, the rule in the header); the same arm without that
    fault exits 0 with every part within or undecided; a rule that cannot be right is refused (exit 2)."""
    from tolerance_ros.core.accuracy.io import Measurements, write_csv
    from tolerance_ros.core.accuracy.simulate import as_built_errors, measure
    from tolerance_ros.core.budget import load_budget
    from tolerance_ros.core.geometry import transform
    delta = load_budget("gao2023_delta2", gao).vector_for(gao)
    q = np.tile(gao.sample_joints(30, 4), (3, 1))
    docs = {}
    for name, fault in (("within", 0.0), ("faulty", 10 * delta[gao.param_names.index("a3")])):
        dx = as_built_errors(delta, 5)
        dx[gao.param_names.index("a3")] = fault or dx[gao.param_names.index("a3")]
        T = measure(gao, q, dx, 1e-5, 1e-5, transform([1, 0, 0], [0, 0, 0.5]), seed=2)
        path = write_csv(tmp_path / f"{name}.csv", Measurements(np.arange(90.0), T, q, gao.joint_names,
                                                                 np.array([""] * 90, dtype=object), np.full(90, -1)))
        code, out, err = run(capsys, "report", "--robot", "gao2023_7dof", "--measurements", path, "--budget",
                             "gao2023_delta2", "--out", tmp_path / name)
        docs[name] = (code, out, err, json.loads((tmp_path / name / "report.json").read_text()))
    code, out, err, doc = docs["faulty"]
    assert code == 3 and "FAILED: 1 part(s) decided out of tolerance" in err.strip().splitlines()[-1]
    assert "a3" in err.splitlines()[-1] and "guarded:2" in err.splitlines()[-1]
    groups = doc["identification"]["groups"]
    a3 = next(g for g in groups["groups"] if g["parameters"][0] == "a3")
    assert a3["decision"] == "out" and a3["unit"] == "m" and {"error", "std", "tolerance"} <= set(a3)
    assert groups["rule"] == "guarded:2" and "2.3 %" in groups["rule_words"]
    md = (tmp_path / "faulty" / "report.md").read_text()
    assert "decision rule guarded:2" in md.split("## Registration")[0] and "| a3 | mm |" in md
    code, out, err, doc = docs["within"]
    assert code == 0, err
    assert {g["decision"] for g in doc["identification"]["groups"]["groups"]} <= {"within", "undecided"}
    code, _, err = run(capsys, "report", "--robot", "gao2023_7dof", "--measurements", tmp_path / "within.csv",
                       "--budget", "gao2023_delta2", "--decision-rule", "guarded:0")
    assert code == 2 and "--decision-rule" in err


def test_calibrate_judges_the_parts_it_identifies_against_a_budget(capsys, tmp_path, gao):
    """calibrate --budget: the same groups and rule as report; a part 10x its tolerance is decided out (exit 3,
    named), its section in calibration.md, and the calibration is still written."""
    from tolerance_ros.core.accuracy.io import Measurements, write_csv
    from tolerance_ros.core.accuracy.simulate import as_built_errors, measure
    from tolerance_ros.core.budget import load_budget
    from tolerance_ros.core.geometry import transform
    delta = load_budget("gao2023_delta2", gao).vector_for(gao)
    q = np.tile(gao.sample_joints(30, 4), (3, 1))
    dx = as_built_errors(delta, 5)
    dx[gao.param_names.index("d3")] = 10 * delta[gao.param_names.index("d3")]
    T = measure(gao, q, dx, 1e-5, 1e-5, transform([1, 0, 0], [0, 0, 0.5]), seed=2)
    path = write_csv(tmp_path / "m.csv", Measurements(np.arange(90.0), T, q, gao.joint_names,
                                                      np.array([""] * 90, dtype=object), np.full(90, -1)))
    code, out, err = run(capsys, "calibrate", "--robot", "gao2023_7dof", "--measurements", path, "--budget",
                         "gao2023_delta2", "--parameters", "full", "--folds", "3", "--out", tmp_path / "cal", "--json")
    assert code == 3 and "decided out of tolerance by the decision rule guarded:2: d3" in err.splitlines()[-1]
    doc = json.loads(out)
    assert [g["parameters"][0] for g in doc["budget"]["out_of_tolerance"]] == ["d3"]
    assert (tmp_path / "cal" / "calibration.yaml").exists()
    assert "## Against the budget gao2023_delta2" in (tmp_path / "cal" / "calibration.md").read_text()


def test_compensate_keeps_an_iso_campaigns_approaches_and_corrects_their_pre_poses(capsys, tmp_path, gao):
    """Issue 49: an --iso9283 --approach campaign compensated keeps each approach's of, approach and via; the
    pre-pose is corrected with its pose, so that the calibrated robot reaches the nominal pre-pose's tool pose."""
    import yaml
    from tolerance_ros.core.accuracy.simulate import as_built_errors, measure
    from tolerance_ros.core.budget import load_budget
    from tolerance_ros.core.calibration.calibrate import calibrate
    from tolerance_ros.core.calibration.calibration_file import load_calibration, save_calibration
    from tolerance_ros.core.campaign import load_campaign
    q = gao.sample_joints(30, 5)
    dx = as_built_errors(load_budget("gao2023_delta2", gao).vector_for(gao), 1)
    cal_file = save_calibration(calibrate(gao, q, measure(gao, q, dx, 1e-5, 0.0, None, seed=2), folds=3),
                                tmp_path / "calibration.yaml")
    iso, out_file = tmp_path / "iso.yaml", tmp_path / "iso_compensated.yaml"
    assert main(["plan-campaign", "--robot", "gao2023_7dof", "--iso9283", "--approach", "100mm", "--out", str(iso),
                 "--quiet"]) == 0
    capsys.readouterr()
    code, out, err = run(capsys, "compensate", "--robot", "gao2023_7dof", "--calibration", cal_file, "--poses", iso,
                         "--out", out_file, "--json", "--accept-flagged")
    assert code == 0, err
    given, written = load_campaign(iso, gao), load_campaign(out_file, gao)
    assert written.names == given.names and written.order == given.order
    approached = [k for k, tp in enumerate(given.poses) if tp.of is not None]
    assert len(approached) == 15
    cal = load_calibration(cal_file, gao)
    calibrated, nominal = cal.mechanism(gao), cal.nominal_at_tool_point(gao)
    for k in approached:
        g, w = given.poses[k], written.poses[k]
        assert (w.of, w.approach) == (g.of, g.approach)
        assert np.abs(w.via - g.via).max() > 1e-5                      # corrected, not copied
        np.testing.assert_allclose(calibrated.fk(w.via[None])[0], nominal.fk(g.via[None])[0], atol=1e-8)
        np.testing.assert_allclose(calibrated.fk(w.joints[None])[0], nominal.fk(g.joints[None])[0], atol=1e-8)
    assert json.loads(out)["poses"][approached[0]]["via"]["reached"]
    assert "via" in yaml.safe_load(out_file.read_text())["poses"][approached[0]]
