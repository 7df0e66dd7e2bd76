"""A writing step on a series store (add, create's epochs, smooth, objects' labels, ...): the
store's folder pinned (io.atomic.pinned_directory: a swap of its name cannot redirect a write),
its lock held (series/lock.py), the store brought back to its last commit (integrity.recover),
and a failure's message saying what the store kept: an interruption (SIGINT, SIGTERM, ...: see
docs/errors.md, "Interruption") or a write error (a full disk) ends as one line naming the store
and what of it is committed, never "no output written" when something was."""
from __future__ import annotations

import re
from contextlib import contextmanager
from pathlib import Path
from typing import Callable

from ..base.errors import M3C2Error
from ..base.interrupt import Interrupted
from . import integrity
from . import lock as lock_mod
from . import store as st
from .store import StoreError


def _signal_name(error: BaseException) -> str:
    """SIGINT for Ctrl-C, else the name the command line's handler wrote ("interrupted by SIGTERM; ...")."""
    if isinstance(error, KeyboardInterrupt):
        return "SIGINT"
    found = re.match(r"interrupted by (\w+)", str(error))
    return found.group(1) if found else "a signal"


def is_interruption(error: BaseException) -> bool:
    """Ctrl-C, or the command line's stop by SIGTERM, SIGHUP or SIGQUIT (base/interrupt.py)."""
    return isinstance(error, (KeyboardInterrupt, Interrupted))


@contextmanager
def guarded(shown: Path, kept: Callable[[], str]):
    """Maps an interruption or a write error inside the block to one line naming `shown` and
    `kept()` (what the store holds then, computed at that moment)."""
    try:
        yield
    except OSError as e:
        raise StoreError(f"{shown}: cannot write: {e.strerror or e}; {kept()}") from None
    except BaseException as e:
        if is_interruption(e):
            raise Interrupted(f"interrupted by {_signal_name(e)}: {kept()}") from None
        raise


@contextmanager
def writing(store: Path, step: str, kept: Callable[[Path], str], *, held: "lock_mod.StoreLock | None" = None):
    """Yields the store's pinned folder with its lock held (or `held`, a lock taken already, as
    create takes it in its private folder before publishing the store) and its state that of its
    last commit. `kept(folder)`: what the store holds, for the message of a failure."""
    from ..io.atomic import pinned_directory
    store = Path(store)
    try:
        # Errors raised inside name the store, not the pinned path (pinned_directory renames them);
        # kept() reads the store by its name: the message may come after the pinned folder is let go.
        with guarded(store, lambda: kept(store)):
            st.open_group(store)  # a clear error, naming the user's path, for what is no committed store
            with pinned_directory(store) as pinned:
                folder = Path(pinned)
                with (held or lock_mod.acquire(folder, step, store)):
                    integrity.recover(folder)
                    integrity.require_present(folder, store)
                    try:
                        yield folder
                    except BaseException:
                        # The step's unpublished arrays: never part of the store (view.publish_many).
                        integrity.remove_staging(folder)
                        raise
    finally:
        if held is not None:
            held.release()  # also when the step failed before taking it over


def committed_epochs_text(store: Path, folder: Path, before: int, planned: int, resume: str) -> str:
    """What an interrupted add or create kept: the epochs of this run committed, those not added."""
    try:
        after = st.committed_epochs(folder)
    except M3C2Error:
        return f"{store} is at its last commit"
    added = after - before
    if added <= 0:
        return f"no epoch of this run committed; {store} holds {after} epoch(s) ({resume})"
    which = f"epoch {before}" if added == 1 else f"epochs {before}-{after - 1}"
    return (f"{which} committed in {store}, {planned - added} not added"
            f"{f' ({resume})' if planned - added else ''}")
