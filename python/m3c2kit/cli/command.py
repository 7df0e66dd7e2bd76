"""The `m3c2` command's entry point (pyproject.toml's [project.scripts], and `python -m m3c2kit`).

Until cli/main.py installs its handlers (base/interrupt.py), a Ctrl-C would land in the middle of
an import as Python's KeyboardInterrupt, a traceback. Nothing can have been written yet, so this
module's first statement makes such a stop what any stop before an output is: "interrupted; no
output written", exit status 1 (cli/main.py's _interrupted). Only the command does this: importing
m3c2kit as a library leaves the caller's handler alone."""
import os
import signal


def _stopped_before_the_run(number, frame) -> None:
    os.write(2, f"m3c2: error: interrupted by {signal.Signals(number).name}; no output written\n".encode())
    os._exit(1)  # nothing to unwind: no file is open, no folder made


if signal.getsignal(signal.SIGINT) is signal.default_int_handler:  # not a caller's SIG_IGN (nohup)
    signal.signal(signal.SIGINT, _stopped_before_the_run)


def main(argv=None) -> int:
    from .main import main as run

    # Python's own again: the run replaces it with its handlers at once, and whatever it wrote is
    # then said by them, never by the message above.
    if signal.getsignal(signal.SIGINT) is _stopped_before_the_run:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    return run(argv)
