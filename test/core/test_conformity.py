"""Decisions of conformity (issue 47): a part is out only where its estimate proves it out, within only where it
proves it within, undecided otherwise; the rule and its risk said."""
import math

import numpy as np
import pytest

from tolerance_ros.core.conformity import DecisionRule, counts, parameter_groups


@pytest.mark.parametrize("text, kind, k", [("guarded", "guarded", 2.0), ("guarded:2", "guarded", 2.0),
                                            ("Guarded:1.5", "guarded", 1.5), ("simple", "simple", 0.0)])
def test_rules_are_read_from_their_names(text, kind, k):
    rule = DecisionRule.parse(text)
    assert (rule.kind, rule.k) == (kind, k)
    assert DecisionRule.parse(str(rule)) == rule


@pytest.mark.parametrize("text", ["guarded:0", "guarded:-1", "guarded:nan", "guarded:x", "guarded:11", "strict", ""])
def test_a_rule_that_cannot_be_right_is_refused_by_name(text):
    with pytest.raises(ValueError, match="decision rule"):
        DecisionRule.parse(text)


def test_guarded_decisions_at_and_about_the_guard_bands():
    rule = DecisionRule.parse("guarded:2")
    tol, u = 1.0, 0.1
    # out only beyond tolerance + 2u, within only below tolerance - 2u, whatever the sign
    assert rule.decide(1.21, u, tol) == "out" and rule.decide(-1.21, u, tol) == "out"
    assert rule.decide(1.19, u, tol) == "undecided" and rule.decide(1.05, u, tol) == "undecided"
    assert rule.decide(0.81, u, tol) == "undecided" and rule.decide(0.79, u, tol) == "within"
    assert rule.decide(-0.5, u, tol) == "within"
    assert rule.decide(5.0, u, math.inf) == "free"
    assert rule.decide(float("nan"), u, tol) == "undecided" and rule.decide(0.1, float("nan"), tol) == "undecided"
    got = rule.decide(np.array([0.0, 1.1, 2.0]), np.array([0.1, 0.1, 0.1]), np.array([1.0, 1.0, 1.0]))
    assert list(got) == ["within", "undecided", "out"]


def test_the_simple_rule_decides_every_part_and_says_its_risk():
    rule = DecisionRule.parse("simple")
    assert rule.decide(1.01, 0.5, 1.0) == "out" and rule.decide(0.99, 0.5, 1.0) == "within"
    assert rule.risk() == 0.5 and "50 %" in rule.words()


def test_the_guarded_rules_risk_is_the_normal_tail_beyond_its_guard():
    assert DecisionRule.parse("guarded:2").risk() == pytest.approx(0.02275, abs=1e-5)
    assert DecisionRule.parse("guarded:3").risk() == pytest.approx(0.00135, abs=1e-5)
    assert "2.3 %" in DecisionRule.parse("guarded:2").words()


def test_a_group_takes_the_worst_case_of_every_member_and_names_those_that_matter():
    names, kinds = ["a", "b", "c", "d"], ["length", "angle", "angle", "length"]
    delta = np.array([1e-4, 1e-3, 1e-3, np.inf])
    dx, std = np.array([3e-4, 0.0, 0.0, 1.0]), np.array([1e-5, 0.0, 0.0, 1e-5])
    aliases = {"a": {"b": 0.05, "c": 2e-3}}  # c moves a's group by 2e-6 m: 2 % of a's own 1e-4 m, named
    g = parameter_groups(names, kinds, dx, std, ["b", "c"], aliases, delta)
    a = next(x for x in g if x["parameters"][0] == "a")
    assert a["tolerance"] == pytest.approx(1e-4 + 0.05 * 1e-3 + 2e-3 * 1e-3)
    assert a["parameters"] == ["a", "b", "c"] and a["unit"] == "m" and a["decision"] == "out"
    aliases = {"a": {"b": 0.05, "c": 5e-4}}  # c now moves it by 0.5 %: not named, still counted
    a = next(x for x in parameter_groups(names, kinds, dx, std, ["b", "c"], aliases, delta)
             if x["parameters"][0] == "a")
    assert a["parameters"] == ["a", "b"] and a["tolerance"] == pytest.approx(1e-4 + 5e-5 + 5e-7)
    d = next(x for x in g if x["parameters"][0] == "d")
    assert d["decision"] == "free" and [x["decision"] for x in g] == ["out", "free"]
    assert counts(x["decision"] for x in g) == {"within": 0, "out": 1, "undecided": 0, "free": 1}


def test_a_part_the_data_do_not_determine_is_never_decided():
    """A near-copy of another parameter, or an estimate beyond any build error (a fit that wandered), is undecided
    whatever it reads, with why; the rest is decided as usual."""
    from tolerance_ros.core.conformity import judged
    names, kinds = ["a", "b", "c"], ["length", "angle", "angle"]
    dx, std = np.array([3e-4, -1.24, 5e-4]), np.array([1e-5, 1e-2, 1e-5])
    delta = np.array([1e-4, 0.0, 1e-4])
    g = {x["parameters"][0]: x for x in judged(names, kinds, dx, std, [], {}, delta, reach=1.0,
                                               undetermined={"a": "a near-copy of c"})["groups"]}
    assert g["a"]["decision"] == "undecided" and g["a"]["note"] == "a near-copy of c"
    assert g["b"]["decision"] == "undecided" and "beyond any build error" in g["b"]["note"]
    assert g["c"]["decision"] == "out" and g["c"]["note"] is None
    assert judged(names, kinds, dx, std, [], {}, delta)["groups"][0]["decision"] == "out"   # b, without the reach
