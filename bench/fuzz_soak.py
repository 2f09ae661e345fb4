"""The memory soak of bench/bench_fuzz.py: generated requests through one service's logic in one child
process, in chunks of SOAK_CHUNK, and the memory the service still holds after each chunk."""
import json
import sys
import time
from pathlib import Path

from hypothesis import HealthCheck, Phase, given, seed, settings
from hypothesis import strategies as st

from tolerance_ros.testing.fuzz_corpus import ENCODINGS, allocate_request, encode, jacobian_request

SOAK_CHUNK = 1_000


def rss_of_process():
    """Resident memory of this process, MB (None where /proc is not there)."""
    try:
        return next(int(line.split()[1]) / 1024 for line in Path("/proc/self/status").read_text().splitlines()
                    if line.startswith("VmRSS"))
    except (OSError, StopIteration):
        return None


def run_soak(service, n, conn, seed_base=0, solve=2, time_limit=2.0):
    """Child process: ``n`` generated requests through one service's logic in chunks of SOAK_CHUNK, each chunk
    generated first and then answered under tracemalloc (the allocator then left to finish its solves): the
    bytes still held after each chunk, i.e. what the service keeps."""
    import gc
    import tracemalloc
    from tolerance_ros.core.models import warm_up_kernels
    from tolerance_ros.services.allocation import AllocatorService
    from tolerance_ros.services.contracts import Limits
    from tolerance_ros.services.error_model import ErrorModelService
    from tolerance_ros.services.robots import RobotSet
    warm_up_kernels()
    robots = RobotSet(["gao2023_7dof"], "gao2023_7dof")
    accepted = [0]
    logic = None

    def emit(kind, doc):  # as bench batches do: ``solve`` of every 1,000 accepted jobs solved, the others cancelled
        if kind == "response" and doc.get("status") == "accepted":
            accepted[0] += 1
            if accepted[0] % SOAK_CHUNK >= solve:
                logic.handle(json.dumps({"id": "soak-cancel", "command": "cancel", "target": doc["id"]}))

    if service == "compute_error_jacobian":
        logic = ErrorModelService(robots)
        handle = logic.handle_text
    else:
        logic = AllocatorService(robots, emit, Limits(max_bytes=100_000), max_queue=4,
                                 max_time_limit_s=time_limit)
        handle = logic.handle
    kept = []
    for chunk in range(0, n, SOAK_CHUNK):
        texts = []

        @seed(seed_base * 1000 + 500 + chunk // SOAK_CHUNK)
        @settings(max_examples=min(SOAK_CHUNK, n - chunk), database=None, phases=[Phase.generate], deadline=None,
                  suppress_health_check=list(HealthCheck))
        @given(st.tuples(jacobian_request() if service == "compute_error_jacobian" else allocate_request(),
                         st.sampled_from(ENCODINGS)))
        def generate(case):
            texts.append(encode(*case))

        generate()
        tracemalloc.start()
        for text in texts:
            handle(text)
        deadline = time.monotonic() + 4 * time_limit * max(solve, 1) + 30
        while service != "compute_error_jacobian" and logic.busy() and time.monotonic() < deadline:
            time.sleep(0.05)
        texts.clear()
        gc.collect()
        kept.append((tracemalloc.get_traced_memory()[0], rss_of_process()))
        tracemalloc.stop()
    if service != "compute_error_jacobian":
        logic.close()
    conn.send(kept)
    conn.close()


def soak(service, ctx, n, seed_base=0, solve=2, time_limit=2.0):
    """The bytes kept after each chunk of the soak of one service (None if its process died or hung)."""
    receive, send = ctx.Pipe(duplex=False)
    child = ctx.Process(target=run_soak, args=(service, n, send, seed_base, solve, time_limit))
    child.start()
    send.close()
    try:
        kept = receive.recv() if receive.poll(120 + n * 0.2) else None
    except EOFError:
        kept = None
    if child.is_alive():
        child.kill()
    child.join(30)
    print(f"  soak of {service}: {n} requests", file=sys.stderr, flush=True)
    return kept
