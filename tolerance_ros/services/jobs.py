"""Services whose jobs run for a while (an allocation, a calibration), ROS-free: requests are acknowledged at
once (``status: accepted``) and queued, ``status`` and ``cancel`` are answered at once, the jobs run one at a
time in a worker thread with the numerical libraries capped to one thread, a cancelled or timed-out job stops
within a loop step, and everything goes out through ``emit(kind, doc)`` (kind 'response', 'progress', or a
subclass's own, such as 'budget')."""
from __future__ import annotations

import json
import threading
import time
from collections import deque
from dataclasses import dataclass

from ..core import interrupt, threads
from .contracts import ContractError, answer_id, error_response, valid_id

MAX_FINISHED = 100  # finished jobs the status answer can list (it shows the last 10)



@dataclass(frozen=True)
class Command:
    """A request that is not a job: ``command`` is 'status' or 'cancel' (of job ``target``)."""

    id: object
    command: str
    target: object = None


def command_of(req, work: str):
    """The Command of a parsed request whose ``command`` is 'status' or 'cancel', or None when it asks for
    the service's own ``work`` (its default); ContractError for another command or a cancel without target."""
    commands = (work, "status", "cancel")
    command = req.get("command", work)
    if command not in commands:
        raise ContractError("invalid_request", f"command: expected one of {list(commands)}, got {command[:40]!r}")
    if command == "cancel":
        if "target" not in req or not valid_id(req["target"]):
            raise ContractError("invalid_request", "target: required with command 'cancel': the id of the job")
        return Command(req["id"], command, req["target"])
    return None if command == work else Command(req["id"], command)


class Outbox:
    """What an AllocatorService emits, held for a publisher that drains it periodically (the node's timer):
    every response and budget, in order, and of the progress only each job's latest, so that a publisher that
    falls behind holds one progress message per job, not the history of every solver iteration."""

    def __init__(self):
        self._lock = threading.Lock()
        self._items = deque()
        self._progress = {}

    def __call__(self, kind, doc):
        with self._lock:
            if kind == "progress":
                self._progress[json.dumps(doc["id"])] = doc
            else:
                self._items.append((kind, doc))

    def __len__(self):
        with self._lock:
            return len(self._items) + len(self._progress)

    def drain(self) -> list:
        """[(kind, doc)] held since the last drain: the latest progress of each job, then the rest in order."""
        with self._lock:
            out = [("progress", doc) for doc in self._progress.values()] + list(self._items)
            self._progress.clear()
            self._items.clear()
        return out


@dataclass(eq=False)
class _Entry:
    """An accepted job, its stop token (deadline counted from acceptance) and whether its final answer is out."""

    job: object
    token: interrupt.StopToken
    answered: bool = False


class JobService:
    """Queue, worker and answers of a service whose jobs run for a while; ROS-free. Subclasses give
    ``KIND`` (its name in messages), ``parse(text)`` (a job with ``id`` and ``time_limit_s``, or a
    ``Command``), ``run(job, progress)`` (the response dict; ``interrupt.check()`` inside stops it) and
    ``deliver(job, response)`` (what a finished job does besides its answer).

    emit(kind, doc) : called from the caller's thread, the worker's and the watchdog's.

    A job's ``time_limit`` counts from its acceptance, and a watchdog thread answers ``timeout`` at that
    moment (with the best verified result so far) whether the job still waits in the queue or its solve
    is inside a long step; a cancel is answered at once. The worker drops the result of a job that was
    answered meanwhile. What is kept per job ends with the job; the finished list keeps the last
    ``MAX_FINISHED``.
    """

    KIND = "job"

    def __init__(self, emit, max_queue: int = 4):
        self.emit = emit
        self.max_queue = int(max_queue)
        self.lock = threading.Condition(threading.RLock())  # emit may call back into the service
        self.queue = deque()      # _Entry of the jobs waiting
        self.current = None       # _Entry of the solve under way
        self.done = deque(maxlen=MAX_FINISHED)
        self.closed = False
        self.worker = threading.Thread(target=self._work, name=self.KIND, daemon=True)
        self.watchdog = threading.Thread(target=self._watch, name=f"{self.KIND}-watchdog", daemon=True)
        self.worker.start()
        self.watchdog.start()

    @property
    def running(self):
        """(job, StopToken) of the solve under way, or None."""
        entry = self.current
        return None if entry is None else (entry.job, entry.token)

    def busy(self) -> bool:
        """True while a job runs or waits."""
        with self.lock:
            return self.current is not None or bool(self.queue)

    def handle(self, text):
        """Answer one request text (never raises)."""
        try:
            job = self.parse(text)
        except Exception as exc:  # every failure becomes a response
            self.emit("response", error_response(answer_id(exc, text), exc))
            return
        if isinstance(job, Command):
            self._command(job)
            return
        with self.lock:
            if len(self.queue) >= self.max_queue:
                self.emit("response", error_response(job.id, ContractError(
                    "busy", f"{self.KIND} queue is full ({self.max_queue} waiting); retry later")))
                return
            self.queue.append(_Entry(job, interrupt.StopToken(job.time_limit_s)))
            self.emit("response", {"id": job.id, "ok": True, "status": "accepted", "queued": len(self.queue),
                                   "running": self._running_id()})
            self.lock.notify_all()

    def _command(self, cmd: Command):
        with self.lock:
            if cmd.command == "status":
                self.emit("response", {"id": cmd.id, "ok": True, "status": "status", "running": self._running_id(),
                                       "queued": len(self.queue), "finished": list(self.done)[-10:]})
                return
            for entry in ([self.current] if self.current else []) + list(self.queue):
                if entry.job.id == cmd.target and not entry.answered:
                    entry.token.cancel()
                    if entry is not self.current:
                        self.queue.remove(entry)
                    self._finish(entry, {**error_response(entry.job.id, ContractError(
                        "cancelled", f"cancelled by request {cmd.id!r}")), "status": "cancelled"})
                    self.emit("response", {"id": cmd.id, "ok": True, "status": "cancelled", "target": entry.job.id})
                    return
        self.emit("response", error_response(cmd.id, ContractError(
            "invalid_request", f"target: no queued or running {self.KIND} has id {cmd.target!r}")))

    def _running_id(self):
        """Id of the job being solved, None when there is none or it is already answered (still stopping)."""
        entry = self.current
        return entry.job.id if entry is not None and not entry.answered else None

    def _finish(self, entry, resp):
        """Send the final answer of a job once (the caller holds the lock)."""
        entry.answered = True
        self.done.append({"id": entry.job.id, "ok": resp["ok"], "status": resp.get("status", "error")})
        self.emit("response", resp)

    def _work(self):
        while True:
            with self.lock:
                while not self.queue and not self.closed:
                    self.lock.wait()
                if self.closed:
                    return
                entry = self.queue.popleft()
                if entry.answered:
                    continue
                self.current = entry
            resp = self._solve(entry)
            with self.lock:
                self.current = None
                if not entry.answered and resp is not None:
                    self._deliver(entry, resp)
                self.lock.notify_all()

    def _deliver(self, entry, resp):
        """A finished job's own effects, then its answer (the caller holds the lock)."""
        if resp.get("status") == "done":
            self.deliver(entry.job, resp)
        self._finish(entry, resp)

    def parse(self, text):
        raise NotImplementedError

    def run(self, job, progress) -> dict:
        raise NotImplementedError

    def deliver(self, job, resp):
        """What a finished job does besides its answer (nothing by default)."""

    def _watch(self):
        """Answer 'timeout' for every job whose time_limit has passed, waiting or running, on time."""
        with self.lock:
            while not self.closed:
                now = time.monotonic()
                entries = ([self.current] if self.current else []) + list(self.queue)
                for entry in entries:
                    if not entry.answered and entry.token.deadline <= now:
                        waiting = entry is not self.current
                        if waiting:
                            self.queue.remove(entry)
                        where = " while it waited in the queue" if waiting else ""
                        self._finish(entry, {**error_response(entry.job.id, ContractError(
                            "timeout", f"stopped at the wall-clock limit of {entry.job.time_limit_s:g} s{where} "
                                       f"(time_limit)")), "status": "timeout", "best": entry.token.best})
                left = [e.token.deadline for e in entries if not e.answered]
                self.lock.wait(max(0.0, min(left) - time.monotonic()) if left else None)

    def _solve(self, entry):
        """The response to a job; a timeout answer when its solve stopped at the deadline; None when cancelled.
        No progress goes out once the job is answered (while its solve stops)."""
        job, token = entry.job, entry.token
        start = time.perf_counter()

        def progress(done, total):
            if not entry.answered:
                self.emit("progress", {"id": job.id, "fraction": min(1.0, done / max(total, 1)),
                                       "elapsed_s": time.perf_counter() - start})

        try:
            with threads.limited(1), interrupt.watching(token):
                return self.run(job, progress)
        except interrupt.Interrupted as exc:
            if exc.reason == "cancelled":
                return None
            return {**error_response(job.id, ContractError("timeout", f"{exc} (time_limit)")), "status": "timeout",
                    "best": token.best}
        except Exception as exc:  # every failure becomes a response; the worker keeps serving
            return error_response(job.id, exc)

    def close(self):
        """Stop the worker and the watchdog: cancel what runs, drop what waits."""
        with self.lock:
            self.closed = True
            if self.current:
                self.current.token.cancel()
            self.queue.clear()
            self.lock.notify_all()
