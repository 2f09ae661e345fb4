"""The exact solver: feasibility over a dense grid of the whole joint space, and optimality against a
relaxation (the same program over the grid subsample, which can only be cheaper)."""
import numpy as np
import pytest
from scipy.optimize import minimize

from tolerance_ros.core.models import DHChain
from tolerance_ros.core.synthesis import SynthesisError, build_problem
from tolerance_ros.core.synthesis.active_set import solve_active_set


@pytest.fixture(scope="module")
def arm():
    """Planar-ish 2R arm with a twist, so that lengths, twists and angles all matter."""
    return DHChain("twisted2r", a=[0.4, 0.3], alpha=[0.3, 0.0], d=[0.1, 0.05], theta=[0, 0])


def grid(model, n=201):
    g = np.linspace(-np.pi, np.pi, n)
    return np.stack(np.meshgrid(g, g), -1).reshape(-1, 2)


def relaxed_cost(problem, q):
    """Optimal min-cost over a finite pose set (a lower bound of the true optimum)."""
    a = problem.active
    J = problem.model.error_jacobian(q).position[:, :, a]
    tau, hi = problem.floors[a], problem.ceilings[a]
    unit = np.array([1e3 if k == "length" else 1.0 for k in np.array(problem.model.param_kinds)[a]])
    K = problem.K[a]
    M = np.einsum("nkp,nkq->npq", J * tau, J * tau) / problem.limit ** 2
    res = minimize(lambda x: np.sum(K / (tau * unit * x)), np.ones(a.sum()), method="SLSQP",
                   bounds=list(zip(np.ones(a.sum()), hi / tau)),
                   constraints=[{"type": "ineq", "fun": lambda x: 1 - np.einsum("p,npq,q->n", x, M, x)}],
                   options={"maxiter": 500, "ftol": 1e-14})
    return float(res.fun)


@pytest.mark.parametrize("criterion", ["paper", "worst-case", "rss"])
def test_allocation_is_feasible_over_a_dense_grid(arm, criterion):
    p = build_problem(arm, 1e-3, criterion=criterion, floors={"length": 1e-5, "angle": 1e-5}, samples=2000)
    res = solve_active_set(p, "min-cost", n_check=3000)
    assert res["status"] == "converged"
    q = grid(arm)
    J = arm.error_jacobian(q).position
    values = p.values(J, res["delta"])
    assert values.max() <= 1e-3 * (1 + 1e-6)
    assert values.max() >= 1e-3 * (1 - 1e-4)  # the limit is active: nothing left on the table
    assert np.all(res["delta"][p.active] >= p.floors[p.active] * (1 - 1e-12))
    assert np.all(res["delta"][p.active] <= p.ceilings[p.active] * (1 + 1e-12))


def test_min_cost_is_optimal_against_the_grid_relaxation(arm):
    p = build_problem(arm, 1e-3, criterion="paper", floors={"length": 1e-5, "angle": 1e-5}, samples=2000)
    res = solve_active_set(p, "min-cost", n_check=3000)
    lower = relaxed_cost(p, grid(arm, 61))
    assert lower <= p.cost(res["delta"]) * (1 + 1e-6)
    assert p.cost(res["delta"]) <= lower * 1.01


def test_optimal_precision_maximises_the_weighted_tolerances(arm):
    p = build_problem(arm, 1e-3, floors={"length": 1e-5, "angle": 1e-5}, samples=2000)
    prec = solve_active_set(p, "optimal-precision", n_check=3000)["delta"]
    cost = solve_active_set(p, "min-cost", n_check=3000)["delta"]
    assert p.index_I(prec) <= p.index_I(cost) + 1e-12
    assert p.cost(cost) <= p.cost(prec) + 1e-9


def test_orientation_limit_is_respected():
    arm = DHChain("spatial3r", a=[0.0, 0.4, 0.3], alpha=[np.pi / 2, 0.0, 0.0], d=[0.3, 0.0, 0.0], theta=[0, 0, 0])
    p = build_problem(arm, 1e-3, orientation_limit=1e-3, floors={"length": 1e-5, "angle": 1e-5}, samples=3000)
    res = solve_active_set(p, "min-cost", n_check=4000)
    q = arm.sample_joints(20000, 99)
    EJ = arm.error_jacobian(q)
    assert p.values(EJ.orientation, res["delta"]).max() <= 1e-3 * (1 + 1e-6)
    assert p.values(EJ.position, res["delta"]).max() <= 1e-3 * (1 + 1e-6)


def test_infeasible_problem_names_the_floors(arm):
    p = build_problem(arm, 1e-4, criterion="paper", floors={"length": 5e-5, "angle": 1e-4}, samples=2000)
    with pytest.raises(SynthesisError, match=r"infeasible: with every tolerance at its floor the paper position "
                                             r"error reaches \d\.\d+ mm \(limit 0\.1 mm\).*contribute most there: "
                                             r"lower the floors \(--floor-length"):
        solve_active_set(p, "min-cost", n_check=2000)


def test_worst_case_at_the_paper_floors_is_infeasible(gao):
    p = build_problem(gao, 1.4e-3, criterion="worst-case", samples=5000)
    with pytest.raises(SynthesisError, match="worst-case position error reaches"):
        solve_active_set(p, "min-cost")


def test_progress_moves_through_the_feasibility_search_the_iterations_and_the_verification(arm):
    """Progress never goes back, moves during the feasibility search (before the first iteration), moves at
    every iteration, stays within the solve's share until the verification, and ends at 100 %."""
    from tolerance_ros.core.synthesis import SOLVE_SHARE, allocate
    calls = []
    res = allocate(arm, 1e-3, criterion="worst-case", floors={"length": 1e-5, "angle": 1e-5}, n_mc=500,
                   progress=lambda done, total: calls.append(done / total))
    assert res.status == "converged"
    assert calls == sorted(calls) and calls[-1] == 1.0
    iterations = len(res.history)
    solve = [f for f in calls if f <= SOLVE_SHARE]
    assert len([f for f in solve if f <= 0.2 * SOLVE_SHARE]) >= 5                  # the feasibility search
    assert len(set(solve)) >= iterations + 5
    assert len({f for f in calls if SOLVE_SHARE < f < 1.0}) >= 5                  # the verification's searches
