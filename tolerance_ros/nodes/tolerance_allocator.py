"""Tolerance allocator (node ``tolerance_allocator``): the JSON service ``allocate_tolerances`` on
``/tolerance/allocate_tolerances/request`` -> ``.../response``. A solve runs in a worker thread, so the
node keeps answering (other requests are acknowledged and queued; ``{"command": "status"}`` is answered
at once); progress goes to ``.../progress``; the finished budget is saved to ``budget_dir`` and
published on ``tolerance_budget`` (transient local: late subscribers get it)."""
from __future__ import annotations

import queue
import threading
import time
from pathlib import Path

from rclpy.node import Node
from std_msgs.msg import String

from ..core.budget import budget_from_dict
from ..core.jsonio import dumps_fast
from ..services.allocation import Command, parse_allocate_request, run_allocation
from ..services.contracts import ContractError, Limits, error_response, request_id_of
from .common import BUDGET_QOS, SERVICE_REQUEST_QOS, SERVICE_RESPONSE_QOS, SERVICE_NAMESPACE, declare, load_models, run

TOPIC = f"{SERVICE_NAMESPACE}/allocate_tolerances"


class ToleranceAllocator(Node):
    def __init__(self, **node_options):
        super().__init__("tolerance_allocator", **node_options)
        robots = declare(self, "robots", ["gao2023_7dof"], "robot configs served (names or paths)")
        default = declare(self, "default_robot", "gao2023_7dof", "robot used when a request names none")
        self.budget_dir = Path(declare(self, "budget_dir", str(Path.home() / ".ros" / "tolerance_ros" / "budgets"),
                                       "directory where finished budgets are saved (YAML, mm and rad)")).expanduser()
        max_queue = declare(self, "max_queue", 4, "allocation requests that may wait behind the running one")
        max_bytes = declare(self, "max_request_bytes", 100_000, "size cap of a request, bytes")
        self.models, self.default = load_models(robots, default)
        self.limits = Limits(max_bytes, 10_000)
        self.responses = self.create_publisher(String, f"{TOPIC}/response", SERVICE_RESPONSE_QOS)
        self.progress_pub = self.create_publisher(String, f"{TOPIC}/progress", SERVICE_RESPONSE_QOS)
        self.budget_pub = self.create_publisher(String, "tolerance_budget", BUDGET_QOS)
        self.create_subscription(String, f"{TOPIC}/request", self.on_request, SERVICE_REQUEST_QOS)
        self.jobs = queue.Queue(maxsize=max_queue)
        self.outbox = queue.Queue()
        self.running = None
        self.done = []
        self.worker = threading.Thread(target=self.work, daemon=True)
        self.worker.start()
        self.create_timer(0.05, self.flush_outbox)
        self.get_logger().info(f"serving {sorted(self.models)} on {TOPIC}/request; budgets saved in {self.budget_dir}")

    def on_request(self, msg):
        try:
            job = parse_allocate_request(msg.data, self.models, self.default, self.limits)
        except ContractError as exc:
            self.publish(error_response(request_id_of(msg.data), exc))
            return
        if isinstance(job, Command):
            self.publish({"id": job.id, "ok": True, "status": "status", "running": self.running,
                          "queued": self.jobs.qsize(), "finished": self.done[-10:]})
            return
        try:
            self.jobs.put_nowait(job)
        except queue.Full:
            self.publish(error_response(job.id, ContractError(
                "busy", f"allocator queue is full ({self.jobs.maxsize} waiting); retry later")))
            return
        self.publish({"id": job.id, "ok": True, "status": "accepted", "queued": self.jobs.qsize(),
                      "running": self.running})

    def work(self):
        while True:
            job = self.jobs.get()
            if job is None:
                return
            self.running = job.id
            start = time.perf_counter()

            def progress(done, total, job_id=job.id):
                self.outbox.put(("progress", {"id": job_id, "fraction": min(1.0, done / max(total, 1)),
                                              "elapsed_s": time.perf_counter() - start}))

            try:
                resp = run_allocation(job, progress)
                path = self.save(job, resp)
                resp["budget_file"] = str(path)
                self.outbox.put(("budget", {"id": job.id, "robot": job.robot, "file": str(path),
                                            "budget": resp["budget"]}))
            except Exception as exc:  # every failure becomes a response; the worker keeps serving
                resp = error_response(job.id, exc)
            self.outbox.put(("response", resp))
            self.done.append({"id": job.id, "ok": resp["ok"]})
            self.running = None

    def save(self, job, resp):
        model = job.mechanism
        budget = budget_from_dict(resp["budget"], dict(zip(model.param_names, model.param_kinds)))
        self.budget_dir.mkdir(parents=True, exist_ok=True)
        safe = "".join(c if c.isalnum() or c in "-_" else "_" for c in str(job.id))
        path = self.budget_dir / f"{job['robot']}_{safe}.yaml"
        return budget.save(path, units={"length": "mm", "angle": "rad"},
                           kinds=dict(zip(model.param_names, model.param_kinds)))

    def flush_outbox(self):
        while True:
            try:
                kind, doc = self.outbox.get_nowait()
            except queue.Empty:
                return
            if kind == "progress":
                self.progress_pub.publish(String(data=dumps_fast(doc)))
            elif kind == "budget":
                self.budget_pub.publish(String(data=dumps_fast(doc)))
            else:
                self.publish(doc)

    def publish(self, doc):
        self.responses.publish(String(data=dumps_fast(doc)))

    def close(self):
        self.jobs.put(None)


def main(args=None):
    run(ToleranceAllocator, args)


if __name__ == "__main__":
    main()
