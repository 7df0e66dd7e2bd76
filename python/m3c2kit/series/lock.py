"""The writer's lock of a series store: one writing step at a time (create's epochs, add, smooth,
objects, import, ...). Two `series add` at once both reported their epochs committed while the
store kept only one run's batches; with the lock the second writer is refused at once, naming
the holder, and retries when it has finished (no waiting: a step may run for hours).

The lock is ``fcntl.lockf`` on the file LOCK_NAME inside the store: POSIX record locks work
across processes of different containers sharing the folder and on NFS (flock may not), and the
kernel releases them when the holder dies, even by SIGKILL, so a stale lock never needs
removing. The file holds the holder's host, pid, step, UTC start and command, for the message
of a refused writer. Zarr and xarray ignore it: it is no array or group (no zarr.json)."""
from __future__ import annotations

import datetime as dt
import errno
import fcntl
import os
import socket
import sys
from pathlib import Path

from .store import StoreError

LOCK_NAME = ".m3c2-lock"


class StoreLock:
    """The lock held on a store (acquire()); release() or leaving the `with` block lets it go."""

    def __init__(self, fd: int):
        self.fd = fd

    def release(self) -> None:
        if self.fd < 0:
            return
        try:
            os.ftruncate(self.fd, 0)  # no holder any more: a stale text would mislead a reader
        except OSError:
            pass  # a full disk cannot refuse truncation, a read-only one is no reason to fail here
        os.close(self.fd)  # closing releases the lockf lock
        self.fd = -1

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
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
    except OSError as e:
        raise StoreError(f"{shown}: cannot open its lock file {LOCK_NAME}: {e.strerror}") from None
    try:
        fcntl.lockf(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as e:
        holder = _read(fd)
        os.close(fd)
        if e.errno in (errno.EACCES, errno.EAGAIN):
            raise StoreError(f"{shown}: another m3c2 is writing this store ({holder or 'holder unknown'}); "
                             f"run {step} again when it has finished") from None
        raise StoreError(f"{shown}: cannot lock the store: {e.strerror}") from None
    try:
        text = holder_text(step).encode("utf-8", "replace")
        os.ftruncate(fd, 0)
        os.pwrite(fd, text, 0)
    except OSError:
        pass  # a full disk: the lock holds all the same, its holder text is only for messages
    return StoreLock(fd)


def _read(fd: int) -> str:
    try:
        return os.pread(fd, 4096, 0).decode("utf-8", "replace").strip()
    except OSError:
        return ""
