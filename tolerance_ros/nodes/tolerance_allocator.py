"""Tolerance allocator (node ``tolerance_allocator``): the JSON service ``allocate_tolerances`` on
``tolerance/allocate_tolerances/request`` -> ``.../response`` (relative to the namespace). Solves run in
a worker thread with one BLAS thread (``services.allocation.AllocatorService``): other requests are
acknowledged and queued, ``status`` and ``cancel`` are answered at once, progress goes to
``.../progress``; a finished budget is saved to ``budget_dir`` and, when it meets its limit, published
on ``tolerance_budget`` (transient local: late subscribers get it)."""
from __future__ import annotations

from pathlib import Path

from rclpy.node import Node
from std_msgs.msg import String

from ..core.budget import budget_from_dict
from ..core.jsonio import dumps_fast
from ..services.allocation import MAX_TIME_LIMIT_S, AllocatorService
from ..services.jobs import Outbox
from ..services.contracts import Limits
from .common import (ALLOCATE_TOPIC, BUDGET_QOS, SERVICE_REQUEST_QOS, SERVICE_RESPONSE_QOS, declare,
                     follow_robot_description, guarded, robot_set, run, served_robots)


class ToleranceAllocator(Node):
    NODE_NAME = "tolerance_allocator"

    def __init__(self, **node_options):
        super().__init__(self.NODE_NAME, **node_options)
        self.setup()

    def setup(self):
        """Parameters, robots, files, publishers, subscriptions and timers: what a managed node's configure does."""
        specs, default = served_robots(self)
        self.budget_dir = Path(declare(self, "budget_dir", str(Path.home() / ".ros" / "tolerance_ros" / "budgets"),
                                       "directory where finished budgets are saved (YAML, mm and rad)")).expanduser()
        max_queue = declare(self, "max_queue", 4, "allocation requests that may wait behind the running one",
                            (0, 1000))
        max_bytes = declare(self, "max_request_bytes", 100_000, "size cap of a request, bytes", (1, 1 << 30))
        max_time = declare(self, "max_time_limit", MAX_TIME_LIMIT_S, "largest wall-clock limit a request may ask "
                                                                     "for, s (also the default limit when below 300 s)",
                           (0.1, 86_400.0))
        self.outbox = Outbox()
        self.service = AllocatorService(robot_set(self, specs, default), self.outbox, Limits(max_bytes, 10_000),
                                        max_queue, self.save, float(max_time))
        self.responses = self.create_publisher(String, f"{ALLOCATE_TOPIC}/response", SERVICE_RESPONSE_QOS)
        self.progress_pub = self.create_publisher(String, f"{ALLOCATE_TOPIC}/progress", SERVICE_RESPONSE_QOS)
        self.budget_pub = self.create_publisher(String, "tolerance_budget", BUDGET_QOS)
        self.create_subscription(String, f"{ALLOCATE_TOPIC}/request", guarded(self, self.on_request),
                                 SERVICE_REQUEST_QOS)
        follow_robot_description(self, self.service.robots)
        self.create_timer(0.05, guarded(self, self.flush_outbox))
        self.get_logger().info(f"serving {sorted(self.service.robots.models) or 'robot_description'} on "
                               f"{self.resolve_topic_name(ALLOCATE_TOPIC + '/request')}; budgets saved in "
                               f"{self.budget_dir}")

    def on_request(self, msg):
        self.service.handle(msg.data)

    def save(self, job, resp):
        """Save a finished budget as YAML (mm and rad) in ``budget_dir``; returns its path."""
        model = job.mechanism
        kinds = dict(zip(model.param_names, model.param_kinds))
        budget = budget_from_dict(resp["budget"], kinds)
        safe = "".join(c if c.isalnum() or c in "-_" else "_" for c in str(job.id))[:80]
        return budget.save(self.budget_dir / f"{job.robot}_{safe}.yaml", units={"length": "mm", "angle": "rad"},
                           kinds=kinds)

    def flush_outbox(self):
        publishers = {"progress": self.progress_pub, "budget": self.budget_pub, "response": self.responses}
        for kind, doc in self.outbox.drain():
            publishers[kind].publish(String(data=dumps_fast(doc)))

    def close(self):
        self.service.close()


def main(args=None):
    run(ToleranceAllocator, args)


if __name__ == "__main__":
    main()
