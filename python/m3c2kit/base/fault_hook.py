"""A testing aid, not a feature (docs/errors.md, "Interruption"): with the environment variable
``M3C2_TEST_SIGNAL_AT=PHASE:SIGNAL`` a run sends itself SIGNAL (a name such as ``SIGTERM`` or a
number) the first time it reaches PHASE, so that a test can kill a real ``m3c2`` run at a known
point without sleeping. The phases, each one call of :func:`checkpoint`:

- ``reading``: a point-cloud file has been read (``io.read_cloud``) or its first chunk streamed
  (``io.streaming.PointSource.chunks``; a tiled run is writing its spill files then);
- ``computing``: the engine runs (``engine.compute``: at its first progress callback, inside the
  computation, or just before it when no callback is given, as for a tile);
- ``staging``: an output's private folders exist (each locked), before anything is written in them
  (``io.atomic.staged_outputs``, ``io.atomic.staged_directory``, a tiled run's spill folder:
  ``run.tiled``); a test stops a real run there (``SIGSTOP``) to attack its folders;
- ``writing``: every temporary of an output is written, before any is renamed onto its target
  (``io.atomic.staged_outputs``);
- ``store-write``: a series step is about to write a store's chunks (store.append_batch: create,
  add, import; analysis: smooth's and objects' new variables in the staging folder);
- ``store-commit``: a series step is about to consolidate the store's metadata (store.commit:
  a batch of epochs, a published variable).

Unset (always, outside tests) it costs one environment lookup per phase; a malformed value does
nothing. Each phase fires at most once per process.
"""
from __future__ import annotations

import os
import signal

from . import portable

__all__ = ["ENV", "PHASES", "checkpoint"]

ENV = "M3C2_TEST_SIGNAL_AT"
PHASES = ("reading", "computing", "staging", "writing", "store-write", "store-commit")
_fired: set[str] = set()


def _signal_number(name: str) -> int | None:
    if name.isdigit():
        return int(name)
    number = getattr(signal, name.upper(), None)
    return int(number) if isinstance(number, int) else None


def armed(phase: str) -> bool:
    """True when ENV asks for a signal at `phase` and it has not fired yet."""
    spec = os.environ.get(ENV)
    return bool(spec) and spec.partition(":")[0] == phase and phase not in _fired


def checkpoint(phase: str) -> None:
    """Sends this process the signal ENV names when ENV names `phase` (once per phase)."""
    if not armed(phase):
        return
    number = _signal_number(os.environ[ENV].partition(":")[2].strip())
    if number is None:
        return
    _fired.add(phase)
    portable.signal_self(number)
