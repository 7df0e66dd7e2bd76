"""All-or-nothing file output: write a temporary file beside the target, then rename it."""
from __future__ import annotations

import os
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

from ..errors import CloudWriteError

__all__ = ["atomic_output"]


def _describe(err: OSError) -> str:
    return err.strerror or str(err)


def _new_file_mode(target: Path) -> int:
    # mkstemp creates 0600 files; give the result the permissions a plain open() would have
    # (or keep the mode of the file being replaced).
    try:
        return target.stat().st_mode & 0o7777
    except OSError:
        umask = os.umask(0)
        os.umask(umask)
        return 0o666 & ~umask


def _fsync_dir(directory: Path) -> None:
    # Makes the rename itself durable; not every filesystem allows fsync on a directory.
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


@contextmanager
def atomic_output(path: str | os.PathLike) -> Iterator[Path]:
    """Yields a temporary path in the target's directory; on normal exit the file written there
    is fsync'ed and renamed onto `path` (``os.replace``), so readers see either the old file or
    the complete new one.

    If the body raises, the temporary file is removed, nothing appears at `path` (an existing
    file there is left untouched) and the exception propagates; an OSError is re-raised as
    :class:`CloudWriteError`. A missing or unwritable directory, or a directory at `path`,
    raises :class:`CloudWriteError` naming `path` before the body runs.
    """
    target = Path(path)
    if target.is_dir():
        raise CloudWriteError(f"{path}: is a directory")
    directory = target.parent
    try:
        fd, tmp_name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".part", dir=directory)
    except FileNotFoundError:
        raise CloudWriteError(f"{path}: cannot write: directory {str(directory)!r} does not exist") from None
    except NotADirectoryError:
        raise CloudWriteError(f"{path}: cannot write: {str(directory)!r} is not a directory") from None
    except OSError as e:
        raise CloudWriteError(f"{path}: cannot write in {str(directory)!r}: {_describe(e)}") from None
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        yield tmp
        with open(tmp, "rb+") as f:
            os.fsync(f.fileno())
        os.chmod(tmp, _new_file_mode(target))
        os.replace(tmp, target)
    except BaseException as e:
        try:
            tmp.unlink()
        except OSError:
            pass
        if isinstance(e, OSError):
            raise CloudWriteError(f"{path}: {_describe(e)}") from e
        raise
    _fsync_dir(directory)
