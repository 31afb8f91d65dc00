"""A dependency-free progress bar on stderr: done/total, rate and time left."""

from __future__ import annotations

import sys
import time


class Progress:
    """``Progress(total, "label")``; call ``update(done)`` (or ``step()``), then ``close()``.

    On a terminal it redraws one line; otherwise it prints a line at most every 10 % (so CI
    logs stay short). Disabled entirely with ``enabled=False``.
    """

    def __init__(self, total: int, label: str = "", enabled: bool = True, stream=None, start: int = 0):
        self.total = max(int(total), 0)
        self.label = label
        self.stream = stream or sys.stderr
        self.enabled = enabled and self.total > 0
        self.tty = hasattr(self.stream, "isatty") and self.stream.isatty()
        self.t0 = time.perf_counter()
        self.start = start
        self.done = start
        self._last_decile = -1

    def __call__(self, done: int, total: int | None = None) -> None:
        if total is not None:
            self.total = total
        self.update(done)

    def step(self, n: int = 1) -> None:
        self.update(self.done + n)

    def update(self, done: int) -> None:
        self.done = done
        if not self.enabled:
            return
        elapsed = time.perf_counter() - self.t0
        fresh = max(done - self.start, 0)
        rate = fresh / elapsed if elapsed > 0 else 0.0
        left = (self.total - done) / rate if rate > 0 else float("nan")
        frac = done / self.total if self.total else 1.0
        bar = "#" * int(frac * 24)
        eta = "--:--" if left != left else f"{int(left // 60):02d}:{int(left % 60):02d}"
        line = f"{self.label} [{bar:<24}] {done}/{self.total}  {elapsed:6.1f} s elapsed, {eta} left"
        if self.tty:
            self.stream.write("\r" + line)
            self.stream.flush()
        else:
            decile = int(frac * 10)
            if decile != self._last_decile:
                self._last_decile = decile
                self.stream.write(line + "\n")
                self.stream.flush()

    def close(self) -> None:
        if self.enabled and self.tty:
            self.stream.write("\n")
            self.stream.flush()
