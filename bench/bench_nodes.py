"""Benchmark of the node logic (no ROS needed), one core:
- ``compute_error_jacobian`` handler time, JSON parsing and encoding included, for a 1-pose and a
  1,000-pose request (targets <= 1 ms and <= 20 ms);
- accuracy-monitor throughput: measured poses paired with joint states, evaluated against the
  budget and written to the campaign log, one message at a time (target >= 2,000 per s).

    python bench/bench_nodes.py
"""
import os

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")

import json  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout without installing
from tolerance_ros.core.geometry import matrices_to_quat  # noqa: E402
from tolerance_ros.services.tracker import SimulatedTracker  # noqa: E402
from tolerance_ros.core.budget import load_budget  # noqa: E402
from tolerance_ros.services.error_model import ErrorModelService  # noqa: E402
from tolerance_ros.core.models import load_robot  # noqa: E402
from tolerance_ros.services.monitor import MonitorLogic  # noqa: E402


def per_call(fn, repeat):
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times)), float(np.min(times))


def main():
    model = load_robot("gao2023_7dof")
    svc = ErrorModelService({model.name: model}, model.name)
    rng = np.random.default_rng(0)
    one = json.dumps({"id": "b1", "joints": model.sample_joints(1, rng)[0].tolist()})
    many = json.dumps({"id": "b2", "joints": model.sample_joints(1000, rng).tolist()})
    assert json.loads(svc.handle_text(one))["ok"] and json.loads(svc.handle_text(many))["ok"]
    m1, b1 = per_call(lambda: svc.handle_text(one), 500)
    m2, b2 = per_call(lambda: svc.handle_text(many), 30)
    print(f"compute_error_jacobian, 1 pose: median {m1 * 1e3:.3f} ms (best {b1 * 1e3:.3f}); target <= 1 ms "
          f"{'met' if m1 <= 1e-3 else 'NOT met'}")
    print(f"compute_error_jacobian, 1,000 poses: median {m2 * 1e3:.2f} ms (best {b2 * 1e3:.2f}); target <= 20 ms "
          f"{'met' if m2 <= 20e-3 else 'NOT met'}")

    budget = load_budget("gao2023_delta2", model)
    sim = SimulatedTracker(model, budget.vector_for(model), seed=1)
    n = 5000
    q = model.sample_joints(n, 2)
    T = np.array([sim.measure_at(qk) for qk in q])
    quats = matrices_to_quat(T[:, :3, :3])
    with tempfile.TemporaryDirectory() as tmp:
        mon = MonitorLogic(model, budget, slop=0.01, log_path=Path(tmp) / "log.jsonl")
        names = list(model.joint_names)
        t0 = time.perf_counter()
        for k in range(n):
            t = 0.02 * k
            mon.on_joint_state(t - 0.002, names, q[k])
            mon.on_pose(t, "tracker", T[k, :3, 3], quats[k])
            mon.on_joint_state(t + 0.003, names, q[k])
        dt = time.perf_counter() - t0
        mon.close()
    rate = mon.counts["paired"] / dt
    print(f"accuracy monitor: {mon.counts['paired']} of {n} measurements paired and evaluated in {dt:.2f} s with "
          f"{2 * n} joint states: {rate:.0f} measurements per s; target >= 2,000 {'met' if rate >= 2000 else 'NOT met'}")


if __name__ == "__main__":
    main()
