"""The writer's lock of a series store: one writing step at a time (create's epochs, add, smooth,
objects, import, ...). Two `series add` at once both reported their epochs committed while the
store kept only one run's batches; with the lock the second writer is refused at once, naming
the holder, and retries when it has finished (no waiting: a step may run for hours).

The lock is held twice, and a writer needs both:
- ``fcntl.flock`` on the store folder itself (its descriptor, kept open): no name inside the
  store can defeat it. With only the file's lock, removing ``.m3c2-lock`` while a writer ran let
  a second writer create a new file, lock it and write beside the first (issue 42).
- ``fcntl.lockf`` on the file LOCK_NAME inside the store: POSIX record locks work across
  processes of different containers sharing the folder and on NFS, where flock on a folder may
  be refused (ENOLCK, EBADF, EINVAL, EOPNOTSUPP): there the file's lock alone holds, as before
  (the documented fallback).
The kernel releases both when the holder dies, even by SIGKILL, so a stale lock never needs
removing. The file holds the holder's host, pid, step, UTC start and command, for the message
of a refused writer. Zarr and xarray ignore it: it is no array or group (no zarr.json).

Elsewhere (base/portable.py; docs/architecture.md, "Portability"): Windows has no flock, and
msvcrt's byte lock on LOCK_NAME stands in for lockf (also dropped when the holder dies; Windows
itself refuses to remove a file another process holds open, which the folder's lock guards
against here). Where files cannot be locked at all (M3C2_PORTABLE_FALLBACKS=1), the lock is the
file EXCLUSIVE_NAME, created exclusively (O_EXCL) and removed at release: a second writer is
refused all the same, but a killed writer's file stays, and the next writer is refused until
the user removes it (the message says so)."""
from __future__ import annotations

import datetime as dt
import errno
import os
import socket
import stat
import sys
import threading
from pathlib import Path

from ..base import portable
from .store import StoreError

LOCK_NAME = ".m3c2-lock"
#: The lock file where files cannot be locked (base/portable.kernel_locks()): its existence is the lock.
EXCLUSIVE_NAME = ".m3c2-lock-exclusive"
#: (st_dev, st_ino) of the lock files this process holds -> their holder text. POSIX locks are the
#: process's: a second acquire in this process (two API calls, two threads) would be granted, and
#: its release, closing a descriptor of the file, would drop the first writer's lock too.
_HELD: dict[tuple[int, int], str] = {}
_HELD_GUARD = threading.Lock()


class StoreLock:
    """The lock held on a store (acquire()); release() or leaving the `with` block lets it go."""

    def __init__(self, fd: int, key: tuple[int, int], folder: "portable.Folder | None" = None,
                 exclusive: Path | None = None):
        self.fd, self.key, self.folder, self.exclusive = fd, key, folder, exclusive

    def release(self) -> None:
        if self.fd < 0:
            return
        with _HELD_GUARD:
            _HELD.pop(self.key, None)
        if self.exclusive is not None:
            os.close(self.fd)  # first: an open file cannot be removed on Windows
            self.fd = -1
            _remove_if_ours(self.exclusive, self.key)
            return
        try:
            os.ftruncate(self.fd, 0)  # no holder any more: a stale text would mislead a reader
        except OSError:
            pass  # a full disk cannot refuse truncation, a read-only one is no reason to fail here
        os.close(self.fd)  # closing releases the lockf lock
        self.fd = -1
        if self.folder is not None:
            self.folder.close()  # and this the folder's flock
            self.folder = None

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> bool:
        self.release()
        return False


def holder_text(step: str) -> str:
    start = dt.datetime.now(dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%S")
    command = " ".join(["m3c2", *sys.argv[1:]]) if sys.argv and sys.argv[0] else "m3c2 (Python API)"
    return f"host {socket.gethostname()}, pid {os.getpid()}, step {step}, since {start} UTC, command: {command}"


def lock_name() -> str:
    """The name of the store's lock file here: LOCK_NAME where files can be locked, else EXCLUSIVE_NAME."""
    return LOCK_NAME if portable.kernel_locks() else EXCLUSIVE_NAME


def moves_with_folder() -> bool:
    """Whether a lock taken inside a private folder stays held when the folder is renamed onto
    its target (series create): POSIX locks do; Windows cannot rename a folder holding an open
    file, so there (and in the forced fallbacks, which stand for it) the lock is taken after."""
    return portable.CAPS.record_locks


def acquire(folder: Path, step: str, shown: Path | None = None) -> StoreLock:
    """Locks the store at `folder` for `step`, or a StoreError naming the holder. `shown`: the
    store's path in messages (`folder` may be a pinned /proc/self/fd path)."""
    shown = folder if shown is None else shown
    path = Path(folder) / lock_name()
    with _HELD_GUARD:
        return _acquire(path, step, shown)


def _refused(shown, step: str, holder: str) -> StoreError:
    return StoreError(f"{shown}: another m3c2 is writing this store ({holder or 'holder unknown'}); "
                      f"run {step} again when it has finished")


def _lock_folder(folder: Path, step: str, shown) -> "portable.Folder | None":
    """The store folder, held and flock-ed; None where a folder cannot be locked (no flock, or a
    file system that refuses it); a StoreError naming the holder when another writer holds it."""
    if not portable.CAPS.folder_locks:
        return None
    try:
        held = portable.Folder(folder)
    except OSError as e:
        raise StoreError(f"{shown}: cannot open the store folder to lock it: {e.strerror}") from None
    try:
        taken = portable.lock_folder(held)
    except OSError as e:
        held.close()
        raise StoreError(f"{shown}: cannot lock the store: {e.strerror}") from None
    if not taken:
        held.close()
        if taken is None:
            return None
        raise _refused(shown, step, _holder(folder)) from None
    return held


def _holder(folder: Path) -> str:
    """The holder text of the store's lock file, '' when it cannot be read (removed, not a file)."""
    try:
        fd = portable.open_nofollow(Path(folder) / lock_name(), os.O_RDONLY | portable.O_NONBLOCK)
    except OSError:
        return ""
    try:
        return _read(fd) if stat.S_ISREG(os.fstat(fd).st_mode) else ""
    finally:
        os.close(fd)


def _planted(shown, step: str, name: str) -> str:
    return (f"{shown}: its lock file {name} is {{}}, which m3c2 never makes: nothing was written "
            f"through it; move it away (it holds no data of the store) and run {step} again")


def _acquire(path: Path, step: str, shown) -> StoreLock:
    try:
        existing = os.stat(path, follow_symlinks=False)
    except OSError:
        existing = None
    if existing is not None and (existing.st_dev, existing.st_ino) in _HELD:  # never opened: see _HELD
        raise StoreError(f"{shown}: another writing step of this process is writing this store "
                         f"({_HELD[existing.st_dev, existing.st_ino]}); run {step} again when it has finished")
    if not portable.kernel_locks():
        return _acquire_exclusive(path, step, shown, existing)
    folder = _lock_folder(path.parent, step, shown)
    try:
        return _acquire_file(path, step, shown, folder)
    except BaseException:
        if folder is not None:
            folder.close()
        raise


def _acquire_file(path: Path, step: str, shown, folder: "portable.Folder | None") -> StoreLock:
    planted = _planted(shown, step, LOCK_NAME)
    try:
        # O_NOFOLLOW, O_NONBLOCK and the fstat below: the holder text truncates and rewrites the
        # file, so a link planted at its name (`.m3c2-lock -> /root/victim`) emptied its target.
        fd = portable.open_nofollow(path, os.O_RDWR | os.O_CREAT | portable.O_NONBLOCK, 0o644)
    except OSError as e:
        if e.errno == portable.ELOOP:
            raise StoreError(planted.format("a symbolic link")) from None
        raise StoreError(f"{shown}: cannot open its lock file {LOCK_NAME}: {e.strerror}") from None
    info = os.fstat(fd)
    if not stat.S_ISREG(info.st_mode) or info.st_nlink != 1:
        os.close(fd)
        raise StoreError(planted.format("not a regular file" if not stat.S_ISREG(info.st_mode)
                                        else f"a hard link to another file ({info.st_nlink} names)"))
    try:
        taken = portable.try_lock(fd)
    except OSError as e:
        os.close(fd)
        raise StoreError(f"{shown}: cannot lock the store: {e.strerror}") from None
    if not taken:
        holder = _read(fd)
        os.close(fd)
        raise _refused(shown, step, holder)
    text = holder_text(step)
    try:
        os.ftruncate(fd, 0)
        portable.write_at(fd, text.encode("utf-8", "replace"), 0)
    except OSError:
        pass  # a full disk: the lock holds all the same, its holder text is only for messages
    _HELD[info.st_dev, info.st_ino] = text
    return StoreLock(fd, (info.st_dev, info.st_ino), folder)


def _acquire_exclusive(path: Path, step: str, shown, existing) -> StoreLock:
    """The lock where files cannot be locked: EXCLUSIVE_NAME created exclusively (O_EXCL: never
    through a link, never over another writer's file), the holder text in it."""
    planted = _planted(shown, step, EXCLUSIVE_NAME)
    try:
        fd = portable.open_nofollow(path, os.O_RDWR | os.O_CREAT | os.O_EXCL, 0o644)
    except FileExistsError:
        try:
            kind = os.lstat(path)
        except OSError:
            kind = None
        if kind is not None and stat.S_ISLNK(kind.st_mode):
            raise StoreError(planted.format("a symbolic link")) from None
        if kind is not None and not stat.S_ISREG(kind.st_mode):
            raise StoreError(planted.format("not a regular file")) from None
        if kind is not None and kind.st_nlink != 1:
            raise StoreError(planted.format(f"a hard link to another file ({kind.st_nlink} names)")) from None
        raise StoreError(f"{shown}: another m3c2 is writing this store ({_holder(path.parent) or 'holder unknown'}); "
                         f"run {step} again when it has finished; if none is (a writer was killed: this system "
                         f"cannot lock files), remove {path} first") from None
    except OSError as e:
        if e.errno == portable.ELOOP:
            raise StoreError(planted.format("a symbolic link")) from None
        raise StoreError(f"{shown}: cannot create its lock file {EXCLUSIVE_NAME}: {e.strerror}") from None
    info = os.fstat(fd)
    text = holder_text(step)
    try:
        portable.write_at(fd, text.encode("utf-8", "replace"), 0)
    except OSError:
        pass  # a full disk: the file holds the lock all the same, its text is only for messages
    _HELD[info.st_dev, info.st_ino] = text
    return StoreLock(fd, (info.st_dev, info.st_ino), exclusive=path)


def _remove_if_ours(path: Path, key: tuple[int, int]) -> None:
    """Removes the exclusive lock file `path` while it still is the file this writer made."""
    try:
        st = os.lstat(path)
        if (st.st_dev, st.st_ino) == key:
            os.unlink(path)
    except OSError:
        pass


def _read(fd: int) -> str:
    try:
        return portable.read_at(fd, 4096, 0).decode("utf-8", "replace").strip()
    except OSError:
        return ""
