"""The one atomic writer of the package: every file any command writes (point tables, rasters, the
report and its PNGs, analysis tables) goes through :func:`staged_outputs` (several files, all or
nothing) or :func:`atomic_output` (one file); a folder written whole (a new series store) goes
through :func:`staged_directory`.

Each temporary lives inside a PRIVATE folder beside its target (io/private.py: ``.m3c2-tmp-<random>``,
mode 0700, made and then reached only through descriptors, locked by this run for its whole life).
Writers that insist on a path get ``/proc/self/fd/<folder's fd>/part<EXT>``: it resolves through the
held descriptor, so renaming the folder away, or replacing it by one holding links, redirects nothing
(issue 31); the short name (``part`` plus the target's extension, which writers dispatching on it
need) fits beside any legal output name, and no ``*.laz`` glob in the target's folder matches it.
When the body returns, each temporary is opened through the folder's descriptor without following a
link, checked to be a regular file, given its final mode with ``fchmod`` (the replaced file's, else
the umask's default) and fsynced, renamed onto its target from that descriptor to the target
folder's, and the target's folder fsynced. A failure removes every private folder (through its
descriptor) and leaves each target as it was. A private folder a killed run left behind is removed
by the next run writing there once its lock is free (:func:`remove_stale`): proof that no process,
in any container or on any NFS client, still writes in it. Where folders cannot be held as
descriptors (Windows; base/portable.py), the same steps go by name, each after checking that the
names still lead to the folders first opened (docs/architecture.md, "Portability").
"""
from __future__ import annotations

import errno
import os
import stat
import warnings
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import Iterator

from ..base import interrupt, portable
from ..base.errors import CloudWriteError, M3C2Error, UsageError
from ..base.fault_hook import checkpoint as fault_checkpoint
from .collisions import refuse_special
from .private import (PRIVATE_PREFIX, PrivateFolder, describe, pinned_directory, private_folder, public_name,
    remove_stale, renamed)

__all__ = ["atomic_output", "staged_outputs", "staged_directory", "pinned_directory", "private_folder",
           "remove_stale", "public_name", "refuse_occupied", "PRIVATE_PREFIX"]


def _suffix(target: Path) -> str:
    name = target.name.lower()
    return "".join(target.suffixes[-2:]) if name.endswith(".copc.laz") else target.suffix


def _umask_mode(bits: int) -> int:
    umask = os.umask(0)
    os.umask(umask)
    return bits & ~umask


def _final_mode(folder: PrivateFolder, target: Path) -> int:
    # The replaced file's permissions, else those a plain open() would give (the folder's are 0700).
    try:
        return folder.parent.stat_name(target.name).st_mode & 0o7777
    except OSError:
        return _umask_mode(0o666)


def _seal(folder: PrivateFolder, name: str, target: Path) -> None:
    """Final mode and fsync through one descriptor opened in the private folder without following
    a link; only a regular file is ever renamed onto a target. Where the folder is held by name
    (base/portable.py), read-write: Windows flushes only a descriptor open for writing."""
    held = folder.folder
    try:
        fd = held.open(name, os.O_RDONLY if held.held else os.O_RDWR)
    except FileNotFoundError:
        raise CloudWriteError(f"{target}: was not written") from None
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            raise CloudWriteError(f"{target}: was not written as a file")
        portable.chmod_open(fd, _final_mode(folder, target), os.path.join(held.pinned(), name))
        os.fsync(fd)
    finally:
        os.close(fd)


def _public(text: str, staged: dict[Path, Path], folders: dict[Path, PrivateFolder]) -> str:
    """`text` with every temporary (and private folder) named by its target (and the target's
    folder), by its pinned path and by its name: a writer handed a temporary names it in its errors
    and warnings, the user never saw it (issue 15: every message names the user's file)."""
    for target, tmp in staged.items():
        folder = folders[target]
        for shown in (tmp, folder.directory / folder.name / tmp.name):
            text = text.replace(str(shown), str(target))
    for folder in folders.values():
        text = text.replace(str(folder.directory / folder.name), str(folder.directory))
    return public_name(text)


@contextmanager
def staged_outputs(targets) -> Iterator[dict[Path, Path]]:
    """All-or-nothing output of several files: yields {target: temporary path}, each temporary in a
    private folder beside its target and ending with the target's extension; when the body
    returns, each is sealed and renamed onto its target. If the body raises, every private folder
    is removed, no target is touched, and the exception propagates (an OSError as CloudWriteError
    naming the target). Every target's folder is checked before the body runs."""
    staged: dict[Path, Path] = {}
    folders: dict[Path, PrivateFolder] = {}
    caught: list = []
    with ExitStack() as held:
        try:
            for target in dict.fromkeys(Path(t) for t in targets):
                if target.is_dir():
                    raise CloudWriteError(f"{target}: is a directory")
                refuse_special(target)  # the API's writers too: a FIFO or device is never replaced
                folder = held.enter_context(private_folder(target.parent, target))
                folders[target] = folder
                staged[target] = folder.path / f"part{_suffix(target)}"
            fault_checkpoint("staging")  # a testing aid (docs/errors.md, "Interruption"): folders made, nothing written
            try:
                with warnings.catch_warnings(record=True) as caught:
                    warnings.simplefilter("always")
                    yield staged
            except M3C2Error as e:
                public = renamed(e, lambda text: _public(text, staged, folders))
                if public is e:
                    raise
                raise public from e.__cause__
            finally:
                for w in caught:  # shown as the caller's filters say, naming the targets
                    warnings.warn_explicit(_public(str(w.message), staged, folders), w.category, w.filename,
                                           w.lineno)
            fault_checkpoint("writing")  # a testing aid (docs/errors.md, "Interruption"): temporaries complete
            interrupt.check()  # a stop Python swallowed while the outputs were made: none is published
            for target, tmp in staged.items():
                folders[target].check()
                _seal(folders[target], tmp.name, target)
            with interrupt.deferred():  # every target replaced, or none: a stop waits for the last
                for target, tmp in staged.items():
                    folder = folders[target]
                    folder.folder.replace(tmp.name, folder.parent, target.name)
                    folder.parent.fsync()  # the rename itself made durable, where a folder can be fsynced
                interrupt.note_published(staged)
        except OSError as e:
            target = next((t for t, tmp in staged.items() if e.filename in (str(tmp), tmp, tmp.name)), None)
            target = target or (next(iter(staged)) if len(staged) == 1 else None)
            where = target or (_public(str(e.filename), staged, folders) if e.filename else "output")
            raise CloudWriteError(f"{where}: {describe(e)}") from e


@contextmanager
def atomic_output(path: str | os.PathLike) -> Iterator[Path]:
    """One file through :func:`staged_outputs`: yields its temporary path."""
    target = Path(path)
    with staged_outputs([target]) as staged:
        yield staged[target]


def _occupied(target: Path) -> UsageError:
    return UsageError(f"{target} exists and is not empty; nothing in it is touched: choose another -o")


def refuse_occupied(target: Path) -> None:
    """Before any work: `target` must be absent or an empty folder (a link, even to one, is not)."""
    try:
        st = os.lstat(target)
    except FileNotFoundError:
        return
    except OSError as e:
        raise CloudWriteError(f"{target}: {describe(e)}") from None
    if not stat.S_ISDIR(st.st_mode):
        raise _occupied(target)
    try:
        with os.scandir(target) as entries:
            occupied = next(entries, None) is not None
    except OSError as e:
        raise CloudWriteError(f"{target}: {describe(e)}") from None
    if occupied:
        raise _occupied(target)


def _rename_onto(folder: PrivateFolder, target: Path) -> None:
    """rename(2) of the private folder onto `target`, which replaces an empty folder atomically.
    Where a rename cannot replace a folder (Windows: EEXIST), an empty one at `target` is removed
    first (not atomic: a folder another process makes there in between is refused as occupied);
    POSIX answers EEXIST only for a folder with entries, so there the second try never runs."""
    try:
        folder.parent.rename(folder.name, folder.parent, target.name)
        return
    except OSError as e:
        if e.errno != errno.EEXIST or not _empty_folder(folder, target):
            raise
    folder.parent.rmdir(target.name)
    folder.parent.rename(folder.name, folder.parent, target.name)


def _empty_folder(folder: PrivateFolder, target: Path) -> bool:
    try:
        if not stat.S_ISDIR(folder.parent.lstat(target.name).st_mode):
            return False
        with folder.parent.subfolder(target.name) as held:
            return not held.listdir()
    except OSError:
        return False


def _publish(folder: PrivateFolder, target: Path) -> None:
    """Renames the private folder onto `target` (absent or an empty folder: rename(2) replaces
    one atomically), its lock file removed, its mode that of a plain mkdir."""
    interrupt.check()  # a stop Python swallowed while the folder was filled: it is not published
    folder.folder.chmod(_umask_mode(0o777))
    folder.check()
    folder.unlock()
    # A folder is renamed by name (no call renames a descriptor): the name is checked to be ours
    # just before and the target just after, so a swap in between is caught, never published.
    folder.check_name()
    with interrupt.deferred():  # renamed and recorded as published, or not renamed at all
        try:
            _rename_onto(folder, target)
        except OSError as e:
            if e.errno in (errno.ENOTEMPTY, errno.EEXIST, errno.ENOTDIR, errno.EISDIR):
                raise _occupied(target) from None
            raise CloudWriteError(f"{target}: cannot create: {describe(e)}") from None
        folder.published(target.name)
        folder.parent.fsync()
        interrupt.note_published([target])


@contextmanager
def staged_directory(target) -> Iterator[Path]:
    """A folder that appears at `target` whole or not at all: refused at once (UsageError) when
    `target` exists and is not an empty folder; else yields the pinned path of a private folder
    beside it, renamed onto `target` when the body returns (mode 0777 less the umask). If the body
    raises (also KeyboardInterrupt, SystemExit), the private folder is removed, `target` is left as
    it was, and the exception propagates."""
    target = Path(target)
    refuse_occupied(target)
    with private_folder(target.parent, target) as folder:
        fault_checkpoint("staging")  # a testing aid (docs/errors.md, "Interruption"): folder made, nothing written
        try:
            yield folder.path
        except M3C2Error as e:
            public = renamed(e, lambda text: _public(text, {}, {target: folder}))
            if public is e:
                raise
            raise public from e.__cause__
        _publish(folder, target)
