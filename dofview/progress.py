"""A small progress bar on stderr for long work (loading big scenes, benchmarks, training, batches).

It stays silent for work that finishes within ``delay`` seconds. On a terminal it redraws one line;
into a log (CI) it prints a line at every 10 %, and at least every ``heartbeat`` seconds so a slow
first step does not look like a hang. Both show the elapsed time and the time left (ETA: the
elapsed time scaled by the fraction done, so steps should cost about alike).
"""

from __future__ import annotations

import sys
import time
from typing import TextIO


class Progress:
    """``with Progress("loading scene.ply", total) as p: p.update(done, info="…")``."""

    def __init__(self, label: str, total: int, stream: TextIO | None = None, delay: float = 0.5,
                 unit: str = "", heartbeat: float = 15.0, resumed: int = 0) -> None:
        """``resumed``: units done before this run (a resumed job); the ETA counts only this run's pace."""
        self.label, self.total, self.unit = label, max(int(total), 1), unit
        self.resumed = resumed
        self.stream = stream or sys.stderr
        self.delay, self.heartbeat = delay, heartbeat
        self.start = time.perf_counter()
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self._last_decile = -1
        self._last_line = -float("inf")
        self._shown = False
        self.done = 0

    def __call__(self, done: int, total: int | None = None) -> None:
        """Callback form: ``progress(done, total)``."""
        if total is not None:
            self.total = max(int(total), 1)
        self.update(done)

    def update(self, done: int, info: str = "") -> None:
        self.done = done
        elapsed = time.perf_counter() - self.start
        if elapsed < self.delay and done < self.total:
            return
        frac = min(done / self.total, 1.0)
        pace = (done - self.resumed) / max(self.total - self.resumed, 1)  # fraction of this run's work
        eta = f"eta {clock(elapsed / pace - elapsed)}" if pace > 0 else "eta ?"
        if self.tty:
            bar = "█" * int(frac * 24) + "·" * (24 - int(frac * 24))
            line = f"\r{self.label} {bar} {done}/{self.total}{self.unit} {clock(elapsed)} {eta} {info}"
            self.stream.write(line[:160].ljust(100))
            self.stream.flush()
            self._shown = True
        else:
            decile = int(frac * 10)
            due = decile > self._last_decile or elapsed - self._last_line >= self.heartbeat
            if due and (self._shown or elapsed >= self.delay):
                self._last_decile, self._last_line = decile, elapsed
                self.stream.write(f"{self.label}: {done}/{self.total}{self.unit} ({frac:.0%}, {clock(elapsed)}, "
                                  f"{eta}) {info}\n")
                self.stream.flush()
                self._shown = True

    def close(self) -> None:
        if self.tty and self._shown:
            self.stream.write("\n")
            self.stream.flush()

    def __enter__(self) -> "Progress":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def clock(seconds: float) -> str:
    """A duration for a progress line: ``4.2s`` under a minute, else ``3m05s`` (or ``1h02m``)."""
    if seconds < 60:
        return f"{seconds:.1f}s"
    m, s = divmod(round(seconds), 60)
    return f"{m}m{s:02d}s" if m < 60 else f"{m // 60}h{m % 60:02d}m"
