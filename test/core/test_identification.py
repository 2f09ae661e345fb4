"""Identification on a synthetic campaign with known truth: a perturbed robot, a known base, known noise."""
import numpy as np
import pytest

from tolerance_ros.core.identification import FitOptions, Unknowns, identify
from tolerance_ros.core.accuracy.registration import register
from tolerance_ros.core.accuracy.simulate import as_built_errors, measure
from tolerance_ros.core.geometry import transform

T_TB = transform([1.5, -0.3, 0.2], [0.05, -0.02, 1.2])


@pytest.fixture(scope="module")
def truth(gao):
    delta = np.r_[np.full(14, 1e-4), np.full(14, 5e-4)]
    dx = as_built_errors(delta, 7)
    q = gao.sample_joints(300, 8)
    T = measure(gao, q, dx, 1e-5, 1e-5, T_TB, seed=9)
    return delta, dx, q, T


def test_identification_recovers_the_injected_errors(gao, truth):
    delta, dx, q, T = truth
    reg = register(gao.fk(q), T)
    ident = identify(gao, q, reg.to_base(T), delta, FitOptions(sigma_position=1e-5, sigma_orientation=1e-5))
    names = list(gao.param_names)
    # The first joint's d and theta move the tool like a base shift/turn: they cannot be separated.
    assert {"d1", "theta1"} <= set(ident.unidentifiable)
    ok = np.array([n not in ident.unidentifiable for n in names])
    err = np.abs(ident.dx - dx)[ok]
    assert np.all(err < 6 * ident.std[ok] + 1e-7)
    assert ident.residual_rms_after < 2e-5 < ident.residual_rms_before


def test_out_of_tolerance_parts_are_named(gao, truth):
    delta, dx, q, T = truth
    tight = delta.copy()
    j = gao.param_index(["theta3"])[0]
    tight[j] = abs(dx[j]) / 3
    reg = register(gao.fk(q), T)
    ident = identify(gao, q, reg.to_base(T), tight, FitOptions(sigma_position=1e-5, sigma_orientation=1e-5))
    assert ident.out_of_tolerance[0]["name"] == "theta3"
    assert ident.out_of_tolerance[0]["ratio"] == pytest.approx(3.0, rel=0.05)


def test_registration_recovers_the_base_transform_up_to_the_robot_errors(gao, truth):
    delta, dx, q, T = truth
    exact = register(gao.fk(q, dx), T)  # with the as-built model the transform is found to noise level
    assert np.allclose(exact.T_tracker_base, T_TB, atol=1e-5)


def test_streaming_identification_is_the_same_result_as_the_batch_fit(gao, truth):
    """The accumulator's one linearised step from the normal equations agrees with the batch Gauss-Newton
    fit on the same (position) data, with the same identifiability."""
    from tolerance_ros.core.accuracy.accumulator import AccuracyAccumulator
    from tolerance_ros.core.identification import Identification
    delta, dx, q, T = truth
    Tb = register(gao.fk(q), T).to_base(T)
    batch = identify(gao, q, Tb, delta, FitOptions(sigma_position=1e-5))
    acc = AccuracyAccumulator(gao, delta)
    for a in range(0, len(q), 64):
        acc.add(Tb[a:a + 64], q[a:a + 64])
    stream = acc.linear_identification(1e-5)
    assert isinstance(stream, Identification) and (stream.method, batch.method) == ("linearised", "gauss-newton")
    assert stream.unidentifiable == batch.unidentifiable and stream.rank == batch.rank
    ok = np.array([n not in batch.unidentifiable for n in gao.param_names])
    assert np.all(np.abs(stream.dx - batch.dx)[ok] < 0.5 * batch.std[ok] + 1e-9)
    assert stream.residual_rms_after == pytest.approx(batch.residual_rms_after, rel=0.05)


def test_dependent_parameters_keep_one_of_each_dependent_set():
    """Two equal parameter columns and one equal to a base column: QR pivoting keeps one of the pair,
    holds the other, and holds the one the base already explains; independent columns stay."""
    from tolerance_ros.core.identification import dependent_parameters
    rng = np.random.default_rng(0)
    base = rng.standard_normal((60, 6))
    A = rng.standard_normal((60, 4))
    A[:, 1] = A[:, 0]                 # p1 duplicates p0
    A[:, 3] = 2.0 * base[:, 2]        # p3 moves the tool like base.z
    held = dependent_parameters(np.hstack([A, base]), 4)
    assert held[3] and not held[2] and held[0] != held[1]


@pytest.mark.parametrize("seed", range(5))
def test_a_tall_jacobian_holds_the_same_columns_as_its_square_twin(seed):
    """The columns held depend only on the columns' inner products: a Jacobian of 3,000 rows (reduced first by
    an orthogonal transformation) holds exactly the columns its 30-row twin of the same geometry holds (taken as
    it is), ties of equal columns included."""
    from tolerance_ros.core.identification import dependent_columns
    rng = np.random.default_rng(seed)
    small = rng.standard_normal((30, 16))
    small[:, 3] = small[:, 1]                                   # a tie: equal columns
    small[:, 7] = 0.5 * small[:, 2] - small[:, 12]              # a combination of an estimable and a nuisance one
    small[:, 9] = small[:, 14]                                  # one the nuisance columns explain
    Q, _ = np.linalg.qr(rng.standard_normal((3000, 30)))
    tall = Q @ small
    estimable, nuisance = np.arange(12), np.arange(12, 16)
    pref = rng.integers(0, 2, 12)
    a = dependent_columns(small, estimable, nuisance, preference=pref)
    b = dependent_columns(tall, estimable, nuisance, preference=pref)
    assert np.array_equal(a, b) and a[9] and a[1] != a[3] and a.sum() == 3


def test_holding_the_dependent_parameters_estimates_the_rest_from_the_data(gao, truth):
    """Position rows only, no prior: d1/theta1 (the base's), alpha6/theta6 (equivalent to d6/a6 when the
    tool point lies on the last axis) and alpha7/theta7 (no effect on position) are held at 0; the
    others are estimated with uncertainties scaled by the residual noise, which estimates the tracker's."""
    delta, dx, q, T = truth
    Tb = register(gao.fk(q), T).to_base(T)
    ident = identify(gao, q, Tb, None, FitOptions(sigma_position=1e-5), hold="dependent",
                     noise_from_residuals=True)
    assert set(ident.held) == {"d1", "theta1", "alpha6", "theta6", "alpha7", "theta7"}
    held = gao.param_index(ident.held)
    assert np.all(ident.dx[held] == 0) and np.all(ident.std[held] == 0)
    d7 = gao.nominal[gao.param_index(["d7"])[0]]
    assert ident.aliases["a6"] == {"theta6": pytest.approx(-d7)} and ident.aliases["d6"] == {"alpha6": pytest.approx(d7)}
    assert ident.aliases["base.z"] == {"d1": pytest.approx(1.0)}
    assert ident.sigma == pytest.approx(1e-5, rel=0.15)
    effective = dx.copy()
    effective[held] = 0.0
    for name, absorbed in ident.aliases.items():
        if name in gao.param_names:
            j = gao.param_index([name])[0]
            effective[j] += sum(c * dx[gao.param_index([h])[0]] for h, c in absorbed.items())
    ok = np.setdiff1d(np.arange(gao.n_params), held)
    z = (ident.dx - effective)[ok] / ident.std[ok]
    assert 0.6 < np.sqrt(np.mean(z ** 2)) < 1.5 and np.abs(z).max() < 4.0
    assert ident.fit_condition < ident.condition * 10 and np.isfinite(ident.fit_condition)


def test_hold_by_name_and_too_few_rows(gao, truth):
    delta, dx, q, T = truth
    Tb = register(gao.fk(q), T).to_base(T)
    ident = identify(gao, q, Tb, delta, FitOptions(sigma_position=1e-5, sigma_orientation=1e-5), hold=["a1", "theta7"])
    assert ident.held == ["a1", "theta7"] and ident.dx[0] == 0
    with pytest.raises(ValueError, match="cannot be estimated"):
        identify(gao, q[:9], Tb[:9], None, FitOptions(sigma_position=1e-5), hold="dependent",
                 noise_from_residuals=True)


def test_every_column_of_the_fit_jacobian_matches_finite_differences():
    """Parameters, base correction, target points and rotations (measured frames) and compliances."""
    from helpers import example_urdf
    from tolerance_ros.core.models import URDFChain
    from tolerance_ros.core.identification import _Layout, _stack, _targets_with, base_matrix
    from tolerance_ros.core.targets import Targets
    from tolerance_ros.core.calibration.elastic import gravity_loads
    model = URDFChain(example_urdf("ur5_robot.urdf"), tip_link="tool0")
    rng = np.random.default_rng(1)
    q = model.sample_joints(6, 2)
    g = gravity_loads(model, q)
    tg = Targets(("A", "B"), np.array([transform([0.1, 0, 0.05], [0.2, 0, 0]), transform([0, 0.2, 0.05], [0, 0.3, 1])]),
                 frames=True)
    idx = np.array([0, 1, 0, 1, 1, 0])
    cmask = np.array([False, True, True, False, False, False])
    layout = _Layout(model.n_params, 2, True, True, cmask)
    x = rng.normal(0, 1e-3, layout.n)
    x[layout.c] = rng.normal(0, 1e-4, layout.nc)
    x[layout.base] = x[layout.r] = 0.0  # rotation vectors: their columns are the derivative at the current value 0
    c = np.zeros(model.dof)
    c[cmask] = x[layout.c]
    T_meas = base_matrix(x[layout.base]) @ model.fk(q + g * c, x[:model.n_params]) @ _targets_with(tg, layout, x)[idx]
    J, r, _ = _stack(model, q, T_meas, x, layout, tg, idx, True, 0.5, g)
    h = 1e-7
    for j in range(layout.n):
        e = np.zeros(layout.n)
        e[j] = h
        rp = _stack(model, q, T_meas, x + e, layout, tg, idx, True, 0.5, g)[1]
        rm = _stack(model, q, T_meas, x - e, layout, tg, idx, True, 0.5, g)[1]
        # r = measured - model, measured here the model at x: J is minus the derivative of r
        assert np.allclose(-(rp - rm) / (2 * h), J[:, j], atol=1e-6), j


def _scipy_cost(model, q, T_base, ident, prior, targets, idx, gravity=None, cmask=None):
    """The minimum of ``identify``'s objective over the same free unknowns, found by scipy's Levenberg-Marquardt
    (tolerances 1e-15) on a residual written here from the model's forward kinematics alone (no Jacobian of
    ours): |measured point - B(x) T(q + g c, dx) X_k|^2 + prior @ x^2."""
    from scipy.optimize import least_squares
    from tolerance_ros.core.identification import base_matrix
    p = model.n_params
    free = ident.free_columns
    x0 = ident.x.copy()
    K = len(targets)
    nt = 3 * K if ident.targets_std is not None else 0
    P = T_base[:, :3, 3]

    def full(v):
        x = np.zeros_like(x0)
        x[free] = v
        return x

    def residual(v):
        x = full(v)
        qq = q
        if cmask is not None:
            c = np.zeros(model.dof)
            c[cmask] = x[p + 6 + nt:]
            qq = q + gravity * c
        T = base_matrix(x[p:p + 6]) @ model.fk(qq, x[:p])
        pts = targets.offsets.copy()
        if nt:
            pts = pts + x[p + 6:p + 6 + nt].reshape(K, 3)
        model_pts = np.einsum("nij,nj->ni", T[:, :3, :3], pts[idx]) + T[:, :3, 3]
        return np.concatenate([(P - model_pts).ravel(), np.sqrt(prior[free]) * v])

    start = np.zeros(len(free))  # from nominal, not from our answer
    res = least_squares(residual, start, method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=100000,
                        x_scale=np.full(len(free), 1e-3))
    return float(res.fun @ res.fun)


@pytest.mark.parametrize("regularised", [False, True])
def test_identify_reaches_the_optimum_scipy_finds_on_a_dh_arm(gao, truth, regularised):
    """The converged fit's cost equals scipy's minimum of the same objective to 1e-9, and the fit says how it
    stopped; a cap of 1 iteration is reported as not converged."""
    delta, dx, q, T = truth
    q, T = q[:80], T[:80]
    Tb = register(gao.fk(q), T).to_base(T)
    prior_std = np.full(gao.n_params, 1e-3) if regularised else None
    if regularised:
        prior_std[gao.joint_columns()] = np.inf
    ident = identify(gao, q, Tb, prior_std, FitOptions(sigma_position=1e-5), hold="dependent",
                     noise_from_residuals=True)
    conv = ident.convergence
    assert conv.converged and conv.stop in ("gradient", "step") and conv.gradient_cosine < 1e-6
    prior = np.zeros(len(ident.x))
    if regularised:
        prior[:gao.n_params] = np.where(np.isinf(prior_std), 0.0, (1e-5 / prior_std) ** 2)
    from tolerance_ros.core.targets import Targets
    cost = _scipy_cost(gao, q, Tb, ident, prior, Targets.at_tool(), np.zeros(len(q), int))
    assert conv.cost == pytest.approx(cost, rel=1e-9)
    capped = identify(gao, q, Tb, prior_std, FitOptions(sigma_position=1e-5, iterations=1), hold="dependent",
                      noise_from_residuals=True)
    assert not capped.convergence.converged and capped.convergence.stop == "iteration cap"
    assert "NOT CONVERGED" in capped.convergence.words()


def test_identify_reaches_the_optimum_scipy_finds_on_a_urdf_arm_with_targets_and_compliance():
    """The FANUC URDF (origins at pitch +-pi/2), three reflectors fitted with the registration, a compliance per
    joint loaded by a point mass at the flange, a prior on the origin errors: scipy's minimum to 1e-9."""
    from pathlib import Path
    from tolerance_ros.core.targets import Targets
    from tolerance_ros.core.calibration.elastic import Load
    from tolerance_ros.core.models import URDFChain
    model = URDFChain(Path(__file__).resolve().parents[1] / "data" / "fanuc_r2000ic" / "fanuc_r2000ic_165f.urdf")
    rng = np.random.default_rng(3)
    q = model.sample_joints(40, 4)
    dx = rng.normal(0, 2e-4, model.n_params)
    load = Load("point-mass", 100.0, (0.0, 0.0, 0.0))
    g = load.torques(model, q)
    c_true = np.array([0, 2e-7, 2e-7, 1e-7, 1e-7, 0])
    offs = np.array([[0.03, 0.09, 0.0], [0.03, -0.045, 0.078], [0.03, -0.045, -0.078]])
    idx = np.tile(np.arange(3), len(q))
    rows = np.repeat(np.arange(len(q)), 3)
    T_tool = model.fk(q + g * c_true, dx)[rows]
    Tb = np.tile(np.eye(4), (len(rows), 1, 1))
    Tb[:, :3, 3] = np.einsum("nij,nj->ni", T_tool[:, :3, :3], offs[idx]) + T_tool[:, :3, 3] + \
        rng.normal(0, 3e-5, (len(rows), 3))
    targets = Targets.from_offsets(("A", "B", "C"), offs + rng.normal(0, 1e-3, (3, 3)))
    cmask = np.ptp(g, axis=0) > 1e-9
    prior_std = np.where(np.array(model.param_kinds) == "length", 1e-3, 1e-3)
    prior_std[model.joint_columns()] = np.inf
    ident = identify(model, q[rows], Tb, prior_std, FitOptions(sigma_position=1e-5),
                     Unknowns(targets=targets, target_index=idx, estimate_targets=True, gravity=g[rows],
                              compliance=cmask, compliance_prior=np.full(model.dof, 1e-6)),
                     hold="dependent", noise_from_residuals=True)
    assert ident.convergence.converged
    prior = np.zeros(len(ident.x))
    prior[:model.n_params] = np.where(np.isinf(prior_std), 0.0, (1e-5 / prior_std) ** 2)
    prior[-int(cmask.sum()):] = (1e-5 / 1e-6) ** 2
    cost = _scipy_cost(model, q[rows], Tb, ident, prior, targets, idx, g[rows], cmask)
    assert ident.convergence.cost == pytest.approx(cost, rel=1e-9)
    assert ident.compliance[2] == pytest.approx(2e-7, rel=0.2)


@pytest.mark.parametrize("regularised", [False, True])
def test_leverages_are_the_fits_hat_matrix(gao, truth, regularised):
    """Each row's leverage is its share of the hat matrix: over the fitted rows (position only) they sum to the
    effective number of unknowns; a row left out gets the leverage of its prediction, h_out, which is
    h / (1 - h) of its leverage h in the fit of every row (Sherman-Morrison)."""
    delta, dx, q, T = truth
    q, T = q[:60], T[:60]
    Tb = register(gao.fk(q), T).to_base(T)
    delta = delta if regularised else None
    ident = identify(gao, q, Tb, delta, FitOptions(sigma_position=1e-5), hold="dependent", noise_from_residuals=True)
    h = ident.row_leverage
    assert np.all((h >= 0) & (h < 1))
    assert 3 * h.sum() == pytest.approx(ident.effective_unknowns, rel=1e-9)
    i = 17
    w = np.ones(len(q))
    w[i] = 0.0
    out = identify(gao, q, Tb, delta, FitOptions(sigma_position=1e-5), hold=ident.held, noise_from_residuals=True,
                   weights=w, start=ident)
    keep = np.flatnonzero(w > 0)
    assert 3 * out.row_leverage[keep].sum() == pytest.approx(out.effective_unknowns, rel=1e-9)
    # left out: h_out / (1 + h_out) is the leverage the row has in the fit of every row (Sherman-Morrison, per axis
    # averaged; equal to first order in the small leverages of a 60-pose fit)
    assert out.row_leverage[i] / (1 + out.row_leverage[i]) == pytest.approx(ident.row_leverage[i], rel=0.03)


def _line(target, wall=np.inf, refuse_first=False):
    """evaluate(x) of the residual r = x - target (1-D, unit Jacobian) whose model cannot be assembled beyond
    ``wall`` (ValueError), and, with ``refuse_first``, not at the first step tried."""
    calls = {"n": 0}

    def evaluate(x):
        calls["n"] += 1
        if abs(x[0]) > wall or (refuse_first and calls["n"] == 2):
            raise ValueError("beyond the wall")
        return np.ones((1, 1)), np.array([target - x[0]])
    return evaluate


def test_the_loop_goes_on_while_the_full_step_lowers_the_cost():
    """The first step refused, the damping grows and the next step falls short by 1e-6 of the optimum, a step below
    XTOL of these large unknowns: the loop had stopped there on its step test and called it converged; the full
    step, tried before stopping, reaches the optimum."""
    from tolerance_ros.core.identification import _minimise
    x, _, r, conv = _minimise(_line(1e13 + 1.0, refuse_first=True), np.array([1e13]), np.arange(1), np.ones(1),
                              np.zeros(1), np.zeros((0, 3), int), 200)
    assert conv.converged and conv.stop == "gradient" and x[0] == 1e13 + 1.0 and r[0] == 0.0


def test_a_fit_stopped_by_a_wall_is_not_called_converged():
    """No step can cross the wall where the optimum lies beyond it: the loop stops there and says it did not converge
    (the full step would still remove the whole cost), whatever its last damped step."""
    from tolerance_ros.core.identification import _minimise
    x, _, r, conv = _minimise(_line(3.0, wall=1.0), np.zeros(1), np.arange(1), np.ones(1), np.zeros(1),
                              np.zeros((0, 3), int), 200)
    assert not conv.converged and conv.stop in ("step", "no descent") and conv.decrement > 0.5
    assert 0.9 < x[0] <= 1.0 and conv.words().startswith("NOT CONVERGED")
