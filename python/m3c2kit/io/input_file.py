"""Opening a user's input file safely: the one place every file option goes through.

A path a user gives may name a FIFO (opening it for reading blocks until a writer comes), a
device (``/dev/zero`` never ends, ``/dev/stdin`` waits for a terminal), a directory, or a
component longer than the system allows (ENAMETOOLONG). Each is refused with one line naming
the path, before a byte is read: the file is opened with O_NONBLOCK (a FIFO opens at once
instead of blocking), then the OPEN descriptor is checked with fstat (no race with a rename
between a check and the open). Small text and JSON inputs are read up to a limit of their kind,
so that a huge or endless file is refused instead of filling the memory.
"""
from __future__ import annotations

import errno
import json
import os
import stat
from pathlib import Path
from typing import Callable

from ..base import portable
from ..base.errors import M3C2Error, UsageError
from .guard import format_bytes

__all__ = ["SMALL_FILE_LIMITS", "os_problem", "os_error_message", "check_input_file", "read_small_bytes", "read_small_text", "read_small_json",
           "parse_json", "path_argument"]

_MiB = 1 << 20

#: The largest file of each kind of small input, in bytes: far above any real one (a CloudCompare
#: parameter file is under 1 KiB, a classifier JSON under 100 KiB, a scan-position table a few KiB),
#: far below what would exhaust the memory once parsed (JSON takes about 10 times its size).
SMALL_FILE_LIMITS: dict[str, int] = {
    "CloudCompare parameter file": 1 * _MiB,
    "classifier": 64 * _MiB,
    "scan-position file": 16 * _MiB,
    "matrix file": 1 * _MiB,
    "reduction-point file": 1 * _MiB,
    "polygon file": 256 * _MiB,
    "CRS file": 1 * _MiB,
    "epoch list file": 16 * _MiB,
    "error model file": 16 * _MiB,
    "registration file": 1 * _MiB,
}


def _a(kind: str) -> str:
    """`kind` with its article: "an error model file", "a classifier"."""
    return f"{'an' if kind[:1].lower() in 'aeiou' else 'a'} {kind}"


def os_problem(err: OSError) -> str:
    """What an OS error says, in the words messages use (ENAMETOOLONG names its limit)."""
    if err.errno == errno.ENAMETOOLONG:
        return "file name too long (a path component over 255 bytes, or a path over 4096)"
    return err.strerror or str(err)


def os_error_message(err: OSError) -> str:
    """``"PATH: PROBLEM"`` for an OS error that reached the command line unconverted (a name too
    long for a check such as Path.exists, which raises it): the file it names, then the problem."""
    name = err.filename  # None, or a descriptor, for errors that name no file
    if isinstance(name, (str, bytes, os.PathLike)):
        return f"{os.fsdecode(name)}: {os_problem(err)}"
    return os_problem(err)


def _open_regular(path, label: str, error: Callable[[str], M3C2Error], directory_note: str) -> int:
    """An open read-only descriptor of `path`, a regular file; else `error` naming `label`."""
    try:
        fd = os.open(path, os.O_RDONLY | portable.O_NONBLOCK | portable.O_CLOEXEC | portable.O_BINARY)
    except FileNotFoundError:
        raise error(f"{label}: no such file") from None
    except IsADirectoryError:
        raise error(f"{label}: is a directory, {directory_note}") from None
    except OSError as e:
        if e.errno == errno.ENAMETOOLONG:
            raise error(f"{label}: {os_problem(e)}") from None
        if e.errno == errno.ENXIO:  # a Unix socket (or a FIFO's other end) cannot be opened as a file
            raise error(f"{label}: not a regular file") from None
        raise error(f"{label}: cannot open: {os_problem(e)}") from None
    try:
        mode = os.fstat(fd).st_mode
        if stat.S_ISDIR(mode):
            raise error(f"{label}: is a directory, {directory_note}")
        if not stat.S_ISREG(mode):  # a FIFO, socket or device: reading could block or never end
            raise error(f"{label}: not a regular file")
        portable.unblock(fd)  # a regular file: plain reads from here
    except BaseException:
        os.close(fd)
        raise
    return fd


def check_input_file(path, *, label: str | None = None, error: Callable[[str], M3C2Error] = UsageError,
                     directory_note: str = "not a file") -> None:
    """Raises `error` (``"{label}: {problem}"``, label the path by default) unless `path` is an
    existing regular file that can be opened for reading. For inputs read by libraries that open
    the file themselves (point clouds)."""
    os.close(_open_regular(path, str(path) if label is None else label, error, directory_note))


def file_sha256(path, *, label: str | None = None, error: Callable[[str], M3C2Error] = UsageError) -> str:
    """The SHA-256 (hex) of the input `path`, a regular file of any size, read safely: `error`
    (``"{label}: {problem}"``) for a missing, special or unreadable file."""
    import hashlib
    label = str(path) if label is None else label
    fd = _open_regular(path, label, error, "not a file")
    digest = hashlib.sha256()
    try:
        with os.fdopen(fd, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                digest.update(block)
    except OSError as e:
        raise error(f"{label}: cannot read: {os_problem(e)}") from None
    return digest.hexdigest()


def read_small_bytes(path, kind: str, *, label: str | None = None,
                     error: Callable[[str], M3C2Error] = UsageError) -> bytes:
    """The bytes of the small input `path` of `kind` (a key of SMALL_FILE_LIMITS), read safely:
    `error` (``"{label}: {problem}"``) for a missing, special, unreadable or too large file."""
    label = str(path) if label is None else label
    limit = SMALL_FILE_LIMITS[kind]
    fd = _open_regular(path, label, error, f"not {_a(kind)}")
    try:
        with os.fdopen(fd, "rb") as f:
            data = f.read(limit + 1)  # one byte more tells a file at the limit from a larger one
    except OSError as e:
        raise error(f"{label}: cannot read: {os_problem(e)}") from None
    if len(data) > limit:
        raise error(f"{label}: larger than {format_bytes(limit)}; too large for a {kind}")
    return data


def read_small_text(path, kind: str, *, label: str | None = None, error: Callable[[str], M3C2Error] = UsageError,
                    encoding: str = "utf-8") -> str:
    """:func:`read_small_bytes` decoded; `error` for bytes that are not `encoding` text."""
    label = str(path) if label is None else label
    data = read_small_bytes(path, kind, label=label, error=error)
    try:
        return data.decode(encoding)
    except UnicodeDecodeError as e:
        raise error(f"{label}: not {_a(kind)} (not {encoding} text at byte {e.start})") from None


def read_small_json(path, kind: str, *, label: str | None = None, error: Callable[[str], M3C2Error] = UsageError):
    """:func:`read_small_text` parsed by :func:`parse_json`."""
    label = str(path) if label is None else label
    return parse_json(read_small_text(path, kind, label=label, error=error, encoding="utf-8-sig"), kind,
                      label=label, error=error)


def parse_json(text: str, kind: str, *, label: str, error: Callable[[str], M3C2Error] = UsageError):
    """`text` of a `kind` file parsed as JSON: `error` for text that is not JSON, and for nesting
    deeper than Python's recursion allows (a forged ``[[[[...]]]]`` raises RecursionError)."""
    try:
        return json.loads(text)
    except RecursionError:
        raise error(f"{label}: not {_a(kind)} (JSON nested too deeply)") from None
    except ValueError as e:
        raise error(f"{label}: not {_a(kind)} (not valid JSON: {e})") from None


def path_argument(name: str, value) -> Path:
    """`value`, an API function's file argument, as a Path; a TypeError naming the argument for
    anything else (None, a number, an array: os.fspath's message names no argument)."""
    if isinstance(value, (str, os.PathLike)):
        return Path(value)
    raise TypeError(f"{name} must be a file path (str or os.PathLike), got {type(value).__name__}")
