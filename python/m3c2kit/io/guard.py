"""Turning the reading libraries' exceptions into :class:`CloudReadError` / :class:`CloudWriteError`."""
from __future__ import annotations

import os
import struct
import sys
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

from ..base import portable
from ..base.errors import CloudReadError, CloudWriteError, M3C2Error

__all__ = ["library_message", "read_errors", "write_errors", "available_memory", "format_bytes"]

# What malformed input makes numpy, laspy (LaspyException), lazrs (LazrsError is a RuntimeError),
# pye57 (E57Exception) and our own parsers raise. TypeError/AttributeError are left alone on
# purpose: they mean a bug here, not a bad file.
_INPUT_ERRORS: tuple[type[BaseException], ...] = (
    ValueError, OSError, EOFError, struct.error, RuntimeError, LookupError, ArithmeticError,
    BufferError, MemoryError,
)

def _input_errors() -> tuple[type[BaseException], ...]:
    # The libraries' own exception types, looked up only once they are imported (a library not
    # imported yet raised nothing): importing this module must not import laspy (and through it
    # pyproj and requests) or pye57.
    found = _INPUT_ERRORS
    laspy = sys.modules.get("laspy")
    if laspy is not None and hasattr(laspy, "LaspyException"):
        found += (laspy.LaspyException,)
    e57_error = getattr(getattr(sys.modules.get("pye57"), "libe57", None), "E57Exception", None)
    if e57_error is not None:
        found += (e57_error,)
    return found


def _is_rust_panic(err: BaseException) -> bool:
    # lazrs (via pyo3) turns a Rust panic into pyo3_runtime.PanicException, which derives from
    # BaseException, not Exception; its module is created at run time, so match it by name.
    return type(err).__name__ == "PanicException"


def library_message(err: BaseException) -> str:
    """The first line of a library's message (pye57 appends pages of debug context)."""
    if isinstance(err, MemoryError):
        return "not enough memory"
    if isinstance(err, OSError) and err.strerror:
        return err.strerror
    text = str(err).strip()
    first = text.splitlines()[0].strip() if text else ""
    return first or type(err).__name__


@contextmanager
def _library_errors(error: type[M3C2Error], path: object, panic_note: str) -> Iterator[None]:
    """Re-raises a library exception from the body as ``error(f"{path}: {message}")``; a Rust
    panic from lazrs (a BaseException) is caught too, other BaseExceptions pass."""
    try:
        yield
    except M3C2Error:
        raise
    except BaseException as e:
        if isinstance(e, _input_errors()):
            raise error(f"{path}: {library_message(e)}") from e
        if _is_rust_panic(e):
            raise error(f"{path}: {panic_note}{library_message(e)}{')' if panic_note else ''}") from e
        raise


def read_errors(path: object):
    """Re-raises a library exception from the body as ``CloudReadError(f"{path}: {message}")``."""
    return _library_errors(CloudReadError, path, "corrupt or unsupported data (")


def write_errors(path: object):
    """Re-raises a library exception from the body as ``CloudWriteError(f"{path}: {message}")``."""
    return _library_errors(CloudWriteError, path, "")


# ------------------------------------------------------------------------------ memory budget

#: Environment variable that overrides the detected available memory (bytes), e.g. to allow a
#: run that swap or memory overcommit can serve, or to test the check.
MEMORY_ENV = "M3C2_AVAILABLE_MEMORY"
_CGROUP_FILES = (("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory.current"),  # cgroup v2
                 ("/sys/fs/cgroup/memory/memory.limit_in_bytes",  # cgroup v1
                  "/sys/fs/cgroup/memory/memory.usage_in_bytes"))


def _read_int(path: str) -> int | None:
    try:
        text = Path(path).read_text().strip()
    except OSError:
        return None
    return int(text) if text.isdigit() else None  # "max" (no limit) -> None


def available_memory() -> int | None:
    """Bytes of memory a new allocation can still get, or None when unknown.

    ``$M3C2_AVAILABLE_MEMORY`` (bytes) wins when set. Otherwise the system's available memory:
    ``MemAvailable`` of /proc/meminfo (free memory plus reclaimable page cache), else
    ``SC_AVPHYS_PAGES * SC_PAGE_SIZE`` (free pages only), capped by the cgroup's limit minus
    its usage (``/sys/fs/cgroup/memory.max`` - ``memory.current``, or the cgroup v1 files: absent
    outside Linux, and then not read). Both system sources are base/portable.py's; where neither
    answers (Windows), None: the in-memory check is skipped unless ``$M3C2_AVAILABLE_MEMORY`` says.
    """
    override = os.environ.get(MEMORY_ENV, "").strip()
    if override:
        try:
            return max(int(float(override)), 0)
        except ValueError:
            pass
    available = portable.meminfo_available()
    if available is None:
        available = portable.free_pages_bytes()
    for limit_file, usage_file in _CGROUP_FILES:
        limit = _read_int(limit_file)
        if limit is None or limit >= 1 << 60:  # v1 writes a huge number for "no limit"
            continue
        room = max(limit - (_read_int(usage_file) or 0), 0)
        available = room if available is None else min(available, room)
        break
    return available


def format_bytes(n: float) -> str:
    """``"1.5 GiB"``-style size."""
    for unit in ("bytes", "KiB", "MiB", "GiB"):
        if abs(n) < 1024 or unit == "GiB":
            return f"{n:.0f} {unit}" if unit == "bytes" else f"{n:.1f} {unit}"
        n /= 1024
    return f"{n:.1f} GiB"
