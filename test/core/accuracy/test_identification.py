"""Identification on a synthetic campaign with known truth: a perturbed robot, a known base, known noise."""
import numpy as np
import pytest

from tolerance_ros.core.accuracy.identification import identify
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
    ident = identify(gao, q, reg.to_base(T), delta, 1e-5, 1e-5)
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
    ident = identify(gao, q, reg.to_base(T), tight, 1e-5, 1e-5)
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
    from tolerance_ros.core.accuracy.identification import Identification
    delta, dx, q, T = truth
    Tb = register(gao.fk(q), T).to_base(T)
    batch = identify(gao, q, Tb, delta, 1e-5)
    acc = AccuracyAccumulator(gao, delta)
    for a in range(0, len(q), 64):
        acc.add(Tb[a:a + 64], q[a:a + 64])
    stream = acc.linear_identification(1e-5)
    assert isinstance(stream, Identification) and (stream.method, batch.method) == ("linearised", "gauss-newton")
    assert stream.unidentifiable == batch.unidentifiable and stream.rank == batch.rank
    ok = np.array([n not in batch.unidentifiable for n in gao.param_names])
    assert np.all(np.abs(stream.dx - batch.dx)[ok] < 0.5 * batch.std[ok] + 1e-9)
    assert stream.residual_rms_after == pytest.approx(batch.residual_rms_after, rel=0.05)
