"""Turning the reading libraries' exceptions into :class:`CloudReadError` / :class:`CloudWriteError`."""
from __future__ import annotations

import struct
from contextlib import contextmanager
from typing import Iterator

from ..errors import CloudReadError, CloudWriteError, M3C2Error

__all__ = ["library_message", "read_errors", "write_errors"]

# What malformed input makes numpy, laspy (LaspyException), lazrs (LazrsError is a RuntimeError),
# pye57 (E57Exception) and our own parsers raise. TypeError/AttributeError are left alone on
# purpose: they mean a bug here, not a bad file.
_INPUT_ERRORS: tuple[type[BaseException], ...] = (
    ValueError, OSError, EOFError, struct.error, RuntimeError, LookupError, ArithmeticError,
    BufferError, MemoryError,
)
try:
    import laspy

    _INPUT_ERRORS += (laspy.LaspyException,)
except ImportError:  # laspy is a dependency, but a missing one must not break the other formats
    pass
try:
    import pye57

    _INPUT_ERRORS += (pye57.libe57.E57Exception,)
except ImportError:
    pass


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
def read_errors(path: object) -> Iterator[None]:
    """Re-raises a library exception from the body as ``CloudReadError(f"{path}: {message}")``."""
    try:
        yield
    except M3C2Error:
        raise
    except _INPUT_ERRORS as e:
        raise CloudReadError(f"{path}: {library_message(e)}") from e
    except BaseException as e:
        if _is_rust_panic(e):
            raise CloudReadError(f"{path}: corrupt or unsupported data ({library_message(e)})") from e
        raise


@contextmanager
def write_errors(path: object) -> Iterator[None]:
    """Re-raises a library exception from the body as ``CloudWriteError(f"{path}: {message}")``."""
    try:
        yield
    except M3C2Error:
        raise
    except _INPUT_ERRORS as e:
        raise CloudWriteError(f"{path}: {library_message(e)}") from e
    except BaseException as e:
        if _is_rust_panic(e):
            raise CloudWriteError(f"{path}: {library_message(e)}") from e
        raise
