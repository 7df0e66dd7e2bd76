"""A stop Python swallowed (raised in a finaliser or a weak reference's callback, where it goes to
sys.unraisablehook) is kept while a run lasts and raised before the atomic writer publishes: no
output appears, as for a stop that unwound (issue 42: a SIGINT while laspy was imported)."""
from __future__ import annotations

import gc
import signal
import sys

import pytest

from m3c2kit.base import interrupt, portable
from m3c2kit.io.atomic import atomic_output, staged_directory


class _StopsWhenCollected:
    def __init__(self, stop: BaseException):
        self.stop = stop

    def __del__(self):
        raise self.stop


def _swallow(stop: BaseException) -> None:
    _StopsWhenCollected(stop)  # collected at once: __del__ raises into sys.unraisablehook
    gc.collect()


@pytest.mark.parametrize("stop", [KeyboardInterrupt(), interrupt.Interrupted("interrupted by SIGTERM")])
def test_a_swallowed_stop_is_raised_before_a_file_is_published(tmp_path, stop):
    target = tmp_path / "out.txt"
    with interrupt.handled([]):
        with pytest.raises(type(stop)):
            with atomic_output(target) as tmp:
                tmp.write_text("half")
                _swallow(stop)
    assert list(tmp_path.iterdir()) == []


def test_a_swallowed_stop_is_raised_before_a_folder_is_published(tmp_path):
    with interrupt.handled([]):
        with pytest.raises(KeyboardInterrupt):
            with staged_directory(tmp_path / "out.zarr") as tmp:
                (tmp / "a").write_text("half")
                _swallow(KeyboardInterrupt())
    assert list(tmp_path.iterdir()) == []


def test_other_unraisable_errors_still_reach_the_previous_hook_and_publish(tmp_path):
    seen = []
    previous, sys.unraisablehook = sys.unraisablehook, lambda u: seen.append(u.exc_value)
    try:
        with interrupt.handled([]):
            with atomic_output(tmp_path / "out.txt") as tmp:
                tmp.write_text("whole")
                _swallow(ValueError("a finaliser's own error"))
    finally:
        sys.unraisablehook = previous
    assert (tmp_path / "out.txt").read_text() == "whole"
    assert [str(e) for e in seen] == ["a finaliser's own error"]


def test_outside_a_run_nothing_is_kept_and_handlers_are_restored(tmp_path):
    before = signal.getsignal(signal.SIGTERM)
    with interrupt.handled([signal.SIGTERM]):
        assert signal.getsignal(signal.SIGTERM) is interrupt.stop
    assert signal.getsignal(signal.SIGTERM) is before
    with atomic_output(tmp_path / "out.txt") as tmp:
        tmp.write_text("whole")
    assert (tmp_path / "out.txt").read_text() == "whole"


def test_a_stop_while_publishing_waits_until_every_output_is_in_place():
    """Hostile round: a stop inside the renames would leave some outputs new and some old."""
    import os
    import signal
    from m3c2kit.base import interrupt
    with interrupt.handled([signal.SIGINT]):
        reached = []
        with pytest.raises(KeyboardInterrupt):
            with interrupt.deferred():
                os.kill(os.getpid(), signal.SIGINT)  # the handler keeps it for the block's end
                reached.append("after the signal")
        assert reached == ["after the signal"]


@pytest.mark.parametrize("published, code, message", [
    ([], 1, "m3c2: error: interrupted by SIGINT; no output written\n"),
    # Without POSIX signals (base/portable.py) the process cannot end by its own signal: 128 + 2.
    (["out.csv"], -2 if portable.CAPS.posix_signals else 130,
     "m3c2: error: interrupted by SIGINT after writing out.csv (whole); nothing after it was written\n")])
def test_a_stop_after_an_output_was_published_says_it_is_whole(published, code, message):
    """Hostile round: a SIGINT just after `convert` published its copy ended with "no output
    written" and exit 1, with the copy there. After a publication the run stops by the signal,
    naming what it wrote whole."""
    import subprocess
    import sys
    probe = ("import signal, sys\nfrom m3c2kit.base import interrupt\nfrom m3c2kit.cli import main as m\n"
             f"with interrupt.handled([signal.SIGINT]):\n    interrupt.note_published({published!r})\n"
             "    sys.exit(m._interrupted(KeyboardInterrupt()))\n")
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True)
    assert done.returncode == code and done.stderr == message, (done.returncode, done.stderr)
