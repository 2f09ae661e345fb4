"""The file readers' and the other entry points' part of bench/bench_fuzz.py: generated inputs, each batch in a
child process, and the table of what each reader or entry point did with them (accepted, refused with its own
error, escaped, unusable, crashes and hangs, slow answers)."""
import json
import math
import sys
import tempfile
import time
from pathlib import Path

from hypothesis import HealthCheck, Phase, given, seed, settings
from hypothesis import strategies as st

from child import run_child
from tolerance_ros.core.jsonio import dumps_fast, loads_strict

SLOW_S = 1.0
EXAMPLES = 3  # failures kept per kind and batch, to show


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
    from tolerance_ros.testing.example_robots import example_urdf
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


def fuzz_cases(kind, name, n, batch, ctx, seed_base=0):
    """All batches of one reader or entry point; the summed counts, crashes and hangs."""
    total = {"inputs": 0, "slow": 0, "max_s": 0.0, "crashes": [], "hangs": 0, "examples": {},
             **{o: 0 for o in OUTCOMES}}
    left, index, started = n, 0, time.monotonic()
    while left > 0:
        m = min(batch, left)
        stats, hung, exitcode = run_child(ctx, run_cases, (kind, name, m, seed_base * 1000 + index), 60 + m * 1.0)
        total["hangs"] += hung
        if stats is None:
            total["inputs"] += m
            total["crashes"].append(f"batch {index}: {exitcode}")
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
