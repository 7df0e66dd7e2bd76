"""A stop the user asked for (SIGINT, SIGTERM, SIGHUP, SIGQUIT) is never lost. The command line's
handlers raise it; Python drops an exception raised inside a callback (an import lock's weak
reference, a finaliser) and hands it to sys.unraisablehook, so a SIGINT while a run imported laspy
was swallowed and the run went on to exit 0 with its output (issue 42). While a run lasts, the hook
keeps such a swallowed stop; the atomic writer asks :func:`check` before it publishes anything,
which raises it there, and no output appears. A stop that unwinds normally is not kept: the
cleanup it runs (a series step recording what it finished) may still write."""
from __future__ import annotations

import signal
import sys
from contextlib import contextmanager

from .errors import M3C2Error

__all__ = ["Interrupted", "stop", "handled", "check"]

_swallowed: list[BaseException] = []


class Interrupted(M3C2Error):
    """SIGTERM, SIGHUP or SIGQUIT during a run (SIGINT is KeyboardInterrupt, as Python raises it)."""


def stop(signum, frame) -> None:
    """The signal handler: the stop, raised where the run is."""
    if signum == signal.SIGINT:
        raise KeyboardInterrupt
    raise Interrupted(f"interrupted by {signal.Signals(signum).name}; no output written")


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
