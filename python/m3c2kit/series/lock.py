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
of a refused writer. Zarr and xarray ignore it: it is no array or group (no zarr.json)."""
from __future__ import annotations

import datetime as dt
import errno
import fcntl
import os
import socket
import stat
import sys
import threading
from pathlib import Path

from .store import StoreError

LOCK_NAME = ".m3c2-lock"
#: (st_dev, st_ino) of the lock files this process holds -> their holder text. POSIX locks are the
#: process's: a second acquire in this process (two API calls, two threads) would be granted, and
#: its release, closing a descriptor of the file, would drop the first writer's lock too.
_HELD: dict[tuple[int, int], str] = {}
_HELD_GUARD = threading.Lock()


class StoreLock:
    """The lock held on a store (acquire()); release() or leaving the `with` block lets it go."""

    def __init__(self, fd: int, key: tuple[int, int], folder_fd: int = -1):
        self.fd, self.key, self.folder_fd = fd, key, folder_fd

    def release(self) -> None:
        if self.fd < 0:
            return
        with _HELD_GUARD:
            _HELD.pop(self.key, None)
        try:
            os.ftruncate(self.fd, 0)  # no holder any more: a stale text would mislead a reader
        except OSError:
            pass  # a full disk cannot refuse truncation, a read-only one is no reason to fail here
        os.close(self.fd)  # closing releases the lockf lock
        self.fd = -1
        if self.folder_fd >= 0:
            os.close(self.folder_fd)  # and this the folder's flock
            self.folder_fd = -1

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> bool:
        self.release()
        return False


def holder_text(step: str) -> str:
    start = dt.datetime.now(dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%S")
    command = " ".join(["m3c2", *sys.argv[1:]]) if sys.argv and sys.argv[0] else "m3c2 (Python API)"
    return f"host {socket.gethostname()}, pid {os.getpid()}, step {step}, since {start} UTC, command: {command}"


def acquire(folder: Path, step: str, shown: Path | None = None) -> StoreLock:
    """Locks the store at `folder` for `step`, or a StoreError naming the holder. `shown`: the
    store's path in messages (`folder` may be a pinned /proc/self/fd path)."""
    shown = folder if shown is None else shown
    path = Path(folder) / LOCK_NAME
    with _HELD_GUARD:
        return _acquire(path, step, shown)


#: flock's answers where the file system cannot lock a folder (NFS, some FUSE): the file's lockf holds alone.
_NO_FOLDER_LOCK = {errno.ENOLCK, errno.EBADF, errno.EINVAL, errno.EOPNOTSUPP, errno.ENOSYS}


def _lock_folder(folder: Path, step: str, shown) -> int:
    """The store folder's descriptor, flock-ed; -1 where the file system cannot lock a folder; a
    StoreError naming the holder when another writer holds it."""
    try:
        fd = os.open(folder, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
    except OSError as e:
        raise StoreError(f"{shown}: cannot open the store folder to lock it: {e.strerror}") from None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as e:
        os.close(fd)
        if e.errno in _NO_FOLDER_LOCK:
            return -1
        if e.errno in (errno.EWOULDBLOCK, errno.EACCES):
            raise StoreError(f"{shown}: another m3c2 is writing this store ({_holder(folder) or 'holder unknown'}); "
                             f"run {step} again when it has finished") from None
        raise StoreError(f"{shown}: cannot lock the store: {e.strerror}") from None
    return fd


def _holder(folder: Path) -> str:
    """The holder text of the store's lock file, '' when it cannot be read (removed, not a file)."""
    try:
        fd = os.open(Path(folder) / LOCK_NAME, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC)
    except OSError:
        return ""
    try:
        return _read(fd) if stat.S_ISREG(os.fstat(fd).st_mode) else ""
    finally:
        os.close(fd)


def _acquire(path: Path, step: str, shown) -> StoreLock:
    try:
        existing = os.stat(path, follow_symlinks=False)
    except OSError:
        existing = None
    if existing is not None and (existing.st_dev, existing.st_ino) in _HELD:  # never opened: see _HELD
        raise StoreError(f"{shown}: another writing step of this process is writing this store "
                         f"({_HELD[existing.st_dev, existing.st_ino]}); run {step} again when it has finished")
    folder_fd = _lock_folder(path.parent, step, shown)
    try:
        return _acquire_file(path, step, shown, folder_fd)
    except BaseException:
        if folder_fd >= 0:
            os.close(folder_fd)
        raise


def _acquire_file(path: Path, step: str, shown, folder_fd: int) -> StoreLock:
    planted = (f"{shown}: its lock file {LOCK_NAME} is {{}}, which m3c2 never makes: nothing was written "
               f"through it; move it away (it holds no data of the store) and run {step} again")
    try:
        # O_NOFOLLOW, O_NONBLOCK and the fstat below: the holder text truncates and rewrites the
        # file, so a link planted at its name (`.m3c2-lock -> /root/victim`) emptied its target.
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC, 0o644)
    except OSError as e:
        if e.errno == errno.ELOOP:
            raise StoreError(planted.format("a symbolic link")) from None
        raise StoreError(f"{shown}: cannot open its lock file {LOCK_NAME}: {e.strerror}") from None
    info = os.fstat(fd)
    if not stat.S_ISREG(info.st_mode) or info.st_nlink != 1:
        os.close(fd)
        raise StoreError(planted.format("not a regular file" if not stat.S_ISREG(info.st_mode)
                                        else f"a hard link to another file ({info.st_nlink} names)"))
    try:
        fcntl.lockf(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as e:
        holder = _read(fd)
        os.close(fd)
        if e.errno in (errno.EACCES, errno.EAGAIN):
            raise StoreError(f"{shown}: another m3c2 is writing this store ({holder or 'holder unknown'}); "
                             f"run {step} again when it has finished") from None
        raise StoreError(f"{shown}: cannot lock the store: {e.strerror}") from None
    text = holder_text(step)
    try:
        os.ftruncate(fd, 0)
        os.pwrite(fd, text.encode("utf-8", "replace"), 0)
    except OSError:
        pass  # a full disk: the lock holds all the same, its holder text is only for messages
    _HELD[info.st_dev, info.st_ino] = text
    return StoreLock(fd, (info.st_dev, info.st_ino), folder_fd)


def _read(fd: int) -> str:
    try:
        return os.pread(fd, 4096, 0).decode("utf-8", "replace").strip()
    except OSError:
        return ""
