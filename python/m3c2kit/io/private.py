"""Private folders no one else can hijack, and the proof that one is abandoned (issue 31).

A private folder (``.m3c2-tmp-<random>``, mode 0700) is made beside an output through a descriptor of
the user's folder (``mkdir`` with ``dir_fd``), opened once without following a link and checked by
``fstat`` (a directory, ours, 0700). Everything in it is then reached through that descriptor: the
path handed to writers that insist on a path is ``/proc/self/fd/<fd>/...``, which the kernel resolves
through the held descriptor, so someone who can write in the user's folder and renames ours away
(or puts a folder of their own with links in it under its name) redirects nothing.

Where ``/proc/self/fd`` does not exist (not Linux), writers get the folder's name, and the folder's
identity is checked when its files are sealed: a folder whose name no longer leads to our inode
stops the run with a clear error before anything is renamed onto an output.

A killed run's folder is removed by the next run writing in that folder, on proof only: every
private folder holds LOCK_NAME, locked (``fcntl.lockf``, a POSIX record lock: honoured across PID
namespaces and over NFS, dropped by the kernel when its holder dies, even by SIGKILL) by its live
writer for the folder's whole life. A folder whose lock this process can take is abandoned; one
whose lock is held, or that has no lock file (an older version's, or one being made), is left
alone. Nothing is followed: every open is ``O_NOFOLLOW``. POSIX locks drop when ANY descriptor of
the file closes in the holding process, so this process never opens the lock file of a folder it
owns (OWN, by inode).
"""
from __future__ import annotations

import fcntl
import os
import re
import secrets
import stat
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

from ..base.errors import CloudWriteError, M3C2Error

__all__ = ["PRIVATE_PREFIX", "LOCK_NAME", "PINNABLE", "PrivateFolder", "private_folder", "pinned_directory",
           "remove_stale", "remove_tree", "public_name", "renamed", "describe"]

PRIVATE_PREFIX = ".m3c2-tmp-"
LOCK_NAME = ".m3c2-tmp-lock"
#: Whether a path can resolve through a held descriptor (Linux's /proc/self/fd).
PINNABLE = os.path.isdir("/proc/self/fd")

_DIR_FLAGS = os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC
_OWN: set[tuple[int, int]] = set()  # (st_dev, st_ino) of the private folders this process holds
_SHOWN: dict[str, str] = {}  # pinned path -> the user's name of it, while pinned


def _identity(st: os.stat_result) -> tuple[int, int]:
    return st.st_dev, st.st_ino


def _pinned_path(fd: int) -> str:
    return f"/proc/self/fd/{fd}"


def public_name(text: str) -> str:
    """`text` with every pinned path (/proc/self/fd/N, held now) written as the user's name of it:
    a writer given a pinned path names it in its errors, the user never saw it."""
    if not _SHOWN or "/proc/self/fd/" not in text:
        return text
    pattern = "|".join(re.escape(p) for p in sorted(_SHOWN, key=len, reverse=True))
    return re.sub(f"(?:{pattern})(?!\\d)", lambda m: _SHOWN[m.group(0)], text)


def renamed(error: M3C2Error, public=public_name) -> M3C2Error:
    """`error` with its text passed through `public` (public_name: pinned paths as the user's names);
    itself when nothing changes or its class cannot be rebuilt from a text."""
    text = public(str(error))
    if text == str(error):
        return error
    try:
        return type(error)(text)
    except TypeError:  # a subclass with another constructor: kept as it is
        return error


def describe(err: OSError) -> str:
    return err.strerror or str(err)


def remove_tree(fd: int) -> None:
    """Empties the folder open at `fd`, descending through descriptors and never following a link."""
    for name in os.listdir(fd):
        try:
            st = os.stat(name, dir_fd=fd, follow_symlinks=False)
            if stat.S_ISDIR(st.st_mode):
                sub = os.open(name, _DIR_FLAGS | os.O_NOFOLLOW, dir_fd=fd)
                try:
                    remove_tree(sub)
                finally:
                    os.close(sub)
                os.rmdir(name, dir_fd=fd)
            else:
                os.unlink(name, dir_fd=fd)
        except OSError:
            pass  # gone already, or not ours to remove: the folder's rmdir then fails and it stays


def _rmdir_if_same(parent_fd: int, name: str, identity: tuple[int, int]) -> None:
    """Removes the (emptied) folder `name` only while that name still is the inode we emptied."""
    try:
        if _identity(os.stat(name, dir_fd=parent_fd, follow_symlinks=False)) == identity:
            os.rmdir(name, dir_fd=parent_fd)
    except OSError:
        pass


def _sweep(parent_fd: int) -> None:
    """Removes the private folders in the folder open at `parent_fd` that are proven abandoned."""
    try:
        names = [n for n in os.listdir(parent_fd) if n.startswith(PRIVATE_PREFIX)]
    except OSError:
        return
    for name in names:
        try:
            fd = os.open(name, _DIR_FLAGS | os.O_NOFOLLOW, dir_fd=parent_fd)
        except OSError:
            continue  # a link (ELOOP), not a folder, gone, or not ours to enter
        try:
            identity = _identity(os.fstat(fd))
            if identity in _OWN:
                continue  # ours: opening its lock file would drop our own lock
            try:
                lock = os.open(LOCK_NAME, os.O_RDWR | os.O_NOFOLLOW | os.O_CLOEXEC, dir_fd=fd)
            except OSError:
                continue  # no lock file: an older version's folder, or one being made
            try:
                if not stat.S_ISREG(os.fstat(lock).st_mode):
                    continue
                try:
                    fcntl.lockf(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
                except OSError:
                    continue  # held: its writer is alive (on this host, in a container, over NFS)
                remove_tree(fd)
                _rmdir_if_same(parent_fd, name, identity)
            finally:
                os.close(lock)
        finally:
            os.close(fd)


def remove_stale(directory: Path) -> None:
    """Removes the private folders in `directory` that are proven abandoned (their lock is free)."""
    try:
        parent = os.open(directory, _DIR_FLAGS)
    except OSError:
        return
    try:
        _sweep(parent)
    finally:
        os.close(parent)


class PrivateFolder:
    """A private folder, held: `parent_fd` (the user's folder), `fd` (ours), `lock_fd` (its lock).

    `path`: where writers write (pinned through `fd` where possible); `directory`: the user's
    folder, as the user named it (for messages)."""

    def __init__(self, directory: Path, label: Path):
        self.directory, self.label = Path(directory), label
        self.parent_fd = self._open_parent()
        self.fd = self.lock_fd = -1
        self.kept = False  # renamed onto its target (staged_directory): never removed then
        try:
            _sweep(self.parent_fd)
            self.name = self._make()
            replaced = CloudWriteError(f"{label}: cannot write in {str(self.directory)!r}: its private work folder "
                                       f"was replaced by someone else before it was used")
            try:
                self.fd = os.open(self.name, _DIR_FLAGS | os.O_NOFOLLOW, dir_fd=self.parent_fd)
            except OSError:  # a link, a file or nothing under its name: not ours
                raise replaced from None
            st = os.fstat(self.fd)
            # Renamed away and replaced between mkdir and open: that folder is not ours to use.
            if not stat.S_ISDIR(st.st_mode) or st.st_uid != os.geteuid():
                raise replaced
            if stat.S_IMODE(st.st_mode) != 0o700:  # a umask that removes owner bits
                os.fchmod(self.fd, 0o700)
            self.identity = _identity(st)
            _OWN.add(self.identity)
            try:
                self.lock_fd = self._lock()
            except OSError as e:
                raise CloudWriteError(f"{label}: cannot write in {str(self.directory)!r}: {describe(e)}") from None
        except BaseException:
            self.close(remove=True)
            raise
        self.path = Path(_pinned_path(self.fd)) if PINNABLE else self.directory / self.name
        if PINNABLE:
            _SHOWN[str(self.path)] = str(self.directory)

    def _open_parent(self) -> int:
        try:
            return os.open(self.directory, _DIR_FLAGS)  # a link the user chose is followed
        except FileNotFoundError:
            raise CloudWriteError(f"{self.label}: cannot write: directory {str(self.directory)!r} "
                                  f"does not exist") from None
        except NotADirectoryError:
            raise CloudWriteError(f"{self.label}: cannot write: {str(self.directory)!r} is not a directory") from None
        except OSError as e:
            raise CloudWriteError(f"{self.label}: cannot write in {str(self.directory)!r}: {describe(e)}") from None

    def _make(self) -> str:
        for _ in range(100):
            name = PRIVATE_PREFIX + secrets.token_hex(8)
            try:
                os.mkdir(name, 0o700, dir_fd=self.parent_fd)
                return name
            except FileExistsError:
                continue
            except OSError as e:
                raise CloudWriteError(f"{self.label}: cannot write in {str(self.directory)!r}: "
                                      f"{describe(e)}") from None
        raise CloudWriteError(f"{self.label}: cannot write in {str(self.directory)!r}: no free name for a "
                              f"private work folder")

    def _lock(self) -> int:
        # Locked under a name of its own, then renamed to LOCK_NAME: a sweeping process never
        # finds LOCK_NAME unlocked while this one lives.
        name = f"{LOCK_NAME}.{secrets.token_hex(4)}"
        fd = os.open(name, os.O_RDWR | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC, 0o600, dir_fd=self.fd)
        try:
            fcntl.lockf(fd, fcntl.LOCK_EX)
            os.replace(name, LOCK_NAME, src_dir_fd=self.fd, dst_dir_fd=self.fd)
        except BaseException:
            os.close(fd)
            raise
        return fd

    def _named_ours(self, name: str) -> bool:
        try:
            return _identity(os.stat(name, dir_fd=self.parent_fd, follow_symlinks=False)) == self.identity
        except OSError:
            return False

    def check(self) -> None:
        """Without pinned paths: refuses when the folder's name no longer leads to our folder (with
        them, writes went through the descriptor and the name does not matter)."""
        if not PINNABLE:
            self.check_name()

    def check_name(self) -> None:
        """Refuses when the folder's name no longer leads to our folder."""
        if not self._named_ours(self.name):
            raise CloudWriteError(f"{self.label}: not written: its private work folder in {str(self.directory)!r} "
                                  f"was replaced by someone else during the run")

    def published(self, name: str) -> None:
        """After the folder was renamed to `name`: keeps it, or refuses when `name` is not our folder
        (swapped in between: what is there is someone else's, and ours is removed at close)."""
        if not self._named_ours(name):
            raise CloudWriteError(f"{self.label}: not created: its private folder in {str(self.directory)!r} was "
                                  f"swapped by someone else as it was renamed; what is at {self.label} is not this "
                                  f"run's output")
        self.name, self.kept = name, True

    def unlock(self) -> None:
        """Removes the lock file, then lets the lock go (the folder is about to become an output)."""
        if self.lock_fd >= 0:
            os.unlink(LOCK_NAME, dir_fd=self.fd)
            os.close(self.lock_fd)
            self.lock_fd = -1

    def close(self, remove: bool) -> None:
        """Closes every descriptor; with `remove`, first removes the folder through them."""
        if self.fd >= 0:
            if remove and not self.kept and hasattr(self, "identity"):  # only a folder proven ours
                try:
                    remove_tree(self.fd)
                except OSError:
                    pass
                _rmdir_if_same(self.parent_fd, self.name, self.identity)
            _SHOWN.pop(_pinned_path(self.fd), None)
            os.close(self.fd)
            self.fd = -1
        if self.lock_fd >= 0:
            os.close(self.lock_fd)  # after the folder's removal: the lock proves it alive until then
            self.lock_fd = -1
        if hasattr(self, "identity"):
            _OWN.discard(self.identity)
        if self.parent_fd >= 0:
            os.close(self.parent_fd)
            self.parent_fd = -1


@contextmanager
def private_folder(directory: Path, target: Path | None = None) -> Iterator[PrivateFolder]:
    """A new private folder in `directory` (beside `target`, named in errors), removed at exit."""
    folder = PrivateFolder(Path(directory), target if target is not None else Path(directory))
    try:
        yield folder
    finally:
        folder.close(remove=True)


@contextmanager
def pinned_directory(path) -> Iterator[Path]:
    """Yields a path of the existing directory `path` that resolves through a descriptor opened
    once, so that a later rename or swap of the name cannot redirect a write made through it.
    Without /proc/self/fd: `path` itself, and a CloudWriteError at exit when its name no longer
    leads to the directory opened. An error raised inside names `path`, never the pinned path."""
    shown = os.fspath(path)
    try:
        fd = os.open(shown, _DIR_FLAGS)
    except FileNotFoundError:
        raise CloudWriteError(f"{shown}: no such directory") from None
    except NotADirectoryError:
        raise CloudWriteError(f"{shown}: is not a directory") from None
    except OSError as e:
        raise CloudWriteError(f"{shown}: cannot open: {describe(e)}") from None
    pinned = _pinned_path(fd)
    try:
        if not PINNABLE:
            identity = _identity(os.fstat(fd))
            yield Path(shown)
            try:
                same = _identity(os.stat(shown)) == identity
            except OSError:
                same = False
            if not same:
                raise CloudWriteError(f"{shown}: was replaced by someone else while it was written")
            return
        _SHOWN[pinned] = shown
        try:
            yield Path(pinned)
        except M3C2Error as e:
            public = renamed(e)
            if public is e:
                raise
            raise public from e.__cause__
    finally:
        _SHOWN.pop(pinned, None)
        os.close(fd)
