"""A small progress bar on stderr for long work (loading big scenes, benchmarks, training, batches).

It stays silent for work that finishes within ``delay`` seconds. On a terminal it redraws one line;
into a log (CI) it prints a line at most every 10 % so logs stay short.
"""

from __future__ import annotations

import sys
import time
from typing import TextIO


class Progress:
    """``with Progress("loading scene.ply", total) as p: p.update(done, info="…")``."""

    def __init__(self, label: str, total: int, stream: TextIO | None = None, delay: float = 0.5,
                 unit: str = "") -> None:
        self.label, self.total, self.unit = label, max(int(total), 1), unit
        self.stream = stream or sys.stderr
        self.delay = delay
        self.start = time.perf_counter()
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self._last_decile = -1
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
        if self.tty:
            bar = "█" * int(frac * 24) + "·" * (24 - int(frac * 24))
            eta = elapsed / frac - elapsed if frac > 0 else 0.0
            line = f"\r{self.label} {bar} {done}/{self.total}{self.unit} {elapsed:5.1f}s eta {eta:5.1f}s {info}"
            self.stream.write(line[:160].ljust(100))
            self.stream.flush()
            self._shown = True
        else:
            decile = int(frac * 10)
            if decile > self._last_decile and (self._shown or elapsed >= self.delay):
                self._last_decile = decile
                self.stream.write(f"{self.label}: {done}/{self.total}{self.unit} ({frac:.0%}, {elapsed:.1f}s) {info}\n")
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
