"""How many threads decode and encode LAZ: the run's ``--threads``, never more (issue 19).

laspy's lazrs backend compresses and decompresses LAZ chunks in parallel (LazBackend.LazrsParallel)
on Rust's rayon thread pool, or on the calling thread (LazBackend.Lazrs). Both write the same bytes
and read the same points (tests/python/io/test_io_laz_threads.py): chunks are coded independently
either way. The pool is created once per process, on its first use, with RAYON_NUM_THREADS threads
(all cores when unset), so the limit is set before that first use and remembered; a later request
for fewer threads than the pool holds decodes serially rather than on more threads than asked.
A RAYON_NUM_THREADS the user set is their limit and is kept.
"""
from __future__ import annotations

import os

__all__ = ["set_threads", "backend", "threads"]

_ENV = "RAYON_NUM_THREADS"
_requested = 0  # 0: all cores (the engine's meaning of threads=0)
_pool: int | None = None  # threads of rayon's pool once this module has started it


def set_threads(n: int) -> None:
    """The LAZ thread limit for this process's following reads and writes (0: all cores)."""
    global _requested
    if n < 0:
        raise ValueError(f"threads must be >= 0, got {n}")
    _requested = int(n)


def threads() -> int:
    """The number of threads the next LAZ read or write may use (>= 1)."""
    return _requested or os.cpu_count() or 1


def _user_pool() -> int | None:
    value = os.environ.get(_ENV, "")
    return int(value) if value.isdigit() and int(value) > 0 else None


def backend():
    """The laspy LazBackend for the next LAZ read or write (None: lazrs is missing, laspy picks)."""
    import laspy

    global _pool
    if not laspy.LazBackend.Lazrs.is_available():
        return None
    wanted = threads()
    if _pool is None:
        _pool = _user_pool()
    if _pool is None and wanted > 1:
        os.environ[_ENV] = str(wanted)  # read by rayon when the parallel coder first runs
        _pool = wanted
    if wanted > 1 and _pool is not None and _pool <= wanted:
        return laspy.LazBackend.LazrsParallel
    return laspy.LazBackend.Lazrs
