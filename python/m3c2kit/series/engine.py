"""The series' calls into the engine (m3c2kit._core), in one place so that they move to the
engine facade with the rest of the front end."""
from __future__ import annotations

import numpy as np

from .. import _core, api
from ..errors import UsageError


def _engine_call(fn, *args, **kwargs):
    try:
        return fn(*args, **kwargs)
    except ValueError as e:  # the engine's InvalidArgument
        raise UsageError(str(e)) from None


def build_params(settings: dict):
    """The engine's Params from a series' compare settings (the keywords of api.build_params)."""
    return api.build_params(**settings)


class Comparison:
    """The reference's index and the core normals, kept to compare epochs one at a time
    (include/m3c2/series.hpp): each result equals api.compare(reference, epoch, core) bit for bit."""

    def __init__(self, reference: np.ndarray, core: np.ndarray, settings: dict, core_normals=None,
                 threads: int = 0):
        params = build_params(settings)
        self._params_record = settings
        self._limit = _core.max_abs_coordinate(params)
        api.check_coordinate_range("reference", None, reference, self._limit)
        self._impl = _engine_call(_core.Comparison, reference, core, params, core_normals,
                                  threads=api.threads_count(threads))

    def compare(self, compared: np.ndarray, source=None, threads: int = 0) -> dict:
        """Raw engine result of one epoch (the arrays of _core.compute)."""
        if len(compared) == 0:
            raise UsageError(f"the epoch {getattr(source, 'path', '')} is empty (0 points)")
        api.check_coordinate_range("compared", source, compared, self._limit)
        return _engine_call(self._impl.compare, compared, threads=api.threads_count(threads))

    def normals(self) -> dict:
        return self._impl.normals()


def temporal_median(values: np.ndarray, window: int, threads: int = 0) -> np.ndarray:
    return _engine_call(_core.temporal_median, np.ascontiguousarray(values, dtype=np.float64), int(window),
                        threads=api.threads_count(threads))


def change_points(series: np.ndarray, width: int, min_size: int, jump: int, penalty: float) -> np.ndarray:
    return _engine_call(_core.change_points, np.ascontiguousarray(series, dtype=np.float64), int(width),
                        int(min_size), int(jump), float(penalty))


def objects_params(**kw):
    p = _core.ObjectsParams()
    for name, value in kw.items():
        if value is not None:
            setattr(p, name, value)
    return p


def objects_by_change(distances: np.ndarray, core: np.ndarray, params, threads: int = 0, progress=None) -> dict:
    return _engine_call(_core.objects_by_change, np.ascontiguousarray(distances, dtype=np.float64),
                        np.ascontiguousarray(core, dtype=np.float64), params, threads=api.threads_count(threads),
                        progress=progress)
