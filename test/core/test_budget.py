"""Budget files: units, completeness, round trips."""
import time

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


def test_a_budget_with_a_20_mb_string_is_refused_by_the_size_cap_at_once(gao, tmp_path):
    p = _write(tmp_path, "tolerances: {a1: 0.001}\nsource: '" + "x" * 20_000_000 + "'\n")
    t0 = time.perf_counter()
    with pytest.raises(BudgetError, match=rf"^{p}: 20000035 bytes; a YAML file may have at most 4194304 bytes"):
        load_budget(p, gao)
    assert time.perf_counter() - t0 < 0.1


@pytest.mark.parametrize("text, message", [
    ("tolerances: {a1: 0.001, a1: 0.002}\n", r", line 1: key 'a1' given twice in one mapping"),
    ("units: {length: mm}\ntolerances: {a1: 1_000}\ndefault: 0\n", r", line 2: '1_000' is a number with digit"),
    (b"source: \xff\ntolerances: {a1: 0.001}\n", r", line 1, column 9: not UTF-8 text"),
])
def test_budget_yaml_that_would_change_a_value_is_refused_with_the_line(gao, tmp_path, text, message):
    p = tmp_path / "b.yaml"
    p.write_bytes(text if isinstance(text, bytes) else text.encode())
    with pytest.raises(BudgetError, match=rf"^{p}{message}"):
        load_budget(p, gao)


def test_json_budgets_refuse_duplicate_keys_and_deep_nesting(gao, tmp_path):
    p = tmp_path / "b.json"
    p.write_text('{"tolerances": {"a1": 0.001, "a1": 0.002}, "default": 0}')
    with pytest.raises(BudgetError, match=rf"^{p}: key 'a1' given twice"):
        load_budget(p, gao)
    p.write_text('{"tolerances": {"a1": 0.001}, "default": 0, "meta": ' + "[" * 100_000 + "]" * 100_000 + "}")
    with pytest.raises(BudgetError, match=rf"^{p}: nested deeper than 32 levels"):
        load_budget(p, gao)


def test_a_budget_for_another_robot_says_so_before_its_fields(gao, tmp_path):
    """A UR10 budget given for the gao2023 arm: the robot named, not one of its parameters."""
    p = tmp_path / "ur10_budget.yaml"
    p.write_text("robot: ur10\nunits: {length: mm, angle: mrad}\n"
                 "tolerances: {shoulder_pan_joint.offset: 0.1, shoulder_pan_joint.x: 0.01}\n")
    with pytest.raises(BudgetError, match=r"this budget is for robot 'ur10', not 'gao2023_7dof'$"):
        load_budget(p, gao)


def test_a_tolerance_no_part_is_made_to_is_refused(gao, tmp_path):
    from tolerance_ros.core.budget import BudgetError, load_budget
    path = tmp_path / "b.yaml"
    path.write_text("robot: gao2023_7dof\nunits: {length: m, angle: rad}\ntolerances: {a1: 1e300}\ndefault: 0\n")
    with pytest.raises(BudgetError, match=r"tolerances.a1: 1e\+300 is beyond 1 m"):
        load_budget(path, gao)
    path.write_text("robot: gao2023_7dof\nunits: {length: mm, angle: rad}\nlimit: {position: 2001-12-14}\n"
                    "tolerances: {a1: 0.05}\ndefault: 0\n")
    with pytest.raises(BudgetError, match="is a date"):
        load_budget(path, gao)


@pytest.mark.parametrize("edit, message", [
    (("length: mm", "length: m"), r"the position limit 1400 mm is 139 % of the robot's size \(gao2023_7dof's reach "
                                  r"is 1 m\).*a length unit off"),
    (("limit: {position: 1.4}", "limit: {position: 1.4, orientation: 2.0}"), "orientation limit 2 rad.*an angle unit off"),
    (("alpha1: ", "alpha1: 0.2 #"), r"tolerances.alpha1: 0.2 rad is beyond 0.1 rad"),
    (("a1: ", "a1: 70 #"), r"tolerances.a1: 70 mm is 6.97 % of the robot's size"),
])
def test_limits_and_tolerances_implausible_for_the_robots_size_are_refused(gao, tmp_path, edit, message):
    """A budget whose length unit was changed from mm to m (a 1.4 m limit on a 1 m arm), an orientation limit or
    a tolerance no robot is designed to: refused naming the value, the robot's size and the likely slip."""
    from tolerance_ros.core.resources import resolve
    text = resolve("budgets", "gao2023_delta2", suffixes=(".yaml",)).read_text()
    assert edit[0] in text
    path = tmp_path / "b.yaml"
    path.write_text(text.replace(edit[0], edit[1], 1))
    with pytest.raises(BudgetError, match=message):
        load_budget(path, gao)
    assert load_budget("gao2023_delta2", gao).problem_for(gao) is None
