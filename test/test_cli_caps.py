"""Bounded commands: every count option has a cap, refused up front in one line naming the option."""
import json
import time

import numpy as np
import pytest

from helpers import run_cli as run
from tolerance_ros.cli.common import CAPS, SENSITIVITY_SAMPLES


def _refused(code, out, err, option, as_json=False):
    assert code == 2, err
    assert option in err and "cap" in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1, err
    if as_json:
        doc = json.loads(out)
        assert doc["ok"] is False and doc["error"]["code"] == "invalid_request" and option in doc["error"]["message"]


def test_jacobian_random_above_its_cap_is_refused_with_the_memory_it_would_need(capsys):
    n = CAPS["random"][0] + 1
    t0 = time.perf_counter()
    code, out, err = run(capsys, "jacobian", "--robot", "gao2023_7dof", "--random", str(n), "--json")
    _refused(code, out, err, "--random", as_json=True)
    assert "MB in memory" in err or "GB in memory" in err
    assert time.perf_counter() - t0 < 5  # refused before any work
    code, out, err = run(capsys, "jacobian", "--robot", "gao2023_7dof", "--random", "1000000")
    _refused(code, out, err, "--random")
    assert "GB in memory" in err


def test_jacobian_at_its_cap_is_served(capsys):
    code, out, err = run(capsys, "jacobian", "--robot", "gao2023_7dof", "--random", "3", "--json")
    assert code == 0, err
    assert np.shape(json.loads(out)["jacobian"]) == (3, 6, 28)


@pytest.mark.parametrize("argv, option", [
    (["plan-campaign", "--robot", "gao2023_7dof", "--n", str(CAPS["n"][0] + 1)], "--n"),
    (["plan-campaign", "--robot", "gao2023_7dof", "--candidates", str(CAPS["candidates"][0] + 1)], "--candidates"),
    (["plan-campaign", "--robot", "gao2023_7dof", "--n", "200", "--candidates", "20000"], "--n x --candidates"),
    (["plan-campaign", "--robot", "gao2023_7dof", "--n", "100000", "--candidates", "200000"], "--n"),
    (["sensitivity", "--robot", "gao2023_7dof", "--samples", str(SENSITIVITY_SAMPLES + 1)], "--samples"),
    (["verify", "--robot", "gao2023_7dof", "--tolerances", "missing.yaml", "--samples",
      str(CAPS["samples"][0] + 1)], "--samples"),
    (["paper", "gao2023", "--poses", str(CAPS["poses"][0] + 1)], "--poses"),
    (["allocate", "--robot", "gao2023_7dof", "--limit", "1mm", "--mc-poses", str(CAPS["mc_poses"][0] + 1)],
     "--mc-poses"),
    (["allocate", "--robot", "gao2023_7dof", "--limit", "1mm", "--ga-tol", str(CAPS["ga_tol"][0] + 1)], "--ga-tol"),
    (["allocate", "--robot", "gao2023_7dof", "--limit", "1mm", "--ga-rounds", str(CAPS["ga_rounds"][0] + 1)],
     "--ga-rounds"),
    (["calibrate", "--robot", "gao2023_7dof", "--measurements", "m.csv", "--out", "x", "--folds",
      str(CAPS["folds"][0] + 1)], "--folds"),
])
def test_counts_above_their_caps_are_refused_in_one_line(capsys, argv, option):
    t0 = time.perf_counter()
    code, out, err = run(capsys, *argv, "--json")
    _refused(code, out, err, option, as_json=True)
    assert time.perf_counter() - t0 < 5


def test_plan_campaign_more_poses_than_candidates_is_refused_up_front(capsys):
    code, _, err = run(capsys, "plan-campaign", "--robot", "gao2023_7dof", "--n", "50", "--candidates", "40")
    assert code == 2 and "--candidates >= 50" in err and len(err.strip().splitlines()) == 1
