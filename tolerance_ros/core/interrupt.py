"""Stopping a long computation from outside: a cancel flag and a wall-clock deadline.

A worker runs a solve inside ``watching(token)``; the solvers' loops call ``check()``, which raises
``Interrupted('cancelled' | 'timeout')`` once the token is cancelled or its deadline has passed, so a
cancel takes effect within one loop step (well under a second). ``record_best`` keeps the best
verified result so far on the token, for the answer to a timeout. Outside ``watching``, ``check()``
does nothing.
"""
from __future__ import annotations

import contextvars
import threading
import time
from contextlib import contextmanager


class Interrupted(Exception):
    """A computation stopped from outside; ``reason`` is 'cancelled' or 'timeout'."""

    def __init__(self, reason: str, message: str):
        super().__init__(message)
        self.reason = reason


class StopToken:
    """A cancel flag and an optional wall-clock limit (s, from now); ``best`` holds what ``record_best`` kept."""

    def __init__(self, time_limit_s: float | None = None):
        self.cancelled = threading.Event()
        self.time_limit_s = time_limit_s
        self.deadline = None if time_limit_s is None else time.monotonic() + time_limit_s
        self.best = None

    def cancel(self):
        self.cancelled.set()

    def check(self):
        if self.cancelled.is_set():
            raise Interrupted("cancelled", "cancelled on request")
        if self.deadline is not None and time.monotonic() > self.deadline:
            raise Interrupted("timeout", f"stopped at the wall-clock limit of {self.time_limit_s:g} s")


_CURRENT = contextvars.ContextVar("tolerance_ros_stop_token", default=None)


@contextmanager
def watching(token: StopToken):
    """Run the body with ``token`` as the one ``check()`` consults (in this thread)."""
    reset = _CURRENT.set(token)
    try:
        yield token
    finally:
        _CURRENT.reset(reset)


def check():
    """Raise Interrupted if the current token says stop; a no-op outside ``watching``."""
    token = _CURRENT.get()
    if token is not None:
        token.check()


def record_best(result):
    """Keep ``result`` as the best verified result so far on the current token (if any)."""
    token = _CURRENT.get()
    if token is not None:
        token.best = result
