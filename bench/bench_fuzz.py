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
import json  # noqa: E402
import math  # noqa: E402
import multiprocessing  # noqa: E402
import platform  # noqa: E402
import signal  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT)]  # run from a checkout without installing

from hypothesis import HealthCheck, Phase, given, seed, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from tolerance_ros.testing.fuzz_corpus import (ENCODINGS, NESTED_ID, UNKNOWN, allocate_request, encode, expected_id,  # noqa: E402
                         jacobian_request)
from tolerance_ros.testing.schemas import validator  # noqa: E402
from tolerance_ros.core.jsonio import dumps_fast, loads_strict  # noqa: E402
from tolerance_ros.services.contracts import CODES  # noqa: E402

SERVICES = ("compute_error_jacobian", "allocate_tolerances")
SLOW_S = 1.0
LATE_S = 0.5   # a final allocation answer may come at most this long after its time_limit
WARM = 500     # requests of a batch before its memory is taken as warmed up
SOLVES = "(a solve of this batch)"  # what the answers of the allocator's solves answer
EXAMPLES = 3  # failures kept per kind and batch, to show


def ros_available() -> bool:
    try:
        import rclpy  # noqa: F401
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
            from tolerance_ros.core.jsonio import dumps_fast
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


class Unusable(Exception):
    """An input taken although it had to be refused, or that gave something unusable."""


OUTCOMES = ("accepted", "refused", "escaped", "unusable")
"""What a reader or entry point did with one input: took it (and what it gave is usable), refused it with its
own error (a reader's naming the file), let another exception out (or an error that does not name the file),
or took it and gave something unusable (non-finite numbers, a broken log)."""


def entry_points():
    """name -> (strategy of inputs, make() -> handle(case) returning 'accepted' or 'refused'): every entry point
    of the services besides the two JSON requests, as the nodes call them."""
    import numpy as np
    from tolerance_ros.testing.fuzz_corpus import (PAYLOADS, budget_messages, joint_states, measured_poses, must_refuse, names_twice,
                             urdf_text)
    from helpers import example_urdf
    from tolerance_ros.core.budget import load_budget
    from tolerance_ros.core.ingest import IngestError
    from tolerance_ros.core.models import ModelError, URDFChain, load_robot
    from tolerance_ros.services.contracts import ContractError, budget_from_message
    from tolerance_ros.services.error_model import ErrorModelService
    from tolerance_ros.services.joint_source import JointStateSequence
    from tolerance_ros.services.monitor import MonitorLogic
    from tolerance_ros.services.robots import RobotSet
    from tolerance_ros.services.tracker import SimulatedTracker

    gao = load_robot("gao2023_7dof")
    budget = load_budget("gao2023_delta2", gao)

    def monitor():
        tmp = tempfile.mkdtemp()
        mon = MonitorLogic(gao, budget, None, slop=0.05, max_wait=0.0, log_path=Path(tmp) / "log.jsonl")

        def handle(case):
            state, pose = case
            before = dict(mon.counts)
            mon.on_joint_state(*state)
            mon.on_pose(*pose)
            mon.resolve()
            dumps_fast(mon.report())
            c = mon.counts
            if c["received"] != c["paired"] + c["unpaired"] + c["rejected"] + len(mon.pending):
                raise Unusable("the counts do not add up")
            if names_twice(state[1]) and c["joint_states"] > before["joint_states"]:
                raise Unusable("took a joint state that names a joint twice")
            return "refused" if c["rejected"] > before["rejected"] or \
                c["joint_states_rejected"] > before["joint_states_rejected"] else "accepted"
        return handle

    def budgets():
        svc = ErrorModelService({gao.name: gao}, gao.name)
        mon = MonitorLogic(gao, None, None)

        def handle(case):
            text, state = case
            try:
                _, b = budget_from_message(text, svc.models)
            except ContractError:
                return "refused"
            svc.current_budget = b
            mon.set_budget(b)
            bound = svc.bound_at(*state[1:], stamp=state[0])
            finite = bound is None or np.isfinite([bound["position_bound_m"], bound["orientation_bound_rad"]]).all()
            return "accepted" if finite else "unusable"
        return handle

    def bound():
        svc = ErrorModelService({gao.name: gao}, gao.name)
        svc.current_budget = budget

        def handle(state):
            b = svc.bound_at(state[1], state[2], stamp=state[0])
            if b is None:
                return "refused"
            if names_twice(state[1]):
                raise Unusable("bound at a joint state that names a joint twice")
            return "accepted" if np.isfinite([b["position_bound_m"], b["orientation_bound_rad"]]).all() else "unusable"
        return handle

    def tracker():
        sim = SimulatedTracker(gao, budget.vector_for(gao))

        def handle(state):
            try:
                T = sim.on_joint_state(state[1], state[2])
            except IngestError:
                return "refused"
            if names_twice(state[1]):
                raise Unusable("measured at a joint state that names a joint twice")
            return "accepted" if np.isfinite(T).all() else "unusable"
        return handle

    def description():
        robots = RobotSet(["robot_description"], "robot_description", tip_link="tool0")
        same = Path(tempfile.mkdtemp()) / "same.urdf"

        def handle(text):
            same.write_text(text, encoding="utf-8", errors="surrogatepass")
            try:
                URDFChain(same, tip_link="tool0")
                from_file = "accepted"
            except ModelError:
                from_file = "refused"
            try:
                robots.on_description(text)
            except (ModelError, ContractError):
                outcome = "refused"
            else:
                m = robots.single()
                if not np.isfinite(m.fk(m.joint_limits.mean(axis=1)[None])).all():
                    raise Unusable("non-finite poses")
                if must_refuse(text.encode("utf-8", "surrogatepass"), "urdf"):
                    raise Unusable(f"accepted {must_refuse(text.encode('utf-8', 'surrogatepass'), 'urdf')}")
                outcome = "accepted"
            if outcome != from_file:
                raise Unusable(f"robot_description {outcome}, the same text from a file {from_file}")
            return outcome
        return handle

    def source():
        seq = JointStateSequence(gao, "random", count=5, dwell=0.5, loop=True)

        def handle(t):
            try:
                return "accepted" if np.isfinite(seq.at(t)[2]).all() else "unusable"
            except ValueError:
                return "refused" if not math.isfinite(t) else "escaped"
        return handle

    def payloads():
        svc = ErrorModelService({gao.name: gao}, gao.name)

        def handle(payload):
            code = loads_strict(svc.handle_text(payload))["error"]["code"]
            return "refused" if code in ("invalid_request", "invalid_json") else "escaped"
        return handle

    doc = budget.to_dict()
    return {"monitor: joint state + measured pose": (st.tuples(joint_states(), measured_poses()), monitor),
            "tolerance_budget message, then a bound": (st.tuples(budget_messages(doc), joint_states()), budgets),
            "predicted bound at a joint state": (joint_states(), bound),
            "simulated tracker: joint state": (joint_states(), tracker),
            "robot_description (URDF text)": (urdf_text(example_urdf("ur5_robot.urdf").read_text()), description),
            "joint-state source: time": (st.floats(), source),
            "request that is not text": (st.sampled_from(PAYLOADS), payloads)}


def run_cases(kind, name, n, batch_seed, conn):
    """Child process: ``n`` generated inputs of one file reader (kind 'reader') or entry point ('entry')."""
    from tolerance_ros.core.models import warm_up_kernels
    warm_up_kernels()  # as every node does at start
    stats = {"inputs": 0, "slow": 0, "max_s": 0.0, "examples": {}, **{o: 0 for o in OUTCOMES}}
    with tempfile.TemporaryDirectory() as tmp:
        if kind == "reader":
            from tolerance_ros.testing.fuzz_corpus import readers
            reader = readers()[name]
            strategy, path = reader.files, Path(tmp) / f"input{reader.suffix}"

            def handle(data):
                path.write_bytes(data)
                try:
                    result = reader.read(path)
                except reader.error as exc:
                    return "refused" if str(path) in str(exc) else "escaped"
                if reader.refuse(data):  # read what it had to refuse
                    raise Unusable(f"accepted {reader.refuse(data)}")
                try:
                    reader.check(result)
                except Exception as exc:  # what it read is not usable
                    raise Unusable(f"{type(exc).__name__}: {exc}") from None
                return "accepted"
        else:
            strategy, make = entry_points()[name]
            handle = make()

        @seed(batch_seed)
        @settings(max_examples=n, database=None, phases=[Phase.generate], deadline=None,
                  suppress_health_check=list(HealthCheck))
        @given(strategy)
        def fuzz(case):
            stats["inputs"] += 1
            t0 = time.perf_counter()
            try:
                outcome = handle(case)
            except Unusable as exc:
                outcome, detail = "unusable", str(exc)
            except Exception as exc:  # escaped the reader or the entry point
                outcome, detail = "escaped", f"{type(exc).__name__}: {exc}"
            else:
                detail = outcome
            elapsed = time.perf_counter() - t0
            stats[outcome] += 1
            if outcome in ("escaped", "unusable"):
                shown = stats["examples"].setdefault(outcome, [])
                if len(shown) < EXAMPLES:
                    shown.append({"input": repr(case)[:300], "detail": detail[:300]})
            stats["max_s"] = max(stats["max_s"], elapsed)
            if elapsed > SLOW_S:
                stats["slow"] += 1

        fuzz()
    conn.send(stats)
    conn.close()


def fuzz_cases(kind, name, n, batch, ctx):
    """All batches of one reader or entry point; the summed counts, crashes and hangs."""
    total = {"inputs": 0, "slow": 0, "max_s": 0.0, "crashes": [], "hangs": 0, "examples": {},
             **{o: 0 for o in OUTCOMES}}
    left, index, started = n, 0, time.monotonic()
    while left > 0:
        m = min(batch, left)
        receive, send = ctx.Pipe(duplex=False)
        child = ctx.Process(target=run_cases, args=(kind, name, m, ARGS.seed * 1000 + index, send))
        child.start()
        send.close()
        try:
            stats = receive.recv() if receive.poll(60 + m * 1.0) else None
        except EOFError:
            stats = None
        if child.is_alive() and stats is None:
            total["hangs"] += 1
            child.kill()
        child.join(30)
        if stats is None:
            total["inputs"] += m
            total["crashes"].append(f"batch {index}: {child.exitcode}")
        else:
            for key in ("inputs", "slow", *OUTCOMES):
                total[key] += stats[key]
            total["max_s"] = max(total["max_s"], stats["max_s"])
            for k, shown in stats["examples"].items():
                total["examples"].setdefault(k, []).extend(shown)
        left -= m
        index += 1
    total["wall_s"] = time.monotonic() - started
    print(f"  {name}: {total['inputs']} inputs, {total['wall_s']:.0f} s", file=sys.stderr, flush=True)
    return total


def print_cases(title, results) -> bool:
    """A table of readers or entry points; True when any input escaped, crashed, hung or gave something
    unusable, or took longer than SLOW_S."""
    width = max(len(name) for name in results)
    slow = f"slower than {SLOW_S:g} s (max)"
    print(f"\n| {title:{width}} | inputs | accepted | refused | escaped | unusable | crashes / hangs | {slow} |")
    print(f"|{'-' * (width + 2)}|-------:|---------:|--------:|--------:|---------:|----------------:|"
          f"{'-' * (len(slow) + 1)}:|")
    bad = False
    for name, r in results.items():
        print(f"| {name:{width}} | {r['inputs']:6d} | {r['accepted']:8d} | {r['refused']:7d} | {r['escaped']:7d} | "
              f"{r['unusable']:8d} | {len(r['crashes']) :>7d} / {r['hangs']:<5d} | "
              f"{str(r['slow']) + ' (' + format(r['max_s'] * 1e3, '.1f') + ' ms)':>{len(slow)}} |")
        bad = bad or bool(r["escaped"] or r["unusable"] or r["crashes"] or r["hangs"] or r["slow"])
        for k, shown in r["examples"].items():
            for example in shown[:EXAMPLES]:
                print(f"{name}: {k}: {json.dumps(example)}")
    return bad


SOAK_CHUNK = 1_000


def rss_of_process():
    """Resident memory of this process, MB (None where /proc is not there)."""
    try:
        return next(int(line.split()[1]) / 1024 for line in Path("/proc/self/status").read_text().splitlines()
                    if line.startswith("VmRSS"))
    except (OSError, StopIteration):
        return None


def run_soak(service, n, conn):
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

    def emit(kind, doc):  # as bench batches do: ARGS.solve of every 1,000 accepted jobs solved, the others cancelled
        if kind == "response" and doc.get("status") == "accepted":
            accepted[0] += 1
            if accepted[0] % SOAK_CHUNK >= ARGS.solve:
                logic.handle(json.dumps({"id": "soak-cancel", "command": "cancel", "target": doc["id"]}))

    if service == "compute_error_jacobian":
        logic = ErrorModelService(robots)
        handle = logic.handle_text
    else:
        logic = AllocatorService(robots, emit, Limits(max_bytes=100_000), max_queue=4,
                                 max_time_limit_s=ARGS.time_limit)
        handle = logic.handle
    kept = []
    for chunk in range(0, n, SOAK_CHUNK):
        texts = []

        @seed(ARGS.seed * 1000 + 500 + chunk // SOAK_CHUNK)
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
        deadline = time.monotonic() + 4 * ARGS.time_limit * max(ARGS.solve, 1) + 30
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


def soak(service, ctx):
    """The bytes kept after each chunk of the soak of one service (None if its process died or hung)."""
    receive, send = ctx.Pipe(duplex=False)
    child = ctx.Process(target=run_soak, args=(service, ARGS.soak, send))
    child.start()
    send.close()
    try:
        kept = receive.recv() if receive.poll(120 + ARGS.soak * 0.2) else None
    except EOFError:
        kept = None
    if child.is_alive():
        child.kill()
    child.join(30)
    print(f"  soak of {service}: {ARGS.soak} requests", file=sys.stderr, flush=True)
    return kept


def machine() -> str:
    cpu = platform.processor() or "unknown CPU"
    try:
        cpu = next(line.split(":", 1)[1].strip() for line in Path("/proc/cpuinfo").read_text().splitlines()
                   if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    return f"{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}"


def load() -> str:
    return "load average " + " ".join(f"{x:.2f}" for x in os.getloadavg())


def fuzz_service(service, use_ros, ctx):
    """All batches of one service; returns the summed counts, crashes and hangs."""
    total = {"requests": 0, "escaped": 0, "internal": 0, "slow": 0, "max_s": 0.0, "schema": 0, "unanswered": 0,
             "accepted": 0, "solved": 0, "late": 0, "max_late_s": -math.inf, "rss": [], "wrong_id": 0, "crashes": [],
             "hangs": 0,
             "examples": {}}
    left, index, started = ARGS.requests, 0, time.monotonic()
    while left > 0:
        n = min(ARGS.batch, left)
        receive, send = ctx.Pipe(duplex=False)
        child = ctx.Process(target=run_batch, args=(service, n, ARGS.seed * 1000 + index, use_ros, send))
        child.start()
        send.close()
        try:
            stats = receive.recv() if receive.poll(60 + n * 0.2 + 4 * ARGS.time_limit * ARGS.solve) else None
        except EOFError:  # the child died without an answer
            stats = None
        if child.is_alive() and stats is None:
            total["hangs"] += 1
            child.kill()
        child.join(30)
        if stats is None:
            total["requests"] += n
            if child.exitcode is not None and child.exitcode < 0:
                total["crashes"].append(f"batch {index}: {signal.Signals(-child.exitcode).name}")
            elif child.exitcode:
                total["crashes"].append(f"batch {index}: exit {child.exitcode}")
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
    print(f"machine: {machine()}; {load()} at the start")
    print("through: " + ("the request callbacks of ErrorModelServer and ToleranceAllocator, each node in a "
                         "private rclpy context" if use_ros else "the services' handle_text / handle (no rclpy)"))
    print(f"corpus: tolerance_ros/testing/fuzz_corpus.py, {ARGS.requests} requests per service in batches of {ARGS.batch} "
          f"(one child process each), seed {ARGS.seed}; allocator: {ARGS.solve} accepted job(s) per batch solved "
          f"with a {ARGS.time_limit:g} s limit, the others cancelled")
    results = {s: fuzz_service(s, use_ros, ctx) for s in SERVICES} if ARGS.requests else {}
    soaks = {s: soak(s, ctx) for s in SERVICES} if ARGS.soak else {}
    from tolerance_ros.testing.fuzz_corpus import readers
    files = {name: fuzz_cases("reader", name, ARGS.files // (5 if name.startswith("URDF") else 1), ARGS.batch, ctx)
             for name in readers()} if ARGS.files else {}
    entries = {name: fuzz_cases("entry", name, ARGS.entries // (5 if name.startswith("robot_desc") else 1),
                                ARGS.batch, ctx) for name in entry_points()} if ARGS.entries else {}
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
    print(f"\n{load()} at the end")
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
