"""Benchmark of the overhead of ``ErrorModelService.handle`` (the ``compute_error_jacobian`` service logic,
no ROS, no pinocchio) around the error-model kernel, one core, CPU time of this process, best of repeats:

- the kernel alone: ``model.fk_and_jacobian`` for 1 pose of the D-H 7-DOF ``gao2023_7dof``;
- ``handle`` for a 1-pose request (JSON text in, response dict out, every check included), and its overhead
  (handle minus kernel; target <= 15 us);
- ``handle`` for a 100-pose request with plain JSON arrays (no ``"arrays": "base64"``; target <= 300 us), and
  beside it ``handle_text`` (the same with the answer written as JSON text).

The rounds of each figure are interleaved, so that a slow second of a shared machine falls on all of them.
Prints the machine and the load average; exits 1 when a target is missed.

    python bench/bench_service.py [--rounds 5]
"""
import os

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import timeit  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout without installing
sys.path.insert(0, str(Path(__file__).resolve().parent))
from machine import load_average, machine, verdicts  # noqa: E402
from tolerance_ros.core.models import load_robot  # noqa: E402
from tolerance_ros.services.error_model import ErrorModelService  # noqa: E402

OVERHEAD_US = 15.0      # handle for 1 pose, minus the kernel
HUNDRED_US = 300.0      # handle for 100 poses, plain JSON arrays


def best_cpu(fn, seconds=0.2) -> float:
    """Best CPU seconds per call over repeats of about 20 ms each, for about ``seconds``."""
    single = min(timeit.repeat(fn, number=1, repeat=3, timer=time.process_time))
    number = max(1, math.ceil(0.02 / max(single, 1e-7)))
    repeat = max(3, int(seconds / max(single * number, 1e-9)))
    return min(timeit.repeat(fn, number=number, repeat=repeat, timer=time.process_time)) / number


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rounds", type=int, default=5, help="interleaved rounds; each figure is the best (default 5)")
    args = ap.parse_args(argv)
    print(f"machine: {machine()}; {load_average()} (before); CPU time of this process, best of {args.rounds} rounds")
    model = load_robot("gao2023_7dof")
    model.warm_up()
    svc = ErrorModelService({model.name: model}, model.name)
    rng = np.random.default_rng(0)
    q1, q100 = model.sample_joints(1, rng), model.sample_joints(100, rng)
    text1 = json.dumps({"id": "b", "joints": q1[0].tolist()})
    text100 = json.dumps({"id": "b", "joints": q100.tolist()})
    for text in (text1, text100):
        answer = svc.handle(text)
        assert answer["ok"], answer
    calls = {"kernel, 1 pose": lambda: model.fk_and_jacobian(q1),
             "handle, 1 pose": lambda: svc.handle(text1),
             "kernel, 100 poses": lambda: model.fk_and_jacobian(q100),
             "handle, 100 poses": lambda: svc.handle(text100),
             "handle_text, 100 poses": lambda: svc.handle_text(text100)}
    rounds = {name: [] for name in calls}
    for _ in range(args.rounds):
        for name, fn in calls.items():
            rounds[name].append(best_cpu(fn))
    t = {name: min(v) * 1e6 for name, v in rounds.items()}
    overhead = t["handle, 1 pose"] - t["kernel, 1 pose"]
    print(f"robot {model.name} (D-H, {model.dof} joints, {model.n_params} parameters), plain JSON arrays")
    for name in calls:
        print(f"  {name:<24} {t[name]:8.1f} us  (rounds: {', '.join(f'{x * 1e6:.1f}' for x in rounds[name])})")
    print(f"  overhead of handle around the kernel, 1 pose: {overhead:.1f} us "
          f"({overhead / t['kernel, 1 pose']:.1f}x the kernel)")
    print(f"  100 poses: handle {t['handle, 100 poses']:.1f} us, of which the kernel {t['kernel, 100 poses']:.1f} us; "
          f"handle_text (the answer as JSON text) {t['handle_text, 100 poses']:.1f} us")
    results = [(overhead <= OVERHEAD_US, f"handle overhead for 1 pose {overhead:.1f} us (target <= {OVERHEAD_US:g} us; "
                                         f"handle {t['handle, 1 pose']:.1f} us, kernel {t['kernel, 1 pose']:.1f} us)"),
               (t["handle, 100 poses"] <= HUNDRED_US,
                f"handle for 100 poses, plain JSON {t['handle, 100 poses']:.1f} us (target <= {HUNDRED_US:g} us)")]
    print(f"{load_average()} (after)")
    return verdicts(results)


if __name__ == "__main__":
    sys.exit(main())
