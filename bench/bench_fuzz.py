"""Long fuzz of the services and the file readers, run as the nodes run them (a script, not a test).

N generated requests per JSON service (``--requests``, default 20,000), valid ones mixed with mutations
(``tolerance_ros/testing/fuzz_corpus.py``), go through the node classes' request callbacks (ErrorModelServer,
ToleranceAllocator; last-resort wrapper included) when rclpy is importable, else through the services'
``handle_text`` / ``handle``. Each batch runs in a child process, so that a crash shows as a signal and
a hang as a batch killed at its deadline. The allocator answers every request at once; of the
allocations it accepts, ``--solve`` per batch are solved (wall-clock limit ``--time-limit``), the others
cancelled. Prints, per service: process crashes, hung batches, exceptions escaping the callback,
'internal' answers, answers slower than 1 s (and the slowest), schema violations (not strict JSON, or
not valid against ``schemas/*.response.json``, or no answer), solves answered later than their
time_limit + 0.5 s, and the memory of a batch after its warm-up and at its end.

A memory soak (``--soak`` requests per service, default 10,000, through the services' logic in one process)
prints the memory each service still holds after every 1,000 requests. Then ``--files`` generated files per
reader (robot YAML, URDF, budget YAML and JSON, campaign,
calibration, measurement CSV; a fifth as many URDFs) and ``--entries`` inputs per other entry point
(the monitor's joint states and measured poses, budget messages and the bound after them, the predicted
bound, the simulated tracker, robot_description, the joint-state source, payloads that are not text),
in child processes too; a table each: inputs, accepted, refused (with the reader's own error naming the
file, or the entry point's documented refusal), escaped (anything else), unusable (taken although the
corpus's own oracle says it must be refused, or giving non-finite numbers), crashes and hangs, and the
slowest answer. Exits 1 if any crash, hang, escape, 'internal' answer, schema violation, late solve,
unusable or slow input occurred.

    python bench/bench_fuzz.py [--requests 20000] [--soak 10000] [--files 2000] [--entries 5000] [--batch 2500]
                               [--solve 2] [--seed 0] [--no-ros]
"""
import os

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")
os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")

import argparse  # noqa: E402
import importlib  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import multiprocessing  # noqa: E402
import signal  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "bench")]  # run from a checkout without installing

from hypothesis import HealthCheck, Phase, given, seed, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from tolerance_ros.testing.fuzz_corpus import (ENCODINGS, NESTED_ID, UNKNOWN, allocate_request, encode, expected_id,  # noqa: E402
                         jacobian_request)
from tolerance_ros.testing.schemas import validator  # noqa: E402
from tolerance_ros.core.jsonio import dumps_fast, loads_strict  # noqa: E402
from tolerance_ros.services.contracts import CODES  # noqa: E402
from child import run_child  # noqa: E402
from fuzz_inputs import EXAMPLES, SLOW_S, entry_points, fuzz_cases, print_cases  # noqa: E402
from fuzz_soak import SOAK_CHUNK, rss_of_process, soak  # noqa: E402
from machine import load_average, machine  # noqa: E402

SERVICES = ("compute_error_jacobian", "allocate_tolerances")
LATE_S = 0.5   # a final allocation answer may come at most this long after its time_limit
WARM = 500     # requests of a batch before its memory is taken as warmed up
SOLVES = "(a solve of this batch)"  # what the answers of the allocator's solves answer


def ros_available() -> bool:
    try:
        importlib.import_module("rclpy")
    except ImportError:
        return False
    return True


def as_ros_text(text):
    """What a std_msgs/String carries: UTF-8 text (bytes that are not UTF-8, and lone surrogates, replaced)."""
    if isinstance(text, str):
        text = text.encode("utf-8", errors="surrogatepass")
    return text.decode("utf-8", errors="replace")


class Target:
    """One service as a node runs it: ``send(text)`` returns the answers published at once; ``later()``
    the answers published since (the allocator's solves); ``escaped()`` exceptions the last-resort
    wrapper caught."""

    def __init__(self, service, use_ros, tmp):
        self.service, self.use_ros, self.pending = service, use_ros, []
        if use_ros:
            self._start_node(tmp)
        elif service == "compute_error_jacobian":
            from tolerance_ros.services.error_model import ErrorModelService
            self.logic = ErrorModelService(self._robots())
        else:
            from tolerance_ros.services.allocation import AllocatorService
            from tolerance_ros.services.contracts import Limits
            self.logic = AllocatorService(self._robots(), self._emit,
                                          Limits(max_bytes=100_000, max_poses=10_000), max_queue=4,
                                          max_time_limit_s=ARGS.time_limit)

    @staticmethod
    def _robots():
        """The robots of the service, their compiled kernels warmed up as the nodes do (``nodes.common.robot_set``)."""
        from tolerance_ros.services.robots import RobotSet
        robots = RobotSet(["gao2023_7dof"], "gao2023_7dof")
        for model in robots.models.values():
            model.warm_up()
        return robots

    def _start_node(self, tmp):
        import rclpy
        from rclpy.parameter import Parameter
        from rclpy.serialization import deserialize_message, serialize_message
        from std_msgs.msg import String
        self.String, self.wire = String, lambda m: deserialize_message(serialize_message(m), String)
        self.context = rclpy.Context()
        rclpy.init(context=self.context, domain_id=int(os.environ.get("ROS_DOMAIN_ID", "77")))
        if self.service == "compute_error_jacobian":
            from tolerance_ros.nodes.error_model_server import ErrorModelServer
            self.node = ErrorModelServer(context=self.context, namespace="/bench_fuzz")
        else:
            from tolerance_ros.nodes.tolerance_allocator import ToleranceAllocator
            self.node = ToleranceAllocator(context=self.context, namespace="/bench_fuzz", parameter_overrides=[
                Parameter("budget_dir", value=tmp), Parameter("max_queue", value=4),
                Parameter("max_time_limit", value=ARGS.time_limit)])
        for pub in self.node.publishers:
            if pub.topic_name.endswith(f"{self.service}/response"):
                pub.publish = lambda msg: self.pending.append(msg.data)
            elif pub.topic_name != "/parameter_events":
                pub.publish = lambda msg: None
        self.callback = next(s.callback for s in self.node.subscriptions
                             if s.topic_name.endswith(f"{self.service}/request"))
        self.timers = [t.callback for t in self.node.timers]

    def _emit(self, kind, doc):
        if kind == "response":
            self.pending.append(dumps_fast(doc))

    def send(self, text):
        if not self.use_ros:
            if self.service == "compute_error_jacobian":
                self.pending.append(self.logic.handle_text(text))
            else:
                self.logic.handle(text)
            return self.later()
        self.callback(self.wire(self.String(data=as_ros_text(text))))
        return self.later()

    def later(self):
        for timer in getattr(self, "timers", []):
            timer()
        out, self.pending = self.pending, []
        return out

    def escaped(self):
        return getattr(self.node, "callback_errors", 0) if self.use_ros else 0

    def busy(self):
        return (self.node.service if self.use_ros else self.logic).busy()

    def close(self):
        if self.service == "allocate_tolerances":
            (self.node if self.use_ros else self.logic).close()
        if self.use_ros:
            import rclpy
            self.node.destroy_node()
            rclpy.shutdown(context=self.context)


def run_batch(service, n, batch_seed, use_ros, conn):
    """Child process: ``n`` generated requests through one fresh node (or service); sends its counts."""
    schema = validator(f"{service}.response")
    stats = {"requests": 0, "escaped": 0, "internal": 0, "slow": 0, "max_s": 0.0, "schema": 0, "unanswered": 0,
             "accepted": 0, "solved": 0, "late": 0, "max_late_s": -math.inf, "rss_warm": None, "rss_end": None,
             "wrong_id": 0, "examples": {}}
    deadlines = {}  # id of a solved job -> [deadline of its final answer (monotonic s)], in acceptance order
    accepted_ids = {}  # id -> jobs accepted with it: a cancel by id may hit another job of the same id

    def keep(kind, text, detail):
        shown = stats["examples"].setdefault(kind, [])
        if len(shown) < EXAMPLES:
            shown.append({"request": str(text)[:300], "detail": str(detail)[:300]})

    def check(text, answers):
        for answer in answers:
            try:
                doc = loads_strict(answer)
                schema.validate(doc)
            except Exception as exc:  # not strict JSON, or not valid against the schema
                stats["schema"] += 1
                keep("schema", text, f"{type(exc).__name__}: {exc}")
                continue
            if not doc["ok"] and doc["error"]["code"] not in CODES:
                stats["schema"] += 1
                keep("schema", text, doc)
            if not doc["ok"] and doc["error"]["code"] == "internal":
                stats["internal"] += 1
                keep("internal", text, doc)
            expected = expected_id(text) if service == "compute_error_jacobian" and text != SOLVES else UNKNOWN
            if doc["id"] == NESTED_ID or expected not in (UNKNOWN, doc["id"]):
                stats["wrong_id"] += 1
                keep("wrong id", text, doc)
            if doc.get("status") == "accepted":
                stats["accepted"] += 1
                accepted_ids[json.dumps(doc["id"])] = accepted_ids.get(json.dumps(doc["id"]), 0) + 1
                if stats["accepted"] > ARGS.solve:
                    check("(cancel)", target.send(json.dumps({"id": "bench-cancel", "command": "cancel",
                                                              "target": doc["id"]})))
                else:
                    stats["solved"] += 1
                    asked = loads_strict(text).get("time_limit", ARGS.time_limit)
                    deadlines.setdefault(json.dumps(doc["id"]), []).append(time.monotonic() + asked)
            elif doc.get("status") in ("done", "timeout") or doc.get("error", {}).get("code") == "infeasible":
                waiting = deadlines.get(json.dumps(doc["id"]))  # the final answer of a solve
                if waiting and accepted_ids[json.dumps(doc["id"])] == 1:  # its job is known for sure
                    late = time.monotonic() - waiting.pop(0)
                    stats["max_late_s"] = max(stats["max_late_s"], late)
                    if late > LATE_S:
                        stats["late"] += 1
                        keep("late", doc["id"], f"{late:.3f} s after its time_limit")


    with tempfile.TemporaryDirectory() as tmp:
        target = Target(service, use_ros, tmp)
        strategy = st.tuples(jacobian_request() if service == "compute_error_jacobian" else allocate_request(),
                             st.sampled_from(ENCODINGS))

        @seed(batch_seed)
        @settings(max_examples=n, database=None, phases=[Phase.generate], deadline=None,
                  suppress_health_check=list(HealthCheck))
        @given(strategy)
        def fuzz(case):
            request, how = case
            text = encode(request, how)
            stats["requests"] += 1
            escaped = target.escaped()
            t0 = time.perf_counter()
            try:
                answers = target.send(text)
            except Exception as exc:  # escaped the callback and its last-resort wrapper
                stats["escaped"] += 1
                keep("escaped", text, f"{type(exc).__name__}: {exc}")
                return
            elapsed = time.perf_counter() - t0
            if target.escaped() > escaped:
                stats["escaped"] += 1
                keep("escaped", text, "caught by the last-resort handler")
            stats["max_s"] = max(stats["max_s"], elapsed)
            if elapsed > SLOW_S:
                stats["slow"] += 1
                keep("slow", text, f"{elapsed:.3f} s")
            is_cancel = isinstance(request, dict) and request.get("command") == "cancel"
            if not answers and not is_cancel:
                stats["unanswered"] += 1
                keep("unanswered", text, "no answer")
            check(text, answers)
            check(SOLVES, target.later())
            if stats["requests"] == WARM:
                stats["rss_warm"] = rss_of_process()

        fuzz()
        deadline = time.monotonic() + 4 * ARGS.time_limit * max(ARGS.solve, 1) + 30
        if service == "allocate_tolerances":
            while target.busy() and time.monotonic() < deadline:
                check(SOLVES, target.later())
                time.sleep(0.05)
            check(SOLVES, target.later())
        stats["rss_end"] = rss_of_process()
        target.close()
    conn.send(stats)
    conn.close()


def fuzz_service(service, use_ros, ctx):
    """All batches of one service; returns the summed counts, crashes and hangs."""
    total = {"requests": 0, "escaped": 0, "internal": 0, "slow": 0, "max_s": 0.0, "schema": 0, "unanswered": 0,
             "accepted": 0, "solved": 0, "late": 0, "max_late_s": -math.inf, "rss": [], "wrong_id": 0, "crashes": [],
             "hangs": 0,
             "examples": {}}
    left, index, started = ARGS.requests, 0, time.monotonic()
    while left > 0:
        n = min(ARGS.batch, left)
        stats, hung, exitcode = run_child(ctx, run_batch, (service, n, ARGS.seed * 1000 + index, use_ros),
                                          60 + n * 0.2 + 4 * ARGS.time_limit * ARGS.solve)
        total["hangs"] += hung
        if stats is None:
            total["requests"] += n
            if exitcode is not None and exitcode < 0:
                total["crashes"].append(f"batch {index}: {signal.Signals(-exitcode).name}")
            elif exitcode:
                total["crashes"].append(f"batch {index}: exit {exitcode}")
        else:
            for key in ("requests", "escaped", "internal", "slow", "schema", "unanswered", "accepted", "solved",
                        "late", "wrong_id"):
                total[key] += stats[key]
            total["max_s"] = max(total["max_s"], stats["max_s"])
            total["max_late_s"] = max(total["max_late_s"], stats["max_late_s"])
            if stats["rss_warm"] is not None and stats["rss_end"] is not None:
                total["rss"].append((stats["rss_warm"], stats["rss_end"]))
            for kind, shown in stats["examples"].items():
                total["examples"].setdefault(kind, []).extend(shown)
        left -= n
        index += 1
        print(f"  {service}: {ARGS.requests - left} of {ARGS.requests} requests, {time.monotonic() - started:.0f} s",
              file=sys.stderr, flush=True)
    total["wall_s"] = time.monotonic() - started
    return total


def main():
    use_ros = ros_available() and not ARGS.no_ros
    ctx = multiprocessing.get_context("fork")
    print(f"machine: {machine()}; {load_average()} at the start")
    print("through: " + ("the request callbacks of ErrorModelServer and ToleranceAllocator, each node in a "
                         "private rclpy context" if use_ros else "the services' handle_text / handle (no rclpy)"))
    print(f"corpus: tolerance_ros/testing/fuzz_corpus.py, {ARGS.requests} requests per service in batches of {ARGS.batch} "
          f"(one child process each), seed {ARGS.seed}; allocator: {ARGS.solve} accepted job(s) per batch solved "
          f"with a {ARGS.time_limit:g} s limit, the others cancelled")
    results = {s: fuzz_service(s, use_ros, ctx) for s in SERVICES} if ARGS.requests else {}
    soaks = {s: soak(s, ctx, ARGS.soak, ARGS.seed, ARGS.solve, ARGS.time_limit) for s in SERVICES} if ARGS.soak else {}
    from tolerance_ros.testing.fuzz_corpus import readers
    files = {name: fuzz_cases("reader", name, ARGS.files // (5 if name.startswith("URDF") else 1), ARGS.batch, ctx,
                        ARGS.seed)
             for name in readers()} if ARGS.files else {}
    entries = {name: fuzz_cases("entry", name, ARGS.entries // (5 if name.startswith("robot_desc") else 1),
                                ARGS.batch, ctx, ARGS.seed) for name in entry_points()} if ARGS.entries else {}
    rows = [("requests", lambda r: f"{r['requests']}"),
            ("process crashes (signals)", lambda r: f"{len(r['crashes'])}"),
            ("batches that hung (killed)", lambda r: f"{r['hangs']}"),
            ("exceptions escaping the callback", lambda r: f"{r['escaped']}"),
            ("'internal' answers", lambda r: f"{r['internal']}"),
            (f"answers slower than {SLOW_S:g} s (max)", lambda r: f"{r['slow']} ({r['max_s'] * 1e3:.1f} ms)"),
            ("schema violations", lambda r: f"{r['schema']}"),
            ("answers with another object's id", lambda r: f"{r['wrong_id']}"),
            ("requests without an answer", lambda r: f"{r['unanswered']}"),
            ("allocations accepted / solved", lambda r: f"{r['accepted']} / {r['solved']}" if r["accepted"] else "-"),
            (f"solved answers > time_limit + {LATE_S:g} s (max)",
             lambda r: f"{r['late']} ({r['max_late_s'] * 1e3:+.0f} ms)" if r["max_late_s"] > -math.inf else "-"),
            (f"memory, MB (after {WARM} requests -> end of batch)", _memory),
            ("wall time", lambda r: f"{r['wall_s']:.0f} s")]
    width = max(len(name) for name, _ in rows)
    if results:
        print()
        print(f"| {'':{width}} | {SERVICES[0]:>22} | {SERVICES[1]:>22} |")
        print(f"|{'-' * (width + 2)}|{'-' * 23}:|{'-' * 23}:|")
        for name, cell in rows:
            print(f"| {name:{width}} | {cell(results[SERVICES[0]]):>22} | {cell(results[SERVICES[1]]):>22} |")
    if soaks:
        print(f"\nsoak: {ARGS.soak} requests per service through its logic in one process, chunks of {SOAK_CHUNK}; "
              f"KiB the service still holds after each chunk (allocator: {ARGS.solve} solves per chunk, then idle):")
        for service, kept in soaks.items():
            if kept is None:
                print(f"  {service}: the process died or hung")
                continue
            print(f"  {service}: held {', '.join(f'{k / 1024:.0f}' for k, _ in kept)} KiB; process RSS "
                  f"{', '.join(f'{r:.0f}' for _, r in kept)} MB")
    failed = any(kept is None for kept in soaks.values())
    failed = (bool(files) and print_cases("file reader", files)) or failed
    failed = (bool(entries) and print_cases("entry point", entries)) or failed
    print(f"\n{load_average()} at the end")
    for service, r in results.items():
        bad = (r["crashes"] or r["hangs"] or r["escaped"] or r["internal"] or r["schema"] or r["unanswered"]
               or r["late"] or r["wrong_id"])
        failed = failed or bool(bad)
        for crash in r["crashes"]:
            print(f"{service}: crash in {crash}")
        for kind, shown in r["examples"].items():
            for example in shown[:EXAMPLES]:
                print(f"{service}: {kind}: {json.dumps(example)}")
    return 1 if failed else 0


def _memory(r) -> str:
    """RSS (MB) after the warm-up of a batch -> at its end, of the batch that grew most."""
    if not r["rss"]:
        return "-"
    warm, end = max(r["rss"], key=lambda pair: pair[1] - pair[0])
    return f"{warm:.0f} -> {end:.0f}"


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--requests", type=int, default=20_000, help="generated requests per service")
    p.add_argument("--files", type=int, default=2_000, help="generated files per reader (a fifth for URDFs)")
    p.add_argument("--soak", type=int, default=10_000, help="requests per service of the memory soak (0: none)")
    p.add_argument("--entries", type=int, default=5_000, help="generated inputs per other entry point (a fifth "
                                                               "for robot_description)")
    p.add_argument("--batch", type=int, default=2_500, help="requests per child process")
    p.add_argument("--solve", type=int, default=2, help="accepted allocations solved per batch (others cancelled)")
    p.add_argument("--time-limit", type=float, default=2.0, help="wall-clock limit of each solve, s")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--no-ros", action="store_true", help="call the services even where rclpy is importable")
    return p.parse_args(argv)


ARGS = parse_args([])

if __name__ == "__main__":
    ARGS = parse_args()
    sys.exit(main())
