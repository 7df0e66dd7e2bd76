"""The series' engine calls, through the engine facade (m3c2kit.engine); the engine's Params of a
series are those of `m3c2 compare` (series.parameters)."""
from __future__ import annotations

import numpy as np

from ..run.checks import check_coordinate_range, threads_count
from .. import engine as facade
from ..base.errors import UsageError


class Comparison:
    """The reference's index and the core normals, kept to compare epochs one at a time
    (include/m3c2/series.hpp): each result equals m3c2kit.compare(reference, epoch, core) bit for
    bit. `params`: the engine's Params of the series (series.parameters.engine_params)."""

    def __init__(self, reference: np.ndarray, core: np.ndarray, params, core_normals=None, threads: int = 0):
        self._limit = facade.max_abs_coordinate(params)
        check_coordinate_range("reference", None, reference, self._limit)
        normals = None if core_normals is None else np.ascontiguousarray(core_normals, dtype=np.float64)
        self._impl = facade.Comparison(reference, core, params, normals, threads=threads_count(threads))

    def compare(self, compared: np.ndarray, source=None, threads: int = 0) -> dict:
        """Raw engine result of one epoch (the arrays of the engine's compute)."""
        if len(compared) == 0:
            raise UsageError(f"the epoch {getattr(source, 'path', '')} is empty (0 points)")
        check_coordinate_range("compared", source, compared, self._limit)
        return self._impl.compare(compared, threads=threads_count(threads))

    def normals(self) -> dict:
        return self._impl.normals()


def temporal_median(values: np.ndarray, window: int, threads: int = 0) -> np.ndarray:
    return facade.temporal_median(np.ascontiguousarray(values, dtype=np.float64), int(window),
                                  threads=threads_count(threads))


def change_points(series: np.ndarray, width: int, min_size: int, jump: int, penalty: float) -> np.ndarray:
    return facade.change_points(np.ascontiguousarray(series, dtype=np.float64), int(width), int(min_size), int(jump),
                                float(penalty))


def objects_params(**kw):
    return facade.objects_params(**kw)


def objects_by_change(distances: np.ndarray, core: np.ndarray, params, threads: int = 0, progress=None) -> dict:
    return facade.objects_by_change(np.ascontiguousarray(distances, dtype=np.float64),
                                    np.ascontiguousarray(core, dtype=np.float64), params,
                                    threads=threads_count(threads), progress=progress)
