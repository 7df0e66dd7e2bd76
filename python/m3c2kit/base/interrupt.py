"""A stop the user asked for (SIGINT, SIGTERM, SIGHUP, SIGQUIT) is never lost. The command line's
handlers raise it; Python drops an exception raised inside a callback (an import lock's weak
reference, a finaliser) and hands it to sys.unraisablehook, so a SIGINT while a run imported laspy
was swallowed and the run went on to exit 0 with its output (issue 42). While a run lasts, the hook
keeps such a swallowed stop; the atomic writer asks :func:`check` before it publishes anything,
which raises it there, and no output appears. A stop that unwinds normally is not kept: the
cleanup it runs (a series step recording what it finished) may still write.

Publishing is not interruptible (:func:`deferred`): a stop arriving while the atomic writer renames
its outputs into place waits until every one is in place (never some new and some old), and then
ends the run. The files a run published are noted (:func:`note_published`), so that a stop after
them says they are whole instead of "no output written" (hostile round: a SIGINT just after
`convert` published its copy ended with that message, and the copy was there)."""
from __future__ import annotations

import signal
import sys
from contextlib import contextmanager

from .errors import M3C2Error

__all__ = ["Interrupted", "stop", "handled", "check", "deferred", "note_published", "published"]

_swallowed: list[BaseException] = []
_pending: list[BaseException] = []  # stops that arrived while publishing was deferred
_deferring: list[bool] = []
_published: list = []  # the outputs this run published, in order


class Interrupted(M3C2Error):
    """SIGTERM, SIGHUP or SIGQUIT during a run (SIGINT is KeyboardInterrupt, as Python raises it)."""


def _stop_of(signum) -> BaseException:
    if signum == signal.SIGINT:
        return KeyboardInterrupt()
    return Interrupted(f"interrupted by {signal.Signals(signum).name}; no output written")


def stop(signum, frame) -> None:
    """The signal handler: the stop, raised where the run is (kept for later while publishing)."""
    if _deferring:
        _pending.append(_stop_of(signum))
        return
    raise _stop_of(signum)


@contextmanager
def deferred():
    """A block that stops do not interrupt (the renames that publish outputs): a stop arriving
    inside is raised when it ends."""
    _deferring.append(True)
    try:
        yield
    finally:
        _deferring.pop()
    if _pending and not _deferring:
        raise _pending.pop(0)


def note_published(paths) -> None:
    """The outputs the run just published, whole (the atomic writer's)."""
    _published.extend(paths)


def published() -> list:
    """The outputs this run has published so far."""
    return list(_published)


@contextmanager
def handled(signals):
    """`signals` raise :func:`stop` inside the block, and a stop Python swallows is kept for check()."""
    previous_hook = sys.unraisablehook

    def keep_swallowed(unraisable) -> None:
        if isinstance(unraisable.exc_value, (KeyboardInterrupt, Interrupted)):
            _swallowed.append(unraisable.exc_value)
        else:
            previous_hook(unraisable)

    _swallowed.clear()
    _pending.clear()
    _published.clear()
    sys.unraisablehook = keep_swallowed
    previous = {s: signal.signal(s, stop) for s in signals}
    try:
        yield
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
        sys.unraisablehook = previous_hook
        _swallowed.clear()


def check() -> None:
    """Raise a stop that was swallowed where it was first raised."""
    if _swallowed:
        raise _swallowed.pop(0)
