"""Benchmark: the first run of a job, estimated from its second, for each order the kernels may compile in.

A first run's cost over the second is the work its calls do on the numpy path until their kernel family
is ready. Two timed runs differ by 10-20 % on a VM from its drift alone, more than what an order or a head
start changes; this replay sees that difference. It measures (1) when each family is ready after the start
of a compiling child on an empty cache (``warmup.child_command``, as a cold command spawns it), for each order; (2) one warm run of the job in this process, every chain and worst-case call
timed on its kernel and, at once after, on its numpy path; then replays the warm run's calls with each
family on numpy until its ready time and prints the estimated first run and its ratio to the second. The
estimate leaves out what the two processes take from each other: the real first run is slower (measured
side by side with ``bench_first_run.py``).

    python bench/bench_first_run_replay.py [--job paper|allocate]
"""
import argparse
import contextlib
import io
import itertools
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_first_run import JOBS, child_env  # noqa: E402
from tolerance_ros.core.models import warmup  # noqa: E402
from machine import load_average, machine  # noqa: E402

FAMILIES = ("zonotope", "dh")  # the two families the D-H jobs wait for


def ready_times(order):
    """Seconds from a compiling child's start on an empty cache to each family of ``order`` being ready."""
    with tempfile.TemporaryDirectory() as cache:
        t0 = time.perf_counter()
        child = subprocess.Popen(warmup.child_command(order), env=child_env(cache), stdout=subprocess.PIPE,
                                 text=True)
        ready = {}
        for line in child.stdout:
            word, _, family = line.strip().partition(" ")
            if word == "ready" and family in order:
                ready[family] = time.perf_counter() - t0
                if len(ready) == len(order):
                    break
        child.kill()
        child.wait()
    return ready


def record(argv):
    """(seconds of a warm run of ``argv``, its calls as (family, start s, kernel s, numpy s)); the time spent
    on the numpy path is taken out of the clock."""
    from tolerance_ros.cli import main
    from tolerance_ros.core import errors
    from tolerance_ros.core.models import dh, kernels
    kernels.warm_up(FAMILIES)
    calls, spent, t0 = [], [0.0], [0.0]

    def timed(family, fast, slow):
        t = time.perf_counter()
        out = fast()
        t1 = time.perf_counter()
        slow()
        t2 = time.perf_counter()
        calls.append((family, t - t0[0] - spent[0], t1 - t, t2 - t1))
        spent[0] += t2 - t1
        return out

    chain, bound = dh.DHChain.fk_and_jacobian, errors.worst_case_bound

    def chain_call(self, q, dx=None, jacobian=True):
        return timed("dh", lambda: chain(self, q, dx, jacobian), lambda: self._fk_and_jacobian_numpy(q, dx, jacobian))

    def bound_call(J, delta, return_signs=False, max_chunk_bytes=64e6, backend="numba"):
        return timed("zonotope", lambda: bound(J, delta, return_signs, max_chunk_bytes, backend),
                     lambda: bound(J, delta, return_signs, max_chunk_bytes, "numpy"))
    users = [m for m in list(sys.modules.values()) if getattr(m, "worst_case_bound", None) is bound]
    with contextlib.ExitStack() as stack:
        for module in users:
            stack.callback(setattr, module, "worst_case_bound", bound)
            module.worst_case_bound = bound_call
        stack.callback(setattr, dh.DHChain, "fk_and_jacobian", chain)
        dh.DHChain.fk_and_jacobian = chain_call
        t0[0] = time.perf_counter()
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            main(list(argv))
        total = time.perf_counter() - t0[0] - spent[0]
    return total, calls


def replay(calls, total, ready):
    """Estimated seconds of the first run: each call on numpy until its family's ``ready`` time."""
    extra = 0.0
    for family, start, kernel_s, numpy_s in calls:
        if start + extra < ready[family]:
            extra += numpy_s - kernel_s
    return total + extra


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--job", default="paper", choices=["paper", "allocate"])
    args = ap.parse_args()
    print(f"machine: {machine()}, {load_average()}")
    orders = list(itertools.permutations(FAMILIES))
    readies = {order: ready_times(order) for order in orders}
    total, calls = record(JOBS[args.job])
    print(f"tolerance-ros {' '.join(JOBS[args.job])}: second run {total:.2f} s, {len(calls)} kernel calls "
          f"({sum(c[3] for c in calls):.2f} s on numpy against {sum(c[2] for c in calls):.2f} s compiled)")
    print("| compile order | ready after the child's start, s | first run s (estimated) | ratio |")
    print("|---|---|---|---|")
    for order in orders:
        ready = readies[order]
        first = replay(calls, total, ready)
        when = ", ".join(f"{f} {ready[f]:.2f}" for f in order)
        print(f"| {' then '.join(order)} | {when} | {first:.2f} | {first / total:.3f} |")
    never = replay(calls, total, dict.fromkeys(FAMILIES, float("inf")))
    print(f"| nothing compiled | - | {never:.2f} | {never / total:.3f} |")
    print(f"\nafter: {load_average()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
