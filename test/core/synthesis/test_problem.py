"""Allocation problems: ceilings, floors, costs and input errors."""
import numpy as np
import pytest

from tolerance_ros.core.synthesis import SynthesisError, build_problem


def test_paper_ceilings_and_free_parameters(gao):
    p = build_problem(gao, 1.4e-3, samples=5000)
    names = list(gao.param_names)
    expected = {"alpha1": 0.0014, "alpha2": 0.0015, "alpha3": 0.0025, "alpha4": 0.0027, "alpha5": 0.0088,
                "alpha6": 0.0154}
    for n, v in expected.items():
        assert round(p.ceilings[names.index(n)], 4) == pytest.approx(v)
    assert np.allclose(p.ceilings[:14], 1.4e-3)
    assert not p.active[names.index("alpha7")] and not p.active[names.index("theta7")]
    assert p.floors[0] == pytest.approx(0.05e-3) and p.floors[14] == pytest.approx(3e-4)


def test_cost_and_index_match_the_paper_units(gao):
    p = build_problem(gao, 1.4e-3, samples=2000)
    d = np.where(np.array(gao.param_kinds) == "length", 0.1e-3, 0.001)
    # 14 lengths at 0.1 mm cost 1/0.1 each; 12 active angles at 1 mrad cost 1.5/0.001 each.
    assert p.cost(d) == pytest.approx(14 * 10 + 12 * 1500)
    assert p.index_I(p.ceilings) == pytest.approx(0.0)
    assert p.index_I(p.floors) > p.index_I(d) > 0


@pytest.mark.parametrize("kwargs, message", [
    (dict(limit=0.0), "limit"),
    (dict(limit=-1e-3), "limit"),
    (dict(limit=1e-3, criterion="median"), "criterion"),
    (dict(limit=1e-3, floors={"nope": 1e-5}), "unknown parameter name"),
    (dict(limit=1e-3, floors={"angle": 0.0}), "floors: must be > 0"),
    (dict(limit=1e-3, orientation_limit=-1.0), "orientation_limit"),
    (dict(limit=1.4e-3, floors={"theta1": 0.01}), "floors above ceilings: theta1"),
])
def test_bad_problems_name_the_cause(gao, kwargs, message):
    with pytest.raises(SynthesisError, match=message):
        build_problem(gao, samples=1000, **kwargs)


def test_the_allocation_reports_progress_before_its_ceilings_search(gao, monkeypatch):
    """The progress starts with the job (its heartbeat then moves through the ceilings' search, a few seconds
    on a cold start), not after the ceilings."""
    from tolerance_ros.core import synthesis
    events = []
    real = synthesis.build_problem

    def build(*args, **kwargs):
        events.append("ceilings")
        return real(*args, **kwargs)
    monkeypatch.setattr(synthesis, "build_problem", build)
    monkeypatch.setattr(synthesis, "solve_active_set", lambda problem, *a, **k: events.append("solve") or {
        "delta": problem.floors.copy(), "status": "converged", "message": "", "history": []})
    synthesis.allocate(gao, 2e-3, progress=lambda done, total: events.append(("progress", done)), verify=False)
    assert events[0] == ("progress", 0) and events.index("ceilings") < events.index("solve")
