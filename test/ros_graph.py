"""Nodes started in a private rclpy context, for the tests of the nodes (import it only once rclpy is
known to be importable)."""
import threading
import time
import uuid

import rclpy
from rclpy.executors import MultiThreadedExecutor
from rclpy.parameter import Parameter

from helpers import private_domain_id
from tolerance_ros.nodes.client import ToleranceClient


class Graph:
    """A private rclpy context with an executor spinning in a thread; nodes are started in it. With
    ``spin=False`` nothing spins: the test calls the nodes' callbacks itself."""

    def __init__(self, spin=True):
        self.context = rclpy.Context()
        rclpy.init(context=self.context, domain_id=private_domain_id(100, 80))
        self.executor = MultiThreadedExecutor(num_threads=4, context=self.context) if spin else None
        self.nodes = []
        self.thread = None
        self._stop = threading.Event()
        if spin:
            self.thread = threading.Thread(target=self._spin, daemon=True)
            self.thread.start()

    def _finish_callbacks(self, timeout):
        """Wait for the callbacks the executor's pool still runs, and raise what they raised, before the nodes
        are destroyed: Jazzy's ``Executor.shutdown`` does not wait for them (it tests ``_is_shutdown`` just after
        setting it), and a timer callback that runs after its node's destruction fails with "cannot use
        Destroyable", printed as an exception never retrieved."""
        deadline = time.monotonic() + timeout
        for task in list(getattr(self.executor, "_futures", [])):
            while not task.done() and time.monotonic() < deadline:
                time.sleep(0.01)
            if task.done():
                task.result()

    def _spin(self):
        """``executor.spin()`` until close(): the thread has left the executor before close() shuts it down
        (``Executor.shutdown`` destroys the guard condition a spinning thread still waits on)."""
        while not self._stop.is_set() and self.context.ok():
            self.executor.spin_once(timeout_sec=0.05)

    def start(self, cls, namespace=None, **params):
        node = cls(context=self.context, namespace=namespace,
                   parameter_overrides=[Parameter(k, value=v) for k, v in params.items()])
        self._add(node)
        return node

    def node(self, name, namespace=None):
        node = rclpy.create_node(name, context=self.context, namespace=namespace)
        self._add(node)
        return node

    def _add(self, node):
        if self.executor is not None:
            self.executor.add_node(node)
        self.nodes.append(node)

    def client(self, namespace=None):
        return ToleranceClient(node=self.node(f"client_{uuid.uuid4().hex[:8]}"), namespace=namespace)

    def close(self):
        if self.executor is not None:
            self._stop.set()
            self.thread.join(timeout=5.0)
            self._finish_callbacks(5.0)
            self.executor.shutdown(timeout_sec=5.0)
        for n in self.nodes:
            if hasattr(n, "close"):
                n.close()
            n.destroy_node()
        rclpy.shutdown(context=self.context)


def wait_for(predicate, timeout=20.0, step=0.05):
    """True as soon as ``predicate()`` is, False after ``timeout`` seconds."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(step)
    return False
