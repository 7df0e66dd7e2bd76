"""A progress bar with ETA on a terminal's stderr; silent when not a terminal or disabled."""
from __future__ import annotations

import sys
import time


class ProgressBar:
    """update(done, total) is the engine's progress callback; it always returns True (go on)."""

    def __init__(self, label: str, enabled: bool = True, stream=None, min_interval: float = 0.2):
        self.stream = stream or sys.stderr
        self.enabled = enabled and self.stream.isatty()
        self.label = label
        self.start = time.monotonic()
        self.last = 0.0
        self.min_interval = min_interval
        self.shown = False

    def update(self, done: int, total: int) -> bool:
        if not self.enabled:
            return True
        now = time.monotonic()
        if now - self.last < self.min_interval and done < total:
            return True
        self.last = now
        elapsed = now - self.start
        fraction = done / total if total else 1.0
        eta = elapsed * (1 - fraction) / fraction if fraction > 0 else float("nan")
        width = 30
        bar = "#" * int(width * fraction) + "-" * (width - int(width * fraction))
        self.stream.write(f"\r{self.label} [{bar}] {100 * fraction:5.1f}% {done}/{total} "
                          f"elapsed {elapsed:6.1f}s ETA {eta:6.1f}s")
        self.stream.flush()
        self.shown = True
        return True

    def close(self) -> None:
        if self.shown:
            self.stream.write("\n")
            self.stream.flush()
