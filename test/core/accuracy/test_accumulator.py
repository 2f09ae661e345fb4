"""The streaming accumulator against a batch computation."""
import numpy as np
import pytest

from tolerance_ros.core.accuracy.accumulator import AccuracyAccumulator
from tolerance_ros.core.accuracy.simulate import as_built_errors, measure
from tolerance_ros.core.accuracy.verdicts import pose_errors


def test_streaming_equals_batch_and_iso_per_pose(gao):
    delta = np.r_[np.full(14, 1e-4), np.full(14, 5e-4)]
    dx = as_built_errors(delta, 1)
    qk = gao.sample_joints(5, 2)
    q = np.tile(qk, (30, 1))
    T = measure(gao, q, dx, 1e-5, 1e-5, None, seed=3)
    acc = AccuracyAccumulator(gao, delta, limit=1.4e-3, campaign_joints=qk, campaign_names=[f"P{i}" for i in range(5)])
    for a in range(0, 150, 7):
        acc.add(T[a:a + 7], q[a:a + 7])
    s = acc.summary()
    dp, _ = pose_errors(gao.fk(q), T)
    e = np.linalg.norm(dp, axis=1)
    assert s["position_error_m"]["mean"] == pytest.approx(e.mean()) and s["position_error_m"]["max"] == pytest.approx(e.max())
    assert s["position_error_m"]["std"] == pytest.approx(e.std())
    P0 = T[::5]
    ap = np.linalg.norm(P0[:, :3, 3].mean(axis=0) - gao.fk(qk[:1])[0, :3, 3])
    assert s["test_poses"]["P0"]["n"] == 30 and s["test_poses"]["P0"]["AP_p"] == pytest.approx(ap)
    assert sum(s["verdicts"].values()) == 150
