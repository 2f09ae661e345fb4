"""Budget files: units, completeness, round trips."""
import numpy as np
import pytest

from tolerance_ros.core.budget import Budget, BudgetError, load_budget


def test_shipped_paper_sets(gao):
    b = load_budget("gao2023_delta1", gao)
    d = b.vector_for(gao)
    assert d[0] == pytest.approx(0.0996e-3) and d[gao.param_index(["theta6"])[0]] == pytest.approx(0.0048)
    assert b.limit_position == pytest.approx(1.4e-3) and b.criterion == "paper"


@pytest.mark.parametrize("suffix", [".yaml", ".json"])
def test_round_trip(gao, tmp_path, suffix):
    d = np.linspace(1e-5, 1e-3, gao.n_params)
    b = Budget.from_vector(gao, d, limit_position=1.4e-3, limit_orientation=2e-3, criterion="worst-case")
    kinds = dict(zip(gao.param_names, gao.param_kinds))
    path = b.save(tmp_path / f"b{suffix}", units={"length": "mm", "angle": "deg"}, kinds=kinds)
    back = load_budget(path, gao)
    assert np.allclose(back.vector_for(gao), d, rtol=1e-12)
    assert back.limit_position == pytest.approx(1.4e-3) and back.limit_orientation == pytest.approx(2e-3)
    assert back.criterion == "worst-case"


def _write(tmp_path, text):
    p = tmp_path / "b.yaml"
    p.write_text(text)
    return p


def test_missing_unknown_and_negative_tolerances_are_errors(gao, tmp_path):
    with pytest.raises(BudgetError, match=r"no tolerance for \['a2'"):
        load_budget(_write(tmp_path, "tolerances: {a1: 0.001}\n"), gao).vector_for(gao)
    with pytest.raises(BudgetError, match="unknown parameter name.*bogus"):
        load_budget(_write(tmp_path, "tolerances: {bogus: 0.001}\ndefault: 0\n"), gao).vector_for(gao)
    with pytest.raises(BudgetError, match="tolerances.a1: must be >= 0"):
        load_budget(_write(tmp_path, "tolerances: {a1: -1}\n"), gao)
    with pytest.raises(BudgetError, match="limit.position: must be > 0"):
        load_budget(_write(tmp_path, "tolerances: {a1: 1}\nlimit: {position: 0}\n"), gao)
    with pytest.raises(BudgetError, match="units.length"):
        load_budget(_write(tmp_path, "units: {length: inch}\ntolerances: {a1: 1}\n"), gao)
    with pytest.raises(BudgetError, match="not 'gao2023_7dof'"):
        load_budget(_write(tmp_path, "robot: other\ntolerances: {a1: 1}\n"), gao)
    with pytest.raises(BudgetError, match="unknown key"):
        load_budget(_write(tmp_path, "tolerance: {a1: 1}\n"), gao)


def test_default_zero_fills_unlisted(gao, tmp_path):
    b = load_budget(_write(tmp_path, "units: {length: mm}\ntolerances: {a1: 0.1}\ndefault: 0\n"), gao)
    d = b.vector_for(gao)
    assert d[0] == pytest.approx(1e-4) and np.all(d[1:] == 0)


def test_free_parameters_count_as_zero_and_round_trip(gao, tmp_path):
    d = np.full(gao.n_params, 1e-4)
    free = np.array([n in ("alpha7", "theta7") for n in gao.param_names])
    b = Budget.from_vector(gao, d, free=free, limit_position=1e-3)
    path = b.save(tmp_path / "b.json")
    back = load_budget(path, gao)
    assert back.free == ("alpha7", "theta7")
    v = back.vector_for(gao)
    assert np.all(v[free] == 0) and np.allclose(v[~free], 1e-4)
    with pytest.raises(BudgetError, match="either free or toleranced"):
        load_budget(_write(tmp_path, "tolerances: {a1: 1}\nfree: [a1]\n"), gao)
