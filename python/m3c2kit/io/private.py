"""Private folders no one else can hijack, and the proof that one is abandoned (issue 31).

A private folder (``.m3c2-tmp-<random>``, mode 0700) is made beside an output through a descriptor of
the user's folder (``mkdir`` with ``dir_fd``), opened once without following a link and checked by
``fstat`` (a directory, ours, 0700). Everything in it is then reached through that descriptor: the
path handed to writers that insist on a path is ``/proc/self/fd/<fd>/...``, which the kernel resolves
through the held descriptor, so someone who can write in the user's folder and renames ours away
(or puts a folder of their own with links in it under its name) redirects nothing.

Where ``/proc/self/fd`` does not exist (macOS), writers get the folder's name, and the folder's
identity is checked when its files are sealed: a folder whose name no longer leads to our inode
stops the run with a clear error before anything is renamed onto an output. Where folders cannot be
held as descriptors at all (Windows; base/portable.py), every call goes by name after that same
identity check (docs/architecture.md, "Portability").

A killed run's folder is removed by the next run writing in that folder, on proof only: every
private folder holds LOCK_NAME, locked (``fcntl.lockf``, a POSIX record lock: honoured across PID
namespaces and over NFS, dropped by the kernel when its holder dies, even by SIGKILL; Windows:
msvcrt's byte lock) by its live writer for the folder's whole life. A folder whose lock this
process can take is abandoned; one whose lock is held, or that has no lock file (an older
version's, or one being made), is left alone; where files cannot be locked at all, no folder is
ever proven abandoned, and none is removed. Nothing is followed: every open is ``O_NOFOLLOW`` (or
its checked stand-in). POSIX locks drop when ANY descriptor of the file closes in the holding
process, so this process never opens the lock file of a folder it owns (OWN, by inode).
"""
from __future__ import annotations

import os
import re
import secrets
import stat
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

from ..base import portable
from ..base.errors import CloudWriteError, M3C2Error
from ..base.portable import Folder

__all__ = ["PRIVATE_PREFIX", "LOCK_NAME", "pinnable", "PrivateFolder", "private_folder", "pinned_directory",
           "remove_stale", "remove_tree", "public_name", "renamed", "describe"]

PRIVATE_PREFIX = ".m3c2-tmp-"
LOCK_NAME = ".m3c2-tmp-lock"
#: What a live writer's lock file holds where locks are msvcrt's: emptied before the lock is let go,
#: so a sweep never takes a folder about to be published for an abandoned one (Windows cannot
#: remove an open file, so the file is removed after its lock is let go, not before).
_LIVE = b"live"

_OWN: set[tuple[int, int]] = set()  # (st_dev, st_ino) of the private folders this process holds
_SHOWN: dict[str, str] = {}  # pinned path -> the user's name of it, while pinned


def pinnable() -> bool:
    """Whether a path can resolve through a held descriptor (Linux's /proc/self/fd)."""
    return portable.CAPS.fd_paths and portable.CAPS.folder_fds


def public_name(text: str) -> str:
    """`text` with every pinned path (/proc/self/fd/N, held now) written as the user's name of it:
    a writer given a pinned path names it in its errors, the user never saw it."""
    if not _SHOWN or portable.FD_PATH_PREFIX not in text:
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


def remove_tree(folder: Folder) -> None:
    """Empties the held `folder`, descending through held folders and never following a link."""
    for name in folder.listdir():
        try:
            st = folder.lstat(name)
            if stat.S_ISDIR(st.st_mode):
                with folder.subfolder(name) as sub:
                    remove_tree(sub)
                folder.rmdir(name)
            else:
                folder.unlink(name)
        except OSError:
            pass  # gone already, or not ours to remove: the folder's rmdir then fails and it stays


def _rmdir_if_same(parent: Folder, name: str, identity: tuple[int, int]) -> None:
    """Removes the (emptied) folder `name` only while that name still is the inode we emptied."""
    try:
        if portable.identity(parent.lstat(name)) == identity:
            parent.rmdir(name)
    except OSError:
        pass


def _abandoned(lock: int) -> bool:
    """Whether the lock file open at `lock` proves its folder abandoned: its lock can be taken
    (and, with msvcrt's locks, it still says its writer was live: an emptied one was let go by a
    writer about to publish its folder)."""
    if not stat.S_ISREG(os.fstat(lock).st_mode):
        return False
    if not portable.CAPS.record_locks and portable.read_at(lock, len(_LIVE), 0) != _LIVE:
        return False
    try:
        return portable.try_lock(lock)
    except OSError:
        return False


def _sweep(parent: Folder) -> None:
    """Removes the private folders in the held `parent` that are proven abandoned. Where files
    cannot be locked, nothing proves it: nothing is removed."""
    if not portable.kernel_locks():
        return
    try:
        names = [n for n in parent.listdir() if n.startswith(PRIVATE_PREFIX)]
    except OSError:
        return
    for name in names:
        try:
            sub = parent.subfolder(name)
        except OSError:
            continue  # a link (ELOOP), not a folder, gone, or not ours to enter
        try:
            if sub.identity not in _OWN:  # ours: opening its lock file would drop our own lock
                _remove_if_abandoned(parent, name, sub)
        finally:
            sub.close()


def _remove_if_abandoned(parent: Folder, name: str, sub: Folder) -> None:
    try:
        lock = sub.open(LOCK_NAME, os.O_RDWR)
    except OSError:
        return  # no lock file: an older version's folder, or one being made
    try:
        if not _abandoned(lock):
            return  # held: its writer is alive (on this host, in a container, over NFS)
        try:
            remove_tree(sub)
        except OSError:
            pass
        _rmdir_if_same(parent, name, sub.identity)
    finally:
        os.close(lock)
    if portable.CAPS.record_locks:
        return
    try:  # an open file cannot be removed there (Windows): the lock file, then the folder, now
        sub.unlink(LOCK_NAME)
    except OSError:
        return
    _rmdir_if_same(parent, name, sub.identity)


def remove_stale(directory: Path) -> None:
    """Removes the private folders in `directory` that are proven abandoned (their lock is free)."""
    try:
        parent = Folder(directory)
    except OSError:
        return
    try:
        _sweep(parent)
    finally:
        parent.close()


class PrivateFolder:
    """A private folder, held: `parent` (the user's folder), `folder` (ours), `lock_fd` (its lock).

    `path`: where writers write (pinned through its descriptor where possible); `directory`: the
    user's folder, as the user named it (for messages)."""

    def __init__(self, directory: Path, label: Path):
        self.directory, self.label = Path(directory), label
        self.parent = self._open_parent()
        self.folder: Folder | None = None
        self.lock_fd = -1
        self.locked_by_record = portable.CAPS.record_locks  # the lock's kind, as taken
        self.kept = False  # renamed onto its target (staged_directory): never removed then
        try:
            _sweep(self.parent)
            self.name = self._make()
            replaced = CloudWriteError(f"{label}: cannot write in {str(self.directory)!r}: its private work folder "
                                       f"was replaced by someone else before it was used")
            try:
                self.folder = self.parent.subfolder(self.name)
            except OSError:  # a link, a file or nothing under its name: not ours
                raise replaced from None
            st = self.folder.stat()
            # Renamed away and replaced between mkdir and open: that folder is not ours to use.
            if not stat.S_ISDIR(st.st_mode) or not portable.owned(st):
                raise replaced
            if stat.S_IMODE(st.st_mode) != 0o700:  # a umask that removes owner bits
                self.folder.chmod(0o700)
            self.identity = self.folder.identity
            _OWN.add(self.identity)
            try:
                self.lock_fd = self._lock()
            except OSError as e:
                raise CloudWriteError(f"{label}: cannot write in {str(self.directory)!r}: {describe(e)}") from None
        except BaseException:
            self.close(remove=True)
            raise
        pinned = self.folder.pinned()
        self.pinned = pinned != self.folder.path
        self.path = Path(pinned) if self.pinned else self.directory / self.name
        if self.pinned:
            _SHOWN[pinned] = str(self.directory)

    @property
    def fd(self) -> int:
        """The private folder's descriptor, -1 where folders are held by name."""
        return self.folder.fd if self.folder is not None else -1

    def _open_parent(self) -> Folder:
        try:
            return Folder(self.directory)  # a link the user chose is followed
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
                self.parent.mkdir(name, 0o700)
                return name
            except FileExistsError:
                continue
            except OSError as e:
                raise CloudWriteError(f"{self.label}: cannot write in {str(self.directory)!r}: "
                                      f"{describe(e)}") from None
        raise CloudWriteError(f"{self.label}: cannot write in {str(self.directory)!r}: no free name for a "
                              f"private work folder")

    def _lock(self) -> int:
        exclusive = os.O_RDWR | os.O_CREAT | os.O_EXCL
        if self.locked_by_record:
            # Locked under a name of its own, then renamed to LOCK_NAME: a sweeping process never
            # finds LOCK_NAME unlocked while this one lives.
            name = f"{LOCK_NAME}.{secrets.token_hex(4)}"
            fd = self.folder.open(name, exclusive, 0o600)
            try:
                if not portable.try_lock(fd):
                    raise OSError(f"{name}: locked by another process as it was made")
                self.folder.replace(name, self.folder, LOCK_NAME)
            except BaseException:
                os.close(fd)
                raise
            return fd
        # msvcrt's locks (Windows cannot rename an open file): made under its name, then locked and
        # marked live (_abandoned); a sweep that comes in between finds it unmarked and leaves it.
        # Without any lock: the file only says what the folder is; no sweep removes it.
        fd = self.folder.open(LOCK_NAME, exclusive, 0o600)
        try:
            if portable.kernel_locks():
                if not portable.try_lock(fd):
                    raise OSError(f"{LOCK_NAME}: locked by another process as it was made")
                portable.write_at(fd, _LIVE, 0)
        except BaseException:
            os.close(fd)
            raise
        return fd

    def _named_ours(self, name: str) -> bool:
        try:
            return portable.identity(self.parent.lstat(name)) == self.identity
        except OSError:
            return False

    def check(self) -> None:
        """Without pinned paths: refuses when the folder's name no longer leads to our folder (with
        them, writes went through the descriptor and the name does not matter)."""
        if not self.pinned:
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
        if self.folder is not None and not self.folder.held:
            self.folder.path = os.path.join(self.parent.path, name)  # held by name: its name now

    def unlock(self) -> None:
        """Removes the lock file and lets the lock go (the folder is about to become an output)."""
        if self.lock_fd < 0:
            return
        if self.locked_by_record:
            self.folder.unlink(LOCK_NAME)
            os.close(self.lock_fd)
        else:  # an open file cannot be removed there: unmarked first, so no sweep takes it meanwhile
            os.ftruncate(self.lock_fd, 0)
            os.close(self.lock_fd)
            self.folder.unlink(LOCK_NAME)
        self.lock_fd = -1

    def close(self, remove: bool) -> None:
        """Closes every descriptor; with `remove`, first removes the folder through them."""
        folder = self.folder
        if folder is not None:
            if remove and not self.kept and hasattr(self, "identity"):  # only a folder proven ours
                try:
                    remove_tree(folder)
                except OSError:
                    pass
                if not self.locked_by_record and self.lock_fd >= 0:  # the lock file stayed (open): now
                    os.close(self.lock_fd)
                    self.lock_fd = -1
                    try:
                        folder.unlink(LOCK_NAME)
                    except OSError:
                        pass
                _rmdir_if_same(self.parent, self.name, self.identity)
            _SHOWN.pop(folder.pinned(), None)
            folder.close()
            self.folder = None
        if self.lock_fd >= 0:
            os.close(self.lock_fd)  # after the folder's removal: the lock proves it alive until then
            self.lock_fd = -1
        if hasattr(self, "identity"):
            _OWN.discard(self.identity)
        if self.parent is not None:
            self.parent.close()
            self.parent = None


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
        folder = Folder(shown)
    except FileNotFoundError:
        raise CloudWriteError(f"{shown}: no such directory") from None
    except NotADirectoryError:
        raise CloudWriteError(f"{shown}: is not a directory") from None
    except OSError as e:
        raise CloudWriteError(f"{shown}: cannot open: {describe(e)}") from None
    pinned = folder.pinned()
    try:
        if pinned == folder.path:
            yield Path(shown)
            try:
                same = portable.identity(os.stat(shown)) == folder.identity
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
        folder.close()
