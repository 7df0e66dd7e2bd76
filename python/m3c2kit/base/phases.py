"""Progress over every phase of a run (reading, indexing, normals, distances, writing) with tqdm:
``tqdm.auto`` draws a widget in notebooks and a text bar on a terminal.

Shown on stderr only when it is a terminal, or when forced (``enabled=True``); never on a pipe or
a log file unless asked. Without tqdm (the ``progress`` extra) each phase is one line on the
stream when it ends (``m3c2: reading done in 1.2 s``). No ETA is shown before :data:`ETA_AFTER` of a phase is done (the first
seconds of a run, spent building indexes, say nothing about the rest), and the rate is the
average since the phase began (``smoothing=0``), not a jumpy instantaneous one.

    >>> with Phases() as p:
    ...     with p.phase("reading", total=2) as step:
    ...         step(1, 2); step(2, 2)
    ...     with p.phase("distances", total=n) as step:
    ...         m3c2kit.compare(..., progress=step)   # the engine's progress(done, total) callback
"""
from __future__ import annotations

import contextlib
import sys
import time
from typing import Callable, Iterator

__all__ = ["Phases", "PHASES", "ETA_AFTER"]

#: The phases of a compare run, in order.
PHASES = ("reading", "indexing", "normals", "distances", "writing")
#: Each phase's span of a whole run, in percent, for `--progress json`'s "percent" (the one place
#: of these names: the QGIS runner reads the percent, not the names). A phase not listed is a
#: run of its own (0 to 100).
RUN_SPANS = {"reading": (0.0, 10.0), "indexing, normals, distances": (10.0, 95.0), "indexing, normals": (10.0, 95.0),
             "writing": (95.0, 100.0)}
#: Share of a phase after which its ETA is shown.
ETA_AFTER = 0.03

_WAITING = "{desc}: {percentage:3.0f}%|{bar}| {n_fmt}/{total_fmt} [{elapsed}, ETA soon]"
_RUNNING = "{desc}: {percentage:3.0f}%|{bar}| {n_fmt}/{total_fmt} [{elapsed}<{remaining}]"


class Phases:
    """One progress bar per phase. `enabled`: None (default) shows the bars when `stream`
    (default stderr) is a terminal, True always, False never."""

    def __init__(self, enabled: bool | None = None, stream=None, mininterval: float = 0.2, json: bool = False) -> None:
        self.stream = stream if stream is not None else sys.stderr
        if enabled is None:
            isatty = getattr(self.stream, "isatty", None)
            enabled = bool(isatty and isatty())
        self.enabled = enabled
        self.mininterval = mininterval
        self.json = json
        self.seconds: dict[str, float] = {}  # each phase's wall time, shown or not (--verbose prints them)

    def __enter__(self) -> "Phases":
        return self

    def __exit__(self, *exc) -> None:
        return None

    @contextlib.contextmanager
    def _plain(self, name: str) -> Iterator[Callable[[int, int], bool]]:
        start = time.monotonic()
        self.stream.write(f"m3c2: {name}...\n")
        self.stream.flush()
        yield lambda done, total=None: True
        self.stream.write(f"m3c2: {name} done in {time.monotonic() - start:.1f} s\n")
        self.stream.flush()

    @contextlib.contextmanager
    def _json(self, name: str, total: int | None) -> Iterator[Callable[[int, int], bool]]:
        """One JSON line at the start, at most one per `mininterval` while it runs, one at its end."""
        import json
        start, stop = RUN_SPANS.get(name, (0.0, 100.0))
        state = {"done": 0, "total": total, "at": 0.0}

        def write(done: int, total_now: int | None) -> None:
            share = min(done / total_now, 1.0) if total_now else 0.0
            line = {"phase": name, "done": int(done), "total": total_now, "percent": round(start + (stop - start) * share, 2)}
            self.stream.write(json.dumps(line) + "\n")
            self.stream.flush()
            state["at"] = time.monotonic()

        def update(done: int, total_now: int | None = None) -> bool:
            if total_now is not None:
                state["total"] = total_now
            done = max(int(done), state["done"])  # monotone, whatever the caller reports
            state["done"] = done
            if time.monotonic() - state["at"] >= self.mininterval:
                write(done, state["total"])
            return True

        write(0, total)
        yield update
        write(state["total"] or state["done"], state["total"] or state["done"] or None)

    @contextlib.contextmanager
    def phase(self, name: str, total: int | None = None) -> Iterator[Callable[[int, int], bool]]:
        """A context whose value is ``update(done, total) -> True``, the engine's callback; its
        wall time is added to :attr:`seconds`."""
        start = time.monotonic()
        try:
            with self._shown(name, total) as update:
                yield update
        finally:
            self.seconds[name] = self.seconds.get(name, 0.0) + time.monotonic() - start

    def timing_line(self) -> str:
        """``time: reading 0.12 s, indexing, normals, distances 1.30 s, writing 0.05 s``."""
        return "time: " + "; ".join(f"{name} {s:.2f} s" for name, s in self.seconds.items())

    @contextlib.contextmanager
    def _shown(self, name: str, total: int | None) -> Iterator[Callable[[int, int], bool]]:
        if not self.enabled:
            yield lambda done, total=None: True
            return
        if self.json:
            with self._json(name, total) as update:
                yield update
            return
        try:
            from tqdm.auto import tqdm
        except ImportError:  # the progress extra is not installed: plain lines
            with self._plain(name) as update:
                yield update
            return

        bar = tqdm(total=total, desc=name, file=self.stream, smoothing=0, mininterval=self.mininterval,
                   bar_format=_WAITING if total else None, dynamic_ncols=True, leave=True)
        state = {"eta": False}

        def update(done: int, total_now: int | None = None) -> bool:
            if total_now is not None and total_now != bar.total:
                bar.total = total_now
            if bar.total and not state["eta"] and done >= ETA_AFTER * bar.total:
                bar.bar_format = _RUNNING
                state["eta"] = True
            bar.update(max(0, done - bar.n))
            return True

        try:
            yield update
        finally:
            if bar.total and bar.n < bar.total and not state["eta"]:
                bar.bar_format = _RUNNING
            bar.close()
