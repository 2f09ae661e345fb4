"""The exact solver: feasibility over a dense grid of the whole joint space, and optimality against a
relaxation (the same program over the grid subsample, which can only be cheaper)."""
from pathlib import Path

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


IRB4600 = Path(__file__).resolve().parents[2] / "data" / "abb_irb4600" / "abb_irb4600_60_205.urdf"


@pytest.mark.parametrize("top", [1, 12, 40])
def test_the_pruned_worst_cases_hold_the_exact_largest_ones(top):
    """_values(top=k) computes the exact worst case only where it can rank among the k largest: its k
    largest entries are those of the full exact evaluation (the same poses, the same values), every other
    entry is a lower bound, and so is below them; most poses are left out."""
    from tolerance_ros.core.errors import worst_case_bound
    from tolerance_ros.core.models import load_robot
    from tolerance_ros.core.synthesis.active_set import _values
    robot = load_robot(str(IRB4600))
    p = build_problem(robot, 8e-3, samples=2000)
    rng = np.random.default_rng(5)
    J = robot.error_jacobian(robot.sample_joints(6000, rng)).position[:, :, p.active]
    for _ in range(3):
        delta = p.floors[p.active] * rng.uniform(1.0, 8.0, p.active.sum())
        exact = worst_case_bound(J, delta)
        calls = []
        pruned = _values(p, J, delta, top=top, tick=lambda: calls.append(1))
        order = np.argsort(-exact, kind="stable")[:top]
        assert np.array_equal(np.argsort(-pruned, kind="stable")[:top], order)
        assert np.allclose(pruned[order], exact[order], rtol=1e-8, atol=0)  # a pose's candidate signs are
        assert np.all(pruned <= exact * (1 + 1e-8))  # chosen on its own perturbation: exact within 2e-9
        assert 0 < len(calls) * 256 < len(J) / 4  # the exact kernel ran on a small share of the poses


def test_a_38_parameter_worst_case_allocation_is_the_optimum_of_an_independent_solver():
    """The ABB IRB 4600 (38 active parameters), worst case, 8 mm: the active-set answer is feasible over the
    joint space (a fresh multi-start search finds nothing above the limit) and costs no more than the
    optimum of the relaxation on the poses where it is active (their worst-case signs at the answer), solved
    independently by scipy's trust-constr (an interior-point method, not SLSQP): the relaxation can only be
    cheaper than the true optimum, so the answer is that optimum to 1e-6."""
    from scipy.optimize import Bounds, NonlinearConstraint
    from tolerance_ros.core.errors import worst_case_bound
    from tolerance_ros.core.models import load_robot
    from tolerance_ros.core.synthesis.search import maximize
    robot, limit = load_robot(str(IRB4600)), 8e-3
    p = build_problem(robot, limit)
    a = p.active
    assert a.sum() == 38
    res = solve_active_set(p, "min-cost")
    d = res["delta"]
    assert res["status"] == "converged"
    found = maximize(robot, lambda q: p.values(robot.error_jacobian(q).position, d), n_samples=20000, n_starts=30,
                     seed=11)
    assert found.value <= limit * (1 + 1e-9)
    poses = found.maxima_q[found.maxima > limit * (1 - 1e-4)]
    assert len(poses) >= 3
    J = robot.error_jacobian(poses).position[:, :, a]
    _, signs = worst_case_bound(J, d[a], return_signs=True)
    tau = p.floors[a]
    A = J * signs[:, None, :] * tau
    M = np.einsum("nkp,nkq->npq", A, A) / limit ** 2
    unit = np.where(np.array(robot.param_kinds)[a] == "length", 1e3, 1.0)
    K = p.K[a] / (tau * unit)
    relaxed = minimize(lambda x: np.sum(K / x), np.ones(a.sum()), jac=lambda x: -K / x ** 2, method="trust-constr",
                       bounds=Bounds(np.ones(a.sum()), p.ceilings[a] / tau),
                       constraints=[NonlinearConstraint(lambda x: np.einsum("p,npq,q->n", x, M, x), -np.inf, 1.0,
                                                        jac=lambda x: 2 * np.einsum("npq,q->np", M, x))],
                       options={"gtol": 1e-12, "xtol": 1e-14, "maxiter": 5000})
    assert relaxed.status in (1, 2) and relaxed.constr_violation < 1e-9, relaxed.message
    assert relaxed.fun * (1 - 1e-6) <= p.cost(d) <= relaxed.fun * (1 + 1e-6)
