"""A stop Python swallowed (raised in a finaliser or a weak reference's callback, where it goes to
sys.unraisablehook) is kept while a run lasts and raised before the atomic writer publishes: no
output appears, as for a stop that unwound (issue 42: a SIGINT while laspy was imported)."""
from __future__ import annotations

import gc
import signal
import sys

import pytest

from m3c2kit.base import interrupt
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
