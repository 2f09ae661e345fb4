"""Text rendering for people: tables, numbers and a progress indicator (stderr)."""
from __future__ import annotations

import sys
import threading
import time

import numpy as np


class Progress:
    """Progress on stderr: a bar on a terminal, a line every 10 % otherwise, and at least every ``EVERY``
    seconds from the first call to the last, the elapsed time moving even through a long step (a heartbeat
    thread writes the current state again when the caller has not for ``EVERY`` s); silent with --quiet."""

    EVERY = 1.0

    def __init__(self, label: str, enabled: bool = True, stream=None):
        self.label = label
        self.stream = stream or sys.stderr
        self.enabled = enabled
        self.tty = hasattr(self.stream, "isatty") and self.stream.isatty()
        self.last = -1
        self.start = self.written = time.perf_counter()
        self.frac = 0.0
        self.finished = False
        self._lock = threading.Lock()
        self._beat = None

    def __call__(self, done, total):
        if not self.enabled or total <= 0:
            return
        frac = min(1.0, done / total)
        step = int(frac * (50 if self.tty else 10))
        now = time.perf_counter()
        with self._lock:
            self.frac = max(self.frac, frac)
            if done >= total:
                self.finished = True
            if self._beat is None and not self.finished:
                self._beat = threading.Thread(target=self._heartbeat, name="progress", daemon=True)
                self._beat.start()
            if step == self.last and done < total and now - self.written < self.EVERY:
                return
            self.last = step
            self._write(now, done >= total)

    def _write(self, now, end=False):
        self.written = now
        elapsed = now - self.start
        if self.tty:
            bar = "#" * int(self.frac * 30)
            self.stream.write(f"\r{self.label} [{bar:<30}] {self.frac * 100:5.1f}% {elapsed:6.1f}s")
            if end:
                self.stream.write("\n")
        else:
            self.stream.write(f"{self.label}: {self.frac * 100:.0f}% ({elapsed:.1f}s)\n")
        self.stream.flush()

    def _heartbeat(self):
        while True:
            time.sleep(self.EVERY / 4)
            with self._lock:
                if self.finished:
                    return
                now = time.perf_counter()
                if now - self.written >= self.EVERY:
                    try:
                        self._write(now)
                    except (OSError, ValueError):  # the stream is gone: the process is ending
                        return


def table(headers, rows, aligns=None) -> str:
    """Plain-text table with right-aligned numbers."""
    cells = [[str(h) for h in headers]] + [[str(c) for c in r] for r in rows]
    widths = [max(len(r[i]) for r in cells) for i in range(len(headers))]
    aligns = aligns or ["<"] + [">"] * (len(headers) - 1)
    lines = []
    for k, r in enumerate(cells):
        lines.append("  ".join(f"{c:{a}{w}}" for c, a, w in zip(r, aligns, widths)).rstrip())
        if k == 0:
            lines.append("  ".join("-" * w for w in widths))
    return "\n".join(lines)


def fmt(x, digits=4) -> str:
    if x is None or (isinstance(x, float) and not np.isfinite(x)):
        return "inf" if x is not None and x > 0 else "-"
    return f"{x:.{digits}g}" if abs(x) >= 1e4 or (abs(x) < 1e-3 and x != 0) else f"{x:.{digits}f}"


def length_text(m, digits=3) -> str:
    """A length (m) in the unit of its size: um below 1 mm, mm below 1 m, else m (``digits`` significant)."""
    if m is None or not np.isfinite(m):
        return "-"
    a = abs(m)
    value, unit = (m * 1e6, "um") if a < 1e-3 else (m * 1e3, "mm") if a < 1.0 else (m, "m")
    return f"{value:.{digits}g} {unit}"
