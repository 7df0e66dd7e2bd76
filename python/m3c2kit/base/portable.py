"""The package's one portability layer (issue 44): every call that only POSIX systems, or only
Linux, offer is made here, beside the fallback another system gets; nothing else in the package
imports ``fcntl`` or ``msvcrt``, reads ``/proc``, passes ``O_NOFOLLOW``, ``O_DIRECTORY`` or
``dir_fd``, or names a signal that Windows lacks (docs/architecture.md, "Portability", lists each
path, its fallback and what changes for the user).

Each capability is detected by feature, never by the system's name (macOS has ``fcntl``,
``O_NOFOLLOW`` and ``dir_fd`` but no ``/proc``; Windows none of them). :data:`CAPS` holds what this
process uses. The environment variable ``M3C2_PORTABLE_FALLBACKS=1``, read once at import, switches
every POSIX path off (:func:`fallbacks`), so that the fallbacks run, and are tested, on Linux
(``tests/python/base/test_portable.py``; ``scripts/test.sh`` runs the tests of base, io, series,
cli and qgis_runner under it too); tests switch single capabilities with :func:`use`. The C++ engine's
``M3C2_PORTABLE_FALLBACKS`` CMake option is the same idea for its compiler builtins.

The QGIS plugin cannot import m3c2kit: its own two signal paths (SIGCONT; Windows' Ctrl-Break)
are in ``qgis/m3c2kit_processing/portable.py``, which reads the same variable.
"""
from __future__ import annotations

import errno
import os
import signal
import stat
from collections import namedtuple
from contextlib import contextmanager
from typing import Iterator

try:
    import fcntl
except ImportError:  # Windows
    fcntl = None
try:
    import msvcrt
except ImportError:  # everywhere but Windows
    msvcrt = None

__all__ = ["ENV", "Capabilities", "CAPS", "FORCED", "detect", "fallbacks", "use", "O_BINARY", "O_CLOEXEC",
           "O_NONBLOCK", "ELOOP", "FD_PATH_PREFIX", "identity", "Folder", "FolderReplaced", "open_nofollow",
           "regular_nofollow", "unblock", "chmod_open", "owned", "kernel_locks", "try_lock", "lock_folder",
           "read_at", "write_at", "stop_signals", "end_by_signal", "signal_self", "resident_bytes",
           "meminfo_available", "free_pages_bytes", "malloc_trim"]

ENV = "M3C2_PORTABLE_FALLBACKS"


#: What this process may use; False: the fallback (docs/architecture.md, "Portability"). A named
#: tuple (no dataclass: this module is imported before every command line, so it stays cheap).
Capabilities = namedtuple("Capabilities", [
    "record_locks",   # fcntl.lockf: POSIX record locks (a store's lock, a private folder's liveness)
    "folder_locks",   # fcntl.flock on a folder's descriptor (a store's second lock)
    "byte_locks",     # msvcrt.locking (Windows): the record locks' stand-in, also dropped when the holder dies
    "nofollow",       # os.O_NOFOLLOW: an open that refuses a link at the last component
    "folder_fds",     # folders held as descriptors (O_DIRECTORY) and calls by name through them (dir_fd)
    "fd_paths",       # /proc/self/fd/N: a path that resolves through a held descriptor (Linux)
    "procfs",         # /proc/self/status, /proc/meminfo: this process's and the system's memory (Linux)
    "owner_ids",      # os.geteuid: whose a folder is
    "fd_chmod",       # os.fchmod: a mode set through a descriptor
    "positional_io",  # os.pread, os.pwrite
    "posix_signals",  # SIGHUP, SIGQUIT, SIGCONT, and a process ending itself by its own signal
    "sysconf_pages",  # os.sysconf("SC_AVPHYS_PAGES"): free memory without /proc
    "glibc",          # glibc's malloc_trim
])


def _glibc() -> bool:
    try:
        return bool(os.confstr("CS_GNU_LIBC_VERSION"))
    except (AttributeError, ValueError, OSError):
        return False


def _sysconf_pages() -> bool:
    try:
        return os.sysconf("SC_AVPHYS_PAGES") > 0 and os.sysconf("SC_PAGE_SIZE") > 0
    except (AttributeError, ValueError, OSError):
        return False


def detect() -> Capabilities:
    """The capabilities this system offers, each found by feature."""
    by_name = {os.open, os.stat, os.mkdir, os.rmdir, os.unlink, os.rename}  # os.replace is os.rename's twin
    folder_fds = hasattr(os, "O_DIRECTORY") and by_name <= os.supports_dir_fd and os.listdir in os.supports_fd
    return Capabilities(
        record_locks=fcntl is not None and hasattr(fcntl, "lockf"),
        folder_locks=fcntl is not None and hasattr(fcntl, "flock"),
        byte_locks=msvcrt is not None and hasattr(msvcrt, "locking"),
        nofollow=hasattr(os, "O_NOFOLLOW"),
        folder_fds=folder_fds,
        fd_paths=folder_fds and os.path.isdir("/proc/self/fd"),
        procfs=os.path.isfile("/proc/self/status"),
        owner_ids=hasattr(os, "geteuid"),
        fd_chmod=hasattr(os, "fchmod"),
        positional_io=hasattr(os, "pread") and hasattr(os, "pwrite"),
        posix_signals=all(hasattr(signal, name) for name in ("SIGHUP", "SIGQUIT", "SIGCONT", "pthread_kill")),
        sysconf_pages=_sysconf_pages(),
        glibc=_glibc(),
    )


def fallbacks() -> Capabilities:
    """Every POSIX path off: what a system without them gets. Windows' byte locks stay as found
    (they are not POSIX; on Linux there are none, so the lock files' own fallback runs)."""
    off = Capabilities(**{name: False for name in Capabilities._fields})
    return off._replace(byte_locks=msvcrt is not None and hasattr(msvcrt, "locking"))


#: Whether M3C2_PORTABLE_FALLBACKS switched the POSIX paths off (read once, at import).
FORCED = os.environ.get(ENV, "").strip() not in ("", "0")
CAPS: Capabilities = fallbacks() if FORCED else detect()


@contextmanager
def use(capabilities: Capabilities) -> Iterator[Capabilities]:
    """`capabilities` in effect inside the block (tests: a fallback on Linux). Folders opened
    inside keep the way they were opened after it."""
    global CAPS
    previous, CAPS = CAPS, capabilities
    try:
        yield capabilities
    finally:
        CAPS = previous


# ----------------------------------------------------------------------------------- flags

#: Windows: bytes as they are (os.open's default there is text mode, which turns \n into \r\n
#: and stops reading at a Ctrl-Z byte). 0 elsewhere.
O_BINARY = getattr(os, "O_BINARY", 0)
#: The descriptor is not inherited by a child (Python's descriptors are not anyway, PEP 446).
O_CLOEXEC = getattr(os, "O_CLOEXEC", 0) | getattr(os, "O_NOINHERIT", 0)
#: Opening a FIFO returns at once instead of waiting for a writer. 0 where there is none
#: (Windows has no FIFO in its file system: nothing can block there).
O_NONBLOCK = getattr(os, "O_NONBLOCK", 0)
#: The error of an open refused because the name is a link.
ELOOP = getattr(errno, "ELOOP", 40)
#: How a path through a held descriptor starts (Linux's /proc): Folder.pinned.
FD_PATH_PREFIX = "/proc/self/fd/"


def identity(st: os.stat_result) -> tuple[int, int]:
    """(st_dev, st_ino): which file a stat is of (Windows: the volume and the file index)."""
    return st.st_dev, st.st_ino


def unblock(fd: int) -> None:
    """Plain (blocking) reads on `fd`, opened with O_NONBLOCK, once it is known to be a regular file."""
    if O_NONBLOCK:
        os.set_blocking(fd, True)


def _loop(path) -> OSError:
    return OSError(ELOOP, os.strerror(ELOOP), os.fspath(path) if not isinstance(path, int) else path)


def _lstat_or_none(path, dir_fd=None):
    try:
        return os.stat(path, dir_fd=dir_fd, follow_symlinks=False) if dir_fd is not None else os.lstat(path)
    except FileNotFoundError:
        return None


def _open_checked(path, flags: int, mode: int, dir_fd=None) -> int:
    """An open that never uses a link, without O_NOFOLLOW: refused (ELOOP) when the name is a link
    before the open, or when after it the name does not lead to the file opened (a link or another
    file swapped in between). Weaker than O_NOFOLLOW: a link swapped in during the open itself is
    followed (with O_CREAT it may create or, with O_TRUNC, empty its target) before it is refused."""
    before = _lstat_or_none(path, dir_fd)
    if before is not None and stat.S_ISLNK(before.st_mode):
        raise _loop(path)
    fd = os.open(path, flags, mode, dir_fd=dir_fd) if dir_fd is not None else os.open(path, flags, mode)
    try:
        opened = identity(os.fstat(fd))
        now = _lstat_or_none(path, dir_fd)
        if now is None or stat.S_ISLNK(now.st_mode) or identity(now) != opened or \
                (before is not None and identity(before) != opened):
            raise _loop(path)
    except BaseException:
        os.close(fd)
        raise
    return fd


def open_nofollow(path, flags: int, mode: int = 0o777) -> int:
    """os.open(path, flags | O_CLOEXEC | O_BINARY, mode) refusing a link at the last component
    (OSError ELOOP): O_NOFOLLOW where there is one, else the checked open (_open_checked)."""
    flags |= O_CLOEXEC | O_BINARY
    if CAPS.nofollow:
        return os.open(path, flags | os.O_NOFOLLOW, mode)
    return _open_checked(path, flags, mode)


def regular_nofollow(path, flags: int = os.O_RDONLY, mode: int = 0o777) -> int:
    """open_nofollow with O_NONBLOCK (a FIFO never blocks it), then an OSError unless it is a
    regular file; blocking again when it is."""
    fd = open_nofollow(path, flags | O_NONBLOCK, mode)
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            raise OSError(f"{os.fspath(path)} is not a regular file")
        unblock(fd)
    except BaseException:
        os.close(fd)
        raise
    return fd


def chmod_open(fd: int, mode: int, path) -> None:
    """Sets the mode of the file open at `fd`, named `path`: fchmod where there is one; else by
    name once the name is checked to lead to that file (OSError ELOOP otherwise)."""
    if CAPS.fd_chmod:
        os.fchmod(fd, mode)
        return
    now = _lstat_or_none(path)
    if now is None or stat.S_ISLNK(now.st_mode) or identity(now) != identity(os.fstat(fd)):
        raise _loop(path)
    os.chmod(path, mode)


def owned(st: os.stat_result) -> bool:
    """Whether `st` is of a file this process's user owns; True where there are no user ids
    (Windows: who may enter a folder is its ACL's, inherited from the folder it is made in)."""
    return st.st_uid == os.geteuid() if CAPS.owner_ids else True


# --------------------------------------------------------------------------------- folders

class FolderReplaced(OSError):
    """A held folder's name no longer leads to it (the fallback of a folder held by name)."""

    def __init__(self, path: str):
        super().__init__(errno.ENOENT, "the folder was replaced by someone else", path)


_DIR_FLAGS = os.O_RDONLY | getattr(os, "O_DIRECTORY", 0) | O_CLOEXEC


class Folder:
    """A folder held for the calls made by name inside it.

    Where folders open as descriptors (CAPS.folder_fds), `fd` is one and every call goes through
    it: a later rename of the folder, or another folder swapped in under its name, redirects none.
    Else (Windows, or the forced fallbacks) `fd` is -1 and each call joins `path`, after checking
    that `path` still leads to the folder first opened (its identity): a swap is refused, but one
    made between the check and the call is not seen (the fallback's weaker guarantee).
    `follow=False`: a link at `path` is refused (ELOOP), never entered."""

    def __init__(self, path, *, follow: bool = True, _parent: "Folder | None" = None, _name: str | None = None):
        self.path = os.fspath(path)
        self.follow = follow
        self.fd = -1
        if CAPS.folder_fds and (_parent is None or _parent.fd >= 0):
            flags = _DIR_FLAGS | (0 if follow else (os.O_NOFOLLOW if CAPS.nofollow else 0))
            if _parent is not None:
                self.fd = os.open(_name, flags, dir_fd=_parent.fd)
            else:
                self.fd = os.open(self.path, flags)
            try:
                st = os.fstat(self.fd)
                if not follow and not CAPS.nofollow:
                    now = _lstat_or_none(_name, _parent.fd) if _parent is not None else _lstat_or_none(self.path)
                    if now is None or stat.S_ISLNK(now.st_mode) or identity(now) != identity(st):
                        raise _loop(self.path)
            except BaseException:
                os.close(self.fd)
                raise
        else:
            if _parent is not None:
                _parent.check()
            st = os.stat(self.path) if follow else os.lstat(self.path)
            if stat.S_ISLNK(st.st_mode):
                raise _loop(self.path)
            if not stat.S_ISDIR(st.st_mode):
                raise NotADirectoryError(errno.ENOTDIR, os.strerror(errno.ENOTDIR), self.path)
        self.identity = identity(st)

    def __enter__(self) -> "Folder":
        return self

    def __exit__(self, *exc) -> bool:
        self.close()
        return False

    def close(self) -> None:
        if self.fd >= 0:
            os.close(self.fd)
            self.fd = -1

    @property
    def held(self) -> bool:
        """True when calls go through a descriptor (no swap of the name can redirect them)."""
        return self.fd >= 0

    def _join(self, name: str) -> str:
        return os.path.join(self.path, name)

    def check(self) -> None:
        """By name: FolderReplaced unless `path` still leads to this folder. Held: nothing to check."""
        if self.fd >= 0:
            return
        try:
            st = os.stat(self.path) if self.follow else os.lstat(self.path)
        except OSError:
            raise FolderReplaced(self.path) from None
        if identity(st) != self.identity:
            raise FolderReplaced(self.path)

    def stat(self) -> os.stat_result:
        if self.fd >= 0:
            return os.fstat(self.fd)
        self.check()
        return os.stat(self.path) if self.follow else os.lstat(self.path)

    def pinned(self) -> str:
        """A path of this folder for code that insists on a path: /proc/self/fd/N (resolved through
        the descriptor) where there is one, else its name."""
        if self.fd >= 0 and CAPS.fd_paths:
            return f"{FD_PATH_PREFIX}{self.fd}"
        return self.path

    def listdir(self) -> list[str]:
        if self.fd >= 0:
            return os.listdir(self.fd)
        self.check()
        return os.listdir(self.path)

    def lstat(self, name: str) -> os.stat_result:
        """The stat of `name` in this folder, a link not followed."""
        if self.fd >= 0:
            return os.stat(name, dir_fd=self.fd, follow_symlinks=False)
        self.check()
        return os.lstat(self._join(name))

    def stat_name(self, name: str) -> os.stat_result:
        """The stat of `name` in this folder, a link followed."""
        if self.fd >= 0:
            return os.stat(name, dir_fd=self.fd)
        self.check()
        return os.stat(self._join(name))

    def open(self, name: str, flags: int, mode: int = 0o777) -> int:
        """A descriptor of the file `name` in this folder, never through a link (ELOOP)."""
        flags |= O_CLOEXEC | O_BINARY
        if self.fd >= 0:
            if CAPS.nofollow:
                return os.open(name, flags | os.O_NOFOLLOW, mode, dir_fd=self.fd)
            return _open_checked(name, flags, mode, dir_fd=self.fd)
        self.check()
        return _open_checked(self._join(name), flags, mode)

    def subfolder(self, name: str) -> "Folder":
        """The folder `name` in this one, held; a link there is refused (ELOOP), never entered."""
        return Folder(self._join(name), follow=False, _parent=self, _name=name)

    def mkdir(self, name: str, mode: int = 0o777) -> None:
        if self.fd >= 0:
            os.mkdir(name, mode, dir_fd=self.fd)
            return
        self.check()
        os.mkdir(self._join(name), mode)

    def unlink(self, name: str) -> None:
        if self.fd >= 0:
            os.unlink(name, dir_fd=self.fd)
            return
        self.check()
        os.unlink(self._join(name))

    def rmdir(self, name: str) -> None:
        if self.fd >= 0:
            os.rmdir(name, dir_fd=self.fd)
            return
        self.check()
        os.rmdir(self._join(name))

    def replace(self, name: str, into: "Folder", new_name: str) -> None:
        """os.replace of `name` here onto `new_name` in `into`."""
        if self.fd >= 0 and into.fd >= 0:
            os.replace(name, new_name, src_dir_fd=self.fd, dst_dir_fd=into.fd)
            return
        self.check()
        into.check()
        os.replace(self._join(name), into._join(new_name))

    def rename(self, name: str, into: "Folder", new_name: str) -> None:
        """os.rename of `name` here to `new_name` in `into` (a folder onto an empty folder)."""
        if self.fd >= 0 and into.fd >= 0:
            os.rename(name, new_name, src_dir_fd=self.fd, dst_dir_fd=into.fd)
            return
        self.check()
        into.check()
        os.rename(self._join(name), into._join(new_name))

    def chmod(self, mode: int) -> None:
        """This folder's mode: through the descriptor, else by its checked name."""
        if self.fd >= 0 and CAPS.fd_chmod:
            os.fchmod(self.fd, mode)
            return
        self.check()
        os.chmod(self.path, mode)

    def fsync(self) -> None:
        """Makes renames in this folder durable where a folder can be fsynced (not every file
        system allows it; no folder descriptor, nothing to do)."""
        if self.fd >= 0:
            try:
                os.fsync(self.fd)
            except OSError:
                pass


# ----------------------------------------------------------------------------------- locks

#: Where msvcrt locks its one byte: far past any holder text, which must stay readable (a Windows
#: byte-range lock also stops other processes' reads of the bytes it covers).
_BYTE_LOCK_OFFSET = 1 << 30
#: flock's answers where the file system cannot lock a folder (NFS, some FUSE).
_NO_FOLDER_LOCK = {errno.ENOLCK, errno.EBADF, errno.EINVAL, errno.EOPNOTSUPP, errno.ENOSYS}


def kernel_locks() -> bool:
    """Whether files can be locked by a lock the system drops when its holder dies (lockf, or
    msvcrt's byte locks); without (the forced fallbacks), locks are files made exclusively."""
    return CAPS.record_locks or CAPS.byte_locks


def try_lock(fd: int) -> bool:
    """Takes the exclusive lock of the file open at `fd` without waiting: True; False when another
    process holds it; an OSError when the file system cannot lock. POSIX: lockf, a record lock
    (honoured across PID namespaces and over NFS, dropped by the kernel when the holder dies, even
    by SIGKILL, and when the process closes ANY descriptor of the file). Windows: msvcrt.locking
    of one byte past the content (dropped when the holder closes it or dies). A RuntimeError where
    neither exists (callers ask kernel_locks() first)."""
    if CAPS.record_locks:
        try:
            fcntl.lockf(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as e:
            if e.errno in (errno.EACCES, errno.EAGAIN):
                return False
            raise
        return True
    if CAPS.byte_locks:
        position = os.lseek(fd, 0, os.SEEK_CUR)
        os.lseek(fd, _BYTE_LOCK_OFFSET, os.SEEK_SET)
        try:
            msvcrt.locking(fd, msvcrt.LK_NBLCK, 1)
        except OSError as e:
            if e.errno in (errno.EACCES, getattr(errno, "EDEADLOCK", errno.EDEADLK), errno.EDEADLK):
                return False
            raise
        finally:
            os.lseek(fd, position, os.SEEK_SET)
        return True
    raise RuntimeError("no file locks on this system (portable.kernel_locks() is False)")


def lock_folder(folder: Folder) -> bool | None:
    """flock on the held folder: True (taken), False (another process holds it), None where a
    folder cannot be locked (no flock, no folder descriptor, or a file system that refuses it:
    NFS, some FUSE)."""
    if not CAPS.folder_locks or folder.fd < 0:
        return None
    try:
        fcntl.flock(folder.fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as e:
        if e.errno in _NO_FOLDER_LOCK:
            return None
        if e.errno in (errno.EWOULDBLOCK, errno.EACCES):
            return False
        raise
    return True


def read_at(fd: int, size: int, offset: int) -> bytes:
    """Up to `size` bytes at `offset`: pread, else a seek and a read (the position moves)."""
    if CAPS.positional_io:
        return os.pread(fd, size, offset)
    os.lseek(fd, offset, os.SEEK_SET)
    return os.read(fd, size)


def write_at(fd: int, data: bytes, offset: int) -> None:
    """`data` at `offset`, whole: pwrite, else a seek and writes (the position moves)."""
    view = memoryview(data)
    if CAPS.positional_io:
        while view:
            view = view[os.pwrite(fd, view, offset):]
            offset = len(data) - len(view)
        return
    os.lseek(fd, offset, os.SEEK_SET)
    while view:
        view = view[os.write(fd, view):]


# --------------------------------------------------------------------------------- signals

#: The signals that end a run cleanly where they exist: Ctrl-C, a terminal hang-up, Ctrl-\,
#: kill's default, and Windows' Ctrl-Break (which the QGIS plugin sends to cancel there).
_STOP_SIGNALS = ("SIGINT", "SIGHUP", "SIGQUIT", "SIGTERM", "SIGBREAK")
_POSIX_ONLY = {"SIGHUP", "SIGQUIT"}


def stop_signals() -> tuple[int, ...]:
    """The numbers of the signals that end a run cleanly here (those this system has; without
    POSIX signals, only C's SIGINT and SIGTERM and Windows' SIGBREAK)."""
    names = [n for n in _STOP_SIGNALS if CAPS.posix_signals or n not in _POSIX_ONLY]
    return tuple(int(getattr(signal, n)) for n in names if hasattr(signal, n))


def end_by_signal(number: int) -> None:
    """Ends this process by signal `number`, as a process stopped by it ends (a shell sees
    128+N, a parent -N). Returns where that cannot be done (no POSIX signals: Windows, where
    os.kill would terminate the process with the signal's number as its status) or where the
    signal does not end it (a caller that handles it itself): the caller then exits itself."""
    if not CAPS.posix_signals:
        return
    signal.signal(number, signal.SIG_DFL)
    os.kill(os.getpid(), number)


def signal_self(number: int) -> None:
    """Sends this process signal `number`: os.kill, as another process would send it; without
    POSIX signals signal.raise_signal (Windows' os.kill would terminate the process without
    running the handler)."""
    if CAPS.posix_signals:
        os.kill(os.getpid(), number)
    else:
        signal.raise_signal(number)


# ---------------------------------------------------------------------------------- memory

def _proc_field(path: str, field: str) -> int | None:
    try:
        with open(path) as f:
            for line in f:
                if line.startswith(field):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def resident_bytes() -> int:
    """This process's resident size (VmRSS of /proc/self/status); 0 where there is no /proc
    (the memory planner then counts only its fixed base for what the process holds)."""
    if not CAPS.procfs:
        return 0
    return _proc_field("/proc/self/status", "VmRSS:") or 0


def meminfo_available() -> int | None:
    """MemAvailable of /proc/meminfo (free memory plus reclaimable page cache), None without it."""
    return _proc_field("/proc/meminfo", "MemAvailable:") if CAPS.procfs else None


def free_pages_bytes() -> int | None:
    """Free physical memory from sysconf (free pages only), None where sysconf does not say."""
    if not CAPS.sysconf_pages:
        return None
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (AttributeError, ValueError, OSError):
        return None


_TRIM: list = []


def malloc_trim():
    """glibc's malloc_trim (hands freed pages back to the system), or None where there is no glibc."""
    if not CAPS.glibc:
        return None
    if not _TRIM:
        try:
            import ctypes
            _TRIM.append(ctypes.CDLL("libc.so.6").malloc_trim)
        except (OSError, AttributeError):
            _TRIM.append(None)
    return _TRIM[0]
