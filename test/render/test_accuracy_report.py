"""The written accuracy report: its files hold the numbers of the evaluation they were written from."""
import csv
import json

import numpy as np
import pytest

from tolerance_ros.core.accuracy.evaluation import evaluate_file
from tolerance_ros.core.accuracy.io import Measurements
from tolerance_ros.core.accuracy.simulate import as_built_errors, measure
from tolerance_ros.core.budget import load_budget
from tolerance_ros.core.campaign import Campaign, TestPose
from tolerance_ros.render.accuracy_report import write_report


@pytest.fixture(scope="module")
def evaluated(gao):
    budget = load_budget("gao2023_delta2", gao)
    qk = gao.sample_joints(3, 1)
    camp = Campaign("c", [TestPose(f"P{i + 1}", joints=qk[i]) for i in range(3)], cycles=10)
    q = np.tile(qk, (10, 1))
    T = measure(gao, q, as_built_errors(budget.vector_for(gao), 2), 1e-5, 1e-5, seed=3)
    labels = np.array([f"P{i % 3 + 1}" for i in range(30)], dtype=object)
    meas = Measurements(np.arange(30.0), T, q, gao.joint_names, labels, np.arange(30) // 3)
    return evaluate_file(gao, meas, budget, camp), budget


def test_report_files_hold_the_evaluated_numbers(gao, evaluated, tmp_path):
    res, budget = evaluated
    files = write_report(res, tmp_path, gao, budget)
    doc = json.loads((tmp_path / "report.json").read_text())
    assert doc["measurements"] == 30 and doc["summary"]["verdicts"] == res["summary"]["verdicts"]
    with open(files["measurements_csv"]) as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 30
    np.testing.assert_allclose([float(r["error[m]"]) for r in rows], res["rows"]["error"], rtol=1e-8)
    assert [r["verdict"] for r in rows] == list(res["rows"]["verdict"])
    with open(files["per_pose_csv"]) as fh:
        per = {r["pose"]: r for r in csv.DictReader(fh)}
    assert float(per["P2"]["AP_p[m]"]) == pytest.approx(res["per_pose"]["P2"]["AP_p"])
    md = (tmp_path / "report.md").read_text()
    assert md.startswith("# Accuracy report: gao2023_7dof")
    assert f"{res['per_pose']['P1']['AP_p'] * 1e3:.4f}" in md
    assert f"mean {res['summary']['position_error_m']['mean'] * 1e3:.4f} mm" in md
    for p in files["plots"]:
        assert (tmp_path / p.split("/")[-1]).stat().st_size > 1000
    with open(files["identification_csv"]) as fh:
        ident = list(csv.DictReader(fh))
    assert [r["parameter"] for r in ident] == list(gao.param_names)
