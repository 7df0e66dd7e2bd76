"""py4dgeo's helpers (py4dgeo 1.2.0's util.py, logger.py and segmentation.regular_corepoint_grid):
the thread count, the log file, a regular grid of core points."""
from __future__ import annotations

import logging
from collections.abc import Sequence

import numpy as np

from ...base.errors import UsageError
from .errors import LOGGER, Py4DGeoError, translated  # noqa: F401 - py4dgeo.util.Py4DGeoError, where py4dgeo has it

__all__ = ["Py4DGeoError", "set_num_threads", "get_num_threads", "set_py4dgeo_logfile", "regular_corepoint_grid"]

_THREADS = 0  # 0: all hardware threads, like py4dgeo's default


@translated
def set_num_threads(num_threads: int) -> None:
    """Threads for later runs (py4dgeo's ``set_num_threads``); 0 means all hardware threads."""
    global _THREADS
    n = int(num_threads)
    if n < 0:
        raise UsageError(f"set_num_threads: the thread count must be >= 0, got {num_threads!r}")
    _THREADS = n


def get_num_threads() -> int:
    """The thread count set by :func:`set_num_threads` (0: all hardware threads)."""
    return _THREADS


def set_py4dgeo_logfile(filename) -> None:
    """py4dgeo's ``set_py4dgeo_logfile``: the "py4dgeo" logger (every Py4DGeoError's message)
    also writes to `filename`, replacing the file set before."""
    logger = logging.getLogger(LOGGER)
    for handler in [h for h in logger.handlers if getattr(h, "_m3c2kit_logfile", False)]:
        logger.removeHandler(handler)
        handler.close()
    handler = logging.FileHandler(filename, mode="a", delay=True)  # created by the first record, as py4dgeo's
    handler._m3c2kit_logfile = True
    handler.setFormatter(logging.Formatter("[%(asctime)s][%(levelname)s] %(message)s"))
    logger.addHandler(handler)
    logger.setLevel(min(logger.level or logging.INFO, logging.INFO))


@translated
def regular_corepoint_grid(lowerleft: Sequence[float], upperright: Sequence[float], num_points: Sequence[int],
                           zval: float = 0.0) -> np.ndarray:
    """py4dgeo's ``regular_corepoint_grid``: num_points[0] x num_points[1] core points evenly
    spaced from `lowerleft` to `upperright` (both included), x outer and y inner, at z = zval.
    py4dgeo 1.2.0 indexes row i * num_points[0] + j, which leaves rows unset (uninitialised
    memory) and overwrites others when the two counts differ; here every row is one grid point."""
    try:
        nx, ny = (int(n) for n in num_points)
    except (TypeError, ValueError):
        raise UsageError(f"regular_corepoint_grid: num_points must be two counts, got {num_points!r}") from None
    if nx < 1 or ny < 1:
        raise UsageError(f"regular_corepoint_grid: num_points must be >= 1 each, got {num_points!r}")
    xs = np.linspace(lowerleft[0], upperright[0], num=nx, dtype=np.float64)
    ys = np.linspace(lowerleft[1], upperright[1], num=ny, dtype=np.float64)
    grid = np.empty((nx * ny, 3))
    grid[:, 0], grid[:, 1], grid[:, 2] = np.repeat(xs, ny), np.tile(ys, nx), float(zval)
    return grid
