"""A small Python client for the JSON services: send a request, wait for the response with the same
id, time out. Hides rclpy like nav2's BasicNavigator does::

    from tolerance_ros.nodes.client import ToleranceClient
    with ToleranceClient(namespace="arm_left") as client:      # the suite of one arm
        client.wait_for_server("compute_error_jacobian", timeout=10.0)
        resp = client.compute_error_jacobian([0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6], arrays="base64")
        print(resp["poses"][0], resp["parameters"][:3])

Answers with ``"arrays": "base64"`` come back with numpy arrays in place of the compact array objects.
Request ids default to ``services.contracts.request_id()``, a uuid4: unique across processes and hosts (in containers every
process may be PID 1, and two clients with PID-based ids took each other's answers).
"""
from __future__ import annotations

import threading
import time
import uuid

import rclpy
from rclpy.executors import SingleThreadedExecutor
from std_msgs.msg import String

from ..core.jsonio import decode_arrays, dumps_fast, loads_strict
from ..services.contracts import request_id
from .common import PREFIX, SERVICE_REQUEST_QOS, SERVICE_RESPONSE_QOS

SERVICES = ("compute_error_jacobian", "allocate_tolerances")


class ServiceError(RuntimeError):
    """The service answered with ok: false; ``code`` and ``response`` carry the details."""

    def __init__(self, response):
        err = response.get("error", {})
        super().__init__(f"{err.get('code')}: {err.get('message')}")
        self.code = err.get("code")
        self.response = response


class ToleranceClient:
    """Client of the JSON services. Creates (and spins in a thread) its own node unless given one.

    namespace : the suite's namespace (e.g. 'arm_left'); None uses the client node's own namespace.
    """

    def __init__(self, node=None, namespace=None):
        self._own = node is None
        self._initialised = False
        if self._own:
            if not rclpy.ok():
                rclpy.init()
                self._initialised = True
            node = rclpy.create_node(f"tolerance_client_{uuid.uuid4().hex[:12]}")
            self._executor = SingleThreadedExecutor()
            self._executor.add_node(node)
            self._thread = threading.Thread(target=self._executor.spin, daemon=True)
            self._thread.start()
        self.node = node
        self._lock = threading.Lock()
        self._responses = {}
        self._events = {}
        self._progress = {}
        self._pubs, self._topics = {}, {}
        ns = (namespace or "").strip("/")
        prefix = PREFIX if namespace is None else (f"/{ns}/{PREFIX}" if ns else f"/{PREFIX}")
        for s in SERVICES:
            base = f"{prefix}/{s}"
            self._topics[s] = base
            self._pubs[s] = node.create_publisher(String, f"{base}/request", SERVICE_REQUEST_QOS)
            node.create_subscription(String, f"{base}/response", self._on_response, SERVICE_RESPONSE_QOS)
        node.create_subscription(String, f"{prefix}/allocate_tolerances/progress", self._on_progress,
                                 SERVICE_RESPONSE_QOS)

    def _on_response(self, msg):
        try:
            doc = loads_strict(msg.data)
        except ValueError:
            return
        if doc.get("arrays") == "base64":
            doc = decode_arrays(doc)
        rid = doc.get("id")
        with self._lock:
            if rid in self._events:
                self._responses.setdefault(rid, []).append(doc)
                self._events[rid].set()

    def _on_progress(self, msg):
        try:
            doc = loads_strict(msg.data)
        except ValueError:
            return
        cb = self._progress.get(doc.get("id"))
        if cb:
            cb(doc)

    def wait_for_server(self, service="compute_error_jacobian", timeout=10.0) -> bool:
        """True once the service's request topic has a subscriber and its response topic a publisher."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            response = self.node.resolve_topic_name(f"{self._topics[service]}/response")
            if self._pubs[service].get_subscription_count() > 0 and self.node.count_publishers(response) > 0:
                return True
            time.sleep(0.05)
        return False

    def request(self, service, payload: dict, timeout=10.0, final=None) -> dict:
        """Send ``payload`` (an id is added if missing) and return the matching response.

        ``final(doc)`` decides whether a response ends the exchange (the allocator first acknowledges).
        Raises TimeoutError, or ServiceError when the response has ok: false.
        """
        payload = dict(payload)
        rid = payload.setdefault("id", request_id())
        ev = threading.Event()
        with self._lock:
            self._events[rid] = ev
        try:
            self._pubs[service].publish(String(data=dumps_fast(payload)))
            deadline = time.monotonic() + timeout
            while True:
                left = deadline - time.monotonic()
                if left <= 0 or not ev.wait(left):
                    raise TimeoutError(f"{service}: no response to id {rid!r} within {timeout} s")
                with self._lock:
                    docs = self._responses.pop(rid, [])
                    ev.clear()
                for doc in docs:
                    if not doc.get("ok", False):
                        raise ServiceError(doc)
                    if final is None or final(doc):
                        return doc
        finally:
            with self._lock:
                self._events.pop(rid, None)
                self._responses.pop(rid, None)

    def compute_error_jacobian(self, joints, timeout=10.0, **fields) -> dict:
        """Jacobian(s), poses, sensitivities (and bounds with ``tolerances=``) at joints (SI)."""
        return self.request("compute_error_jacobian", {"joints": joints, **fields}, timeout)

    def allocate_tolerances(self, limit, timeout=300.0, progress=None, **fields) -> dict:
        """Allocate tolerances for a position limit (m); waits for the finished budget."""
        payload = {"limit": limit, **fields}
        payload.setdefault("id", request_id())
        if progress:
            self._progress[payload["id"]] = progress
        try:
            return self.request("allocate_tolerances", payload, timeout, final=lambda d: d.get("status") == "done")
        finally:
            self._progress.pop(payload["id"], None)

    def close(self):
        """Stop the client's own spinning thread and node (and rclpy, if the client started it)."""
        if self._own:
            self._executor.shutdown(timeout_sec=2.0)
            self._thread.join(timeout=2.0)
            self.node.destroy_node()
            if self._initialised and rclpy.ok():
                rclpy.shutdown()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
