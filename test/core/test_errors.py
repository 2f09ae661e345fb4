"""Error bounds: the exact worst case against brute force, and the ordering of the bounds."""
import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from helpers import random_dh
from tolerance_ros.core import errors as errors_module
from tolerance_ros.core.errors import (bounds, direction_bounds, error_norms, paper_bound, per_axis_bound, rss_bound,
                                       worst_case_bound)


def brute_force(J, delta):
    S = np.array(list(itertools.product([-1.0, 1.0], repeat=J.shape[2])))
    E = np.einsum("nkp,sp->nsk", J, S * delta)
    return np.linalg.norm(E, axis=2).max(axis=1)


def _degenerate(J, kind, rng):
    p = J.shape[2]
    if kind == "planar":
        J[:, 2, :] = 0.0
    elif kind == "parallel" and p >= 3:
        J[:, :, 1] = 2.0 * J[:, :, 0]
        J[:, :, 2] = -0.5 * J[:, :, 0]
    elif kind == "zero":
        J[:, :, 0] = 0.0
    elif kind == "collinear":
        J[:] = J[:, :, :1] * rng.uniform(-1, 1, p)
    elif kind == "half-coplanar":
        J[:, 2, : p // 2] = 0.0
    return J


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 11),
       st.sampled_from(["generic", "planar", "parallel", "zero", "collinear", "half-coplanar"]))
def test_worst_case_equals_brute_force(seed, p, kind):
    rng = np.random.default_rng(seed)
    J = _degenerate(rng.standard_normal((6, 3, p)), kind, rng)
    delta = rng.uniform(0, 1, p)
    ref = brute_force(J, delta)
    for backend in ("numba", "numpy"):  # the compiled kernel and the numpy reference
        w, s = worst_case_bound(J, delta, return_signs=True, backend=backend)
        assert np.allclose(w, ref, rtol=1e-9, atol=1e-12), backend
        # The returned signs attain the bound.
        assert np.allclose(error_norms(J, s * delta), w, rtol=1e-12, atol=1e-12), backend


@pytest.mark.parametrize("kind", ["generic", "parallel", "zero", "half-coplanar"])
def test_the_compiled_worst_case_equals_the_numpy_reference_on_many_generators(kind):
    """42 generators (a 6-joint URDF chain's position rows), where brute force cannot follow: the kernel's
    values equal the reference's to 1e-12, and its signs attain them."""
    from tolerance_ros.core.models import kernels
    assert kernels.get("zonotope") is not None
    rng = np.random.default_rng(len(kind))
    J = _degenerate(rng.standard_normal((200, 3, 42)), kind, rng)
    delta = rng.uniform(1e-6, 1e-4, 42)
    ref, s_ref = worst_case_bound(J, delta, return_signs=True, backend="numpy")
    assert np.allclose(error_norms(J, s_ref * delta), ref, rtol=1e-12, atol=0)
    w, s = worst_case_bound(J, delta, return_signs=True, backend="numba")
    assert np.allclose(w, ref, rtol=1e-12, atol=0)
    assert np.allclose(error_norms(J, s * delta), w, rtol=1e-12, atol=0)


def test_the_numpy_worst_case_is_the_same_in_any_chunk_size(monkeypatch):
    """The reference works in chunks of poses (``WORST_CASE_CHUNK``): one pose at a time, 7 or all at once
    give the same values and signs."""
    from tolerance_ros.core import errors
    rng = np.random.default_rng(11)
    J = rng.standard_normal((40, 3, 12))
    delta = rng.uniform(1e-6, 1e-4, 12)
    runs = []
    for chunk in (1, 7, 1000):
        monkeypatch.setattr(errors, "WORST_CASE_CHUNK", chunk)
        runs.append(worst_case_bound(J, delta, return_signs=True, backend="numpy"))
    for w, s in runs[1:]:
        assert np.array_equal(w, runs[0][0]) and np.array_equal(s, runs[0][1])
    assert np.allclose(runs[0][0], brute_force(J, delta), rtol=1e-9, atol=0)


def test_the_perturbation_is_the_same_draws_whatever_the_calls_before(monkeypatch):
    """The degeneracy-breaking perturbation of a block of n poses is the first draws of one seeded generator,
    kept between calls: the same after a longer block, a shorter one, or a block beyond the kept table."""
    from tolerance_ros.core import errors
    monkeypatch.setattr(errors, "_NOISE", {})
    monkeypatch.setattr(errors, "_NOISE_CAP", 3 * 5 * 100)

    def fresh(n, m):
        return np.random.default_rng(12345).standard_normal((n, 3, m))
    for n in (3, 50, 7, 100, 101, 250, 1):
        got = errors._perturbation(n, 5)
        assert np.array_equal(got, fresh(n, 5)), n
        assert not got.flags.writeable
    assert len(errors._NOISE[5]) == 100  # the table never grows beyond its cap
    assert np.array_equal(errors._perturbation(4, 2), fresh(4, 2))


def test_worst_case_on_robot_jacobians_equals_brute_force():
    rng = np.random.default_rng(3)
    model = random_dh(rng, dof=3)
    J = model.error_jacobian(model.sample_joints(20, rng)).position
    delta = rng.uniform(1e-5, 1e-4, model.n_params)
    assert np.allclose(worst_case_bound(J, delta), brute_force(J, delta), rtol=1e-9)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_bound_ordering(seed):
    rng = np.random.default_rng(seed)
    model = random_dh(rng)
    J = model.error_jacobian(model.sample_joints(30, rng)).position
    delta = rng.uniform(0, 1e-3, model.n_params)
    b = bounds(J, delta)
    tol = 1e-12
    assert np.all(b["rss"] <= b["worst-case"] + tol)
    assert np.all(b["worst-case"] <= b["per-axis"] + tol)
    assert np.all(b["paper"] <= b["worst-case"] + tol)


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1), st.sampled_from(["none", "planar", "parallel", "zero", "collinear"]))
def test_the_direction_bounds_enclose_the_exact_worst_case(seed, kind):
    """lower <= worst case <= upper, on random and degenerate generators and on robot Jacobians; the upper
    bound within 1 / cos of the covering angle (3.3 % for 64 directions) of the lower."""
    rng = np.random.default_rng(seed)
    J = rng.normal(size=(40, 3, int(rng.integers(1, 40))))
    _degenerate(J, kind, rng)
    model = random_dh(rng)
    for G, d in ((J, rng.uniform(0, 1, J.shape[2])),
                 (model.error_jacobian(model.sample_joints(40, rng)).position, rng.uniform(0, 1e-3, model.n_params))):
        exact = worst_case_bound(G, d)
        lower, upper = direction_bounds(G, d)
        assert np.all(lower <= exact * (1 + 1e-12)) and np.all(exact <= upper * (1 + 1e-9))
        assert np.all(upper <= lower / errors_module._directions()[1] * (1 + 1e-12))
        assert np.all(upper <= exact * 1.034 + 1e-300)


def test_every_direction_lies_within_the_covering_angle_of_the_bounds_directions():
    """The covering angle read off the convex hull is not too small: no unit vector of a dense random sample
    is farther from the directions and their opposites (the upper bound is valid); and it is the real one
    within a few per cent (the bound is not looser than it needs)."""
    for count in (16, 64):
        U, cos_cover = errors_module._directions(count)
        assert np.allclose(np.linalg.norm(U, axis=1), 1.0)
        v = np.random.default_rng(count).normal(size=(200000, 3))
        v /= np.linalg.norm(v, axis=1, keepdims=True)
        nearest = np.abs(v @ U.T).max(axis=1)  # cos of the angle to the nearest of +-U
        assert nearest.min() >= cos_cover - 1e-12
        assert np.arccos(nearest.min()) > 0.9 * np.arccos(cos_cover)


def test_zero_tolerances_give_zero_bounds(gao):
    J = gao.error_jacobian(gao.sample_joints(10, 0)).position
    for v in bounds(J, np.zeros(gao.n_params)).values():
        assert np.all(v == 0.0)


def test_bounds_scale_linearly(gao):
    J = gao.error_jacobian(gao.sample_joints(10, 0)).position
    d = np.full(gao.n_params, 1e-4)
    b1, b2 = bounds(J, d), bounds(J, 3 * d)
    for k in b1:
        assert np.allclose(b2[k], 3 * b1[k], rtol=1e-12)


def test_single_parameter_bounds_are_column_norms(planar2r):
    q = planar2r.sample_joints(5, 1)
    J = planar2r.error_jacobian(q).position
    d = np.zeros(planar2r.n_params)
    j = planar2r.param_index(["theta1"])[0]
    d[j] = 1e-3
    expected = np.linalg.norm(J[:, :, j], axis=1) * 1e-3
    for v in bounds(J, d).values():
        assert np.allclose(v, expected)


def test_paper_bound_is_J_delta_and_signs(planar2r):
    J = planar2r.error_jacobian(planar2r.sample_joints(5, 1)).position
    d = np.arange(1, planar2r.n_params + 1) * 1e-4
    assert np.allclose(paper_bound(J, d), np.linalg.norm(J @ d, axis=1))
    s = np.where(np.arange(planar2r.n_params) % 2 == 0, 1.0, -1.0)
    assert np.allclose(paper_bound(J, d, s), np.linalg.norm(J @ (s * d), axis=1))
    assert np.allclose(per_axis_bound(J, d), np.linalg.norm(np.abs(J) @ d, axis=1))
    assert np.allclose(rss_bound(J, d), np.sqrt(((J ** 2).sum(axis=1) * d ** 2).sum(axis=1)))


@pytest.mark.parametrize("delta", [np.full(3, -1.0), np.array([np.nan, 0, 0]), np.zeros(2)])
def test_invalid_delta(delta):
    with pytest.raises(ValueError, match="delta"):
        worst_case_bound(np.ones((2, 3, 3)), delta)


def test_rss_confidence_is_guaranteed_for_gaussian_errors(gao):
    from tolerance_ros.core.errors import confidence_for_k, k_for_confidence
    assert k_for_confidence(0.9973) == pytest.approx(3.0, abs=1e-3)
    assert confidence_for_k(3.0) == pytest.approx(0.9973, abs=1e-4)
    rng = np.random.default_rng(0)
    q = gao.sample_joints(3, rng)
    J = gao.error_jacobian(q).position
    delta = rng.uniform(1e-5, 3e-4, gao.n_params)
    k = k_for_confidence(0.9)
    bound = rss_bound(J, delta, k)
    dx = rng.standard_normal((200000, gao.n_params)) * delta / 3
    for i in range(3):
        err = np.linalg.norm(dx @ J[i].T, axis=1)
        assert np.mean(err <= bound[i]) >= 0.9
    with pytest.raises(ValueError, match="confidence"):
        k_for_confidence(0.5)
