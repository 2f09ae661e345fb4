"""The paper's figures reproduced (Gao et al. 2023): what matches exactly, and the documented bands."""
import numpy as np
import pytest

from tolerance_ros.papers import gao2023


@pytest.fixture(scope="module")
def progress():
    return []


@pytest.fixture(scope="module")
def res(progress):
    return gao2023.reproduce(n_poses=10000, m_salience=1000, progress=lambda done, total: progress.append((done, total)))


def test_the_progress_starts_with_the_reproduction_and_ends_at_its_end(res, progress):
    """Its first call comes before the first step (the heartbeat moves through a cold start's model loading)."""
    assert progress[0] == (0, 4) and progress[-1] == (4, 4)
    assert [d for d, _ in progress] == sorted(d for d, _ in progress)


def test_fig2_salience(res):
    s = res["salience"]
    assert s["angle_ranking"]["match"]
    assert max(s["alpha7_theta7"]["reproduced"]) < 1e-12
    assert s["lengths_equal"]["match"]


def test_table3_ceilings_match_to_the_printed_digit(res):
    for c in res["ceilings"]:
        assert round(c["reproduced"], 4) == pytest.approx(c["published"]), c["parameter"]
    assert res["ceilings_lengths_m"]["reproduced"] == [pytest.approx(1.4e-3)]


def test_figures_are_si_like_every_json_document(res):
    assert res["units"] == "m and rad"
    assert res["table4"]["delta1"]["published"]["max"] == pytest.approx(1.4845e-3)
    assert 0.3e-3 < res["table4"]["delta2"]["reproduced"]["mean"] < 0.7e-3


def test_cost_indices(res):
    assert res["table4"]["delta2"]["reproduced"]["cost"] == pytest.approx(44736, abs=1)
    # delta_1's printed tolerances are rounded; the index moves by 0.03 %.
    assert res["table4"]["delta1"]["reproduced"]["cost"] == pytest.approx(34459, rel=5e-4)


def test_correlations(res):
    for c in res["correlations"]:
        assert c["reproduced"] == pytest.approx(c["published"], abs=0.06), c["parameters"]
    assert len(res["correlated_pairs"]) == 8


def test_table4_delta2_within_the_rounding_band(res):
    t = res["table4"]["delta2"]
    for k in ("max", "mean", "std"):
        lo, hi = sorted((t["rounding_band"]["low"][k], t["rounding_band"]["high"][k]))
        assert lo <= t["published"][k] <= hi, k
    assert t["reproduced"]["pass_rate"] == 1.0


def test_chosen_interpretation_is_the_best_tried(res):
    best = res["interpretation_study"][0]
    assert best["joint_range"].startswith("full turn") and best["errors"].startswith("all +delta")
    assert best["mean_relative_deviation"] < 0.10


def test_sign_control_lowers_the_mean_error_as_published(res):
    for key in ("delta1", "delta2"):
        before, after = res["table4"][key]["reproduced"], res["table5"][key]["reproduced"]
        assert after["mean"] < before["mean"] and after["max"] < before["max"]
        ratio = after["mean"] / before["mean"]
        published = res["table5"][key]["published"]["mean"] / res["table4"][key]["published"]["mean"]
        assert ratio == pytest.approx(published, abs=0.04)


def test_differences_are_reported(res):
    assert any("delta1 mean" in n for n in res["not_reproduced"])


def test_synthesis_study_beats_both_published_sets(gao):
    import numpy as np
    from tolerance_ros.core.analysis import monte_carlo
    from tolerance_ros.core.budget import load_budget
    syn = gao2023.synthesis_study(seed=1, n_mc=3000)
    sets = syn["sets"]
    # One Monte Carlo sample: the synthesis verifies delta_1 on the very poses Table 4 uses with that seed.
    table4 = monte_carlo(gao, load_budget("gao2023_delta1", gao).vector_for(gao), distribution="fixed",
                         q=gao.sample_joints(3000, np.random.default_rng(1)), limit_position=1.4e-3)
    again = sets["published delta1"]["verification"]["monte_carlo"]["position_m"]
    assert (again["max"], again["mean"], again["pass_rate"]) == (table4.summary["position"]["max"],
                                                                  table4.summary["position"]["mean"],
                                                                  table4.summary["position"]["pass_rate"])
    best = sets["active-set min-cost"]
    assert best["success"] and best["cost"] < sets["published delta1"]["cost"] < sets["published delta2"]["cost"]
    assert best["verification"]["supremum"]["paper"]["position"]["value"] <= 1.4e-3
    assert best["verification"]["monte_carlo"]["poses"] == 3000
    assert best["verification"]["monte_carlo"]["position_m"]["pass_rate"] == 1.0
    # It exploits cancellation of errors of opposite effect, and says so.
    assert best["verification"]["supremum"]["worst-case"]["position"]["value"] > 1.4e-3
    assert any("cancel" in w for w in best["warnings"])
    assert set(syn["free"]) == {"alpha7", "theta7"}
    # The published sets are checked with the same search: neither stays within 1.4 mm everywhere.
    for key in ("published delta1", "published delta2"):
        assert sets[key]["verification"]["supremum"]["paper"]["position"]["value"] > 1.4e-3
    assert sets["active-set optimal-precision"]["index_I_m"] < sets["published delta2"]["index_I_m"]
    # The README's table is this study printed as Markdown: one row per set, with the figures above.
    md = gao2023.synthesis_markdown(syn).splitlines()
    assert len(md) == 2 + len(sets)
    row = next(line for line in md if line.startswith("| active-set, min-cost |")).split(" | ")
    assert row[2] == f"{best['cost']:.0f}" and row[-1] == "100.00 % |"
    delta1 = next(line for line in md if line.startswith("| published delta_1"))
    assert "(34459 printed)" in delta1


@pytest.mark.parametrize("kind", ["optimal-precision", "min-cost"])
def test_the_main_jobs_allocation_is_the_same_on_the_compiled_and_the_numpy_path(kind, monkeypatch):
    """`paper gao2023`'s active-set allocations computed with the compiled kernels and with the numpy reference
    (what a first run on a cold kernel cache serves): the same tolerances and cost to the printed digits
    (a tie between equally precise sets is broken by the cost, never by rounding)."""
    from tolerance_ros.core.models import kernels
    from tolerance_ros.core.synthesis import allocate
    model = gao2023.load_robot(gao2023.ROBOT)
    problem = gao2023.build_problem(model, gao2023.LIMIT, criterion="paper", seed=2023)
    runs = {}
    for path in ("compiled", "numpy"):
        if path == "numpy":
            monkeypatch.setattr(kernels, "_unavailable", True)
        else:
            assert kernels.get("dh") is not None
        res = allocate(model, problem.limit, kind, "active-set", problem=problem, seed=2023, verify=False)
        runs[path] = (res.delta, res.cost)
    printed = np.where(np.array(model.param_kinds) == "length", 1e3, 1.0)   # Table 3: mm and rad, 4 decimals
    np.testing.assert_allclose(runs["compiled"][0], runs["numpy"][0], rtol=1e-4, atol=0)
    np.testing.assert_array_equal(np.round(runs["compiled"][0] * printed, 4), np.round(runs["numpy"][0] * printed, 4))
    assert round(runs["compiled"][1]) == round(runs["numpy"][1])
