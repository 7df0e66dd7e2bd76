"""One rule checked before any work, for every command (issue 15): no output of a run may be, be a
hard link to, or be reached through a symbolic link to any of its inputs, and an existing output
that is read-only is refused rather than replaced (docs/errors.md, "Outputs")."""
from __future__ import annotations

import errno
import os
import stat
from typing import Mapping

from ..base.errors import CloudWriteError, UsageError
from .input_file import os_problem

__all__ = ["check_outputs", "refuse_special", "require_suffix"]


def _identity(path) -> tuple[int, int] | None:
    """(device, inode) of the file `path` names, through any symbolic link; None if there is none."""
    try:
        info = os.stat(path)
    except (OSError, ValueError):
        return None
    return info.st_dev, info.st_ino


def check_outputs(outputs: Mapping[str, object], inputs: Mapping[str, object]) -> None:
    """Raises a UsageError naming both when an output (label -> path) is the same file as an input
    (same device and inode, so also a hard link or a symlink to it, or the same resolved path), or
    when an existing output is read-only; a CloudWriteError when an output is a folder. None
    paths are skipped. Every command calls it before any work."""
    known = {}
    for label, path in inputs.items():
        if path is None:
            continue
        key = _identity(path)
        if key is not None:
            known[key] = (label, path)
        known[os.path.realpath(path)] = (label, path)
    for label, path in outputs.items():
        if path is None:
            continue
        _refuse_no_file_name(label, path)
        _refuse_name_too_long(path)
        for key in (_identity(path), os.path.realpath(path)):
            if key is not None and key in known:
                in_label, in_path = known[key]
                raise UsageError(f"{label} {os.fspath(path)!r} is the {in_label} {os.fspath(in_path)!r} (the same "
                                 f"file, a hard link or a link to it): writing it would destroy the input; choose "
                                 f"another output path")
        if os.path.isdir(path):
            raise CloudWriteError(f"{os.fspath(path)}: is a directory")
        refuse_special(path)
        _refuse_read_only(label, path)


def _refuse_no_file_name(label: str, path) -> None:
    # `-o ''` and `-o .` name no file: derived names then failed with "PosixPath('.') has an empty name".
    if os.path.basename(os.path.normpath(os.fspath(path))) in ("", ".", "..", "/"):
        raise UsageError(f"{label} {os.fspath(path)!r}: names no file; give a file name")


def require_suffix(label: str, path, suffixes: tuple[str, ...], what: str) -> None:
    """An output's content matches its extension (issue 42: `variogram -o m.png` wrote the model's
    JSON under a figure's name): a UsageError unless `path` ends with one of `suffixes`."""
    if path is not None and os.path.splitext(os.fspath(path))[1].lower() not in suffixes:
        raise UsageError(f"{label} {os.fspath(path)}: {what} is written as {' or '.join(suffixes)}; give a name "
                         f"ending so")


def refuse_special(path) -> None:
    # An output is renamed onto its name: run as root, `-o /dev/null` replaced the device node
    # with a regular file (and `-o FIFO` the FIFO); a link to one (/dev/stdout) names what the
    # user meant to write to, which a rename would not reach either.
    for look in (os.lstat, os.stat):
        try:
            mode = look(path).st_mode
        except (OSError, ValueError):
            continue
        if not (stat.S_ISREG(mode) or stat.S_ISLNK(mode) or stat.S_ISDIR(mode)):
            raise CloudWriteError(f"{os.fspath(path)}: not a regular file (a device, FIFO or socket); an output "
                                  f"replaces only a regular file: choose another output path")


def _refuse_name_too_long(path) -> None:
    # Found now, not when the output is written after the whole run (the same check reading does).
    try:
        os.stat(path)
    except OSError as e:
        if e.errno == errno.ENAMETOOLONG:
            raise CloudWriteError(f"{os.fspath(path)}: {os_problem(e)}") from None
    except ValueError:  # an embedded NUL: the writer reports it
        pass


def _refuse_read_only(label: str, path) -> None:
    try:
        info = os.stat(path)
    except (OSError, ValueError):
        return
    if stat.S_ISREG(info.st_mode) and not info.st_mode & (stat.S_IWUSR | stat.S_IWGRP | stat.S_IWOTH):
        raise UsageError(f"{label} {os.fspath(path)!r} exists and is read-only (mode {stat.filemode(info.st_mode)}); "
                         f"remove it or make it writable first, or choose another output path")
