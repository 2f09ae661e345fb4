"""Sensitivity, salience, ceilings, correlation and the Monte Carlo verification."""
import numpy as np
import pytest

from tolerance_ros.core import analysis
from tolerance_ros.core.errors import paper_bound


def test_salience_sums_to_one_and_ranks_the_paper_arm(gao):
    s = analysis.sensitivity(gao, 500, 0, length_unit="mm")
    assert s.salience.sum() == pytest.approx(1.0)
    names = list(gao.param_names)
    assert s.salience[names.index("alpha7")] < 1e-12 and s.salience[names.index("theta7")] < 1e-12
    lengths = s.salience[:14]
    assert np.allclose(lengths, lengths[0], rtol=1e-12)
    assert s.ranking()[0] in ("alpha2", "theta2")
    # SI lengths weigh length parameters 1000x more than mm lengths relative to angles.
    s_m = analysis.sensitivity(gao, 500, 0, length_unit="m")
    assert s_m.salience[0] / s_m.salience[15] == pytest.approx(1000 * s.salience[0] / s.salience[15])
    assert np.allclose(s_m.mu_mean, s.mu_mean)


def test_sensitivity_is_seeded(gao):
    a = analysis.sensitivity(gao, 200, 5)
    b = analysis.sensitivity(gao, 200, 5)
    c = analysis.sensitivity(gao, 200, 6)
    assert np.array_equal(a.mu_mean, b.mu_mean) and not np.array_equal(a.mu_mean, c.mu_mean)


def test_ceilings_of_a_planar_arm(planar2r):
    # |J_theta1| is the distance from the base axis to the tool: at most 0.7 m (stretched arm).
    q = np.array([[0.0, 0.0], [0.3, 1.0]])
    J = planar2r.error_jacobian(q).position
    c = analysis.ceilings(J, 1e-3)
    names = list(planar2r.param_names)
    assert c[names.index("theta1")] == pytest.approx(1e-3 / 0.7)
    assert c[names.index("theta2")] == pytest.approx(1e-3 / 0.3)
    assert c[names.index("a1")] == pytest.approx(1e-3)
    assert c[names.index("d1")] == pytest.approx(1e-3)
    # alpha1 tilts link 2 about x1: the tool moves by 0.3 |sin q2|; alpha2 turns about the tool point.
    assert c[names.index("alpha1")] == pytest.approx(1e-3 / (0.3 * np.sin(1.0)))
    assert np.isinf(c[names.index("alpha2")])


def test_ceiling_of_a_column_without_effect_is_infinite(gao):
    J = gao.error_jacobian(gao.sample_joints(100, 0)).position
    c = analysis.ceilings(J, 1.4e-3)
    assert np.isinf(c[list(gao.param_names).index("theta7")])


def test_correlation_matrix(gao):
    J = gao.error_jacobian(gao.sample_joints(2000, 1)).position
    R = analysis.correlation(J)
    finite = np.isfinite(np.diag(R))
    assert np.allclose(np.diag(R)[finite], 1.0)
    assert np.allclose(R[np.ix_(finite, finite)], R[np.ix_(finite, finite)].T)
    pairs = {(a, b): r for a, b, r in analysis.correlated_pairs(R, gao.param_names, 0.7)}
    assert pairs[("a6", "theta6")] == pytest.approx(-1.0, abs=1e-9)
    assert pairs[("d6", "alpha6")] == pytest.approx(1.0, abs=1e-9)
    assert len(pairs) == 8


def test_sign_control_rule():
    names = ["a1", "a2", "t1", "t2"]
    s = analysis.sign_control(names, [("a1", "t1", 0.9), ("a2", "t2", -0.9)])
    assert s.tolist() == [-1, 1, 1, 1]


@pytest.mark.parametrize("dist", analysis.DISTRIBUTIONS)
def test_error_samples_respect_their_distribution(dist):
    delta = np.array([1e-3, 2e-3, 0.0])
    x = analysis.sample_errors(delta, 20000, dist, 0)
    assert x.shape == (20000, 3)
    assert np.all(x[:, 2] == 0)
    if dist in ("fixed", "extreme"):
        assert np.allclose(np.abs(x), delta)
        if dist == "fixed":
            assert np.all(x >= 0)
        else:
            assert abs(np.mean(x[:, 0] > 0) - 0.5) < 0.02
    elif dist == "uniform":
        assert np.all(np.abs(x) <= delta) and np.std(x[:, 1]) == pytest.approx(2e-3 / np.sqrt(3), rel=0.03)
    else:
        assert np.std(x[:, 1]) == pytest.approx(2e-3 / 3, rel=0.03)


def test_monte_carlo_fixed_signs_is_the_paper_criterion(gao):
    delta = np.full(gao.n_params, 1e-4)
    v = analysis.monte_carlo(gao, delta, n=500, distribution="fixed", seed=1, limit_position=1.4e-3)
    J = gao.error_jacobian(v.q).position
    assert np.allclose(v.position, paper_bound(J, delta))
    s = v.summary["position"]
    assert s["max"] == pytest.approx(v.position.max())
    assert s["pass_rate"] == pytest.approx(np.mean(v.position <= 1.4e-3))
    assert s["failures"] == int(np.sum(v.position > 1.4e-3))
    assert s["percentiles"]["p50"] == pytest.approx(np.median(v.position))


def test_monte_carlo_is_seeded_and_poses_do_not_depend_on_the_distribution(gao):
    delta = np.full(gao.n_params, 1e-4)
    a = analysis.monte_carlo(gao, delta, n=300, distribution="uniform", seed=4)
    b = analysis.monte_carlo(gao, delta, n=300, distribution="uniform", seed=4)
    c = analysis.monte_carlo(gao, delta, n=300, distribution="normal", seed=4)
    assert np.array_equal(a.position, b.position)
    assert np.array_equal(a.q, c.q)


def test_nonlinear_verification_agrees_with_the_linear_model_for_small_errors(gao):
    delta = np.full(gao.n_params, 1e-5)
    lin = analysis.monte_carlo(gao, delta, n=200, distribution="extreme", seed=2)
    nl = analysis.monte_carlo(gao, delta, n=200, distribution="extreme", seed=2, method="nonlinear")
    assert np.allclose(lin.position, nl.position, rtol=1e-3, atol=1e-9)
    assert np.allclose(lin.orientation, nl.orientation, rtol=1e-3, atol=1e-9)


def test_monte_carlo_chunks_and_progress(gao):
    calls = []
    delta = np.full(gao.n_params, 1e-4)
    a = analysis.monte_carlo(gao, delta, n=1000, seed=3, chunk=300, progress=lambda d, t: calls.append((d, t)))
    b = analysis.monte_carlo(gao, delta, n=1000, seed=3)
    assert np.array_equal(a.position, b.position)
    assert calls == [(300, 1000), (600, 1000), (900, 1000), (1000, 1000)]


def test_monte_carlo_rejects_bad_tolerances(gao):
    with pytest.raises(ValueError, match="delta"):
        analysis.monte_carlo(gao, np.zeros(3))
    with pytest.raises(ValueError, match="delta"):
        analysis.monte_carlo(gao, np.full(gao.n_params, -1.0))
