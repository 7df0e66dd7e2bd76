"""The Python API: M3C2 on numpy arrays. Parameter names are the command line's (with _ for -).

D (``normal_scale``) and d (``projection_scale``) are DIAMETERS, as in the paper and
CloudCompare; ``max_depth`` is the half-length of the cylinder along the normal.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from . import diagnostics, engine
from .result import Result
from .errors import UsageError
from .run import in_memory
from .run.checks import as_points, check_coordinate_range, check_spacing, threads_count
from .run.cores import core_points_for
from .run.memory import InsufficientMemory, check_memory, estimate_memory
from .run.plan import run_record
from .settings import build_params, engine_params, resolve  # build_params: the engine's Params for keywords
from .settings.parsers import positive

__all__ = ["compare", "compare_quietly", "normals", "subsample", "as_points", "threads_count", "check_spacing",
           "check_coordinate_range", "core_points_for", "run_record", "build_params", "InsufficientMemory",
           "estimate_memory", "check_memory"]

#: Keywords of compare() besides the parameter table's (m3c2kit.settings.table).
_COMPARE_INPUTS = ("core_points", "core", "core_normals", "progress", "read_points")


def compare(reference, compared, core_points=None, *, core=None, core_normals=None,
            progress: Callable[[int, int], object] | None = None, read_points=None, reorder_inputs: bool = False,
            **params) -> Result:
    """M3C2 distance, level of detection and significance at each core point, with the run's
    data-quality warnings (m3c2kit.diagnostics) emitted as M3C2Warning.

    reference, compared, core_points (or ``core``, the command line's name): (N, 3) float64
    arrays (viewed without a copy when C-contiguous float64) or objects with an ``xyz``
    attribute such as m3c2kit.io.Cloud. core_points defaults to the reference itself, or to it
    subsampled with ``core_spacing``. The other keywords are the parameter table's
    (m3c2kit.settings.table, docs/cli.md), with the command line's names; an unknown one is a
    UsageError naming the closest valid one. The run is m3c2kit.run's plan executed in memory
    (m3c2kit.run.run_tiled executes the same plan in tiles, with the same bits).

    reorder_inputs: True lets the engine order the two clouds' coordinate arrays in place during
    the call instead of copying them (24 bytes per point less at the peak; about 0.1 s per
    million points more); every row is back in its place when the call returns or raises. Only
    for arrays nothing else reads during the call; read-only arrays, and runs that read a cloud
    in input order (normal subsampling, uncertainty pm / ep), are copied as without it. The
    results are the same bits. The command line passes it for the clouds it read.
    """
    result, values, given = _compare(reference, compared, core_points, core=core, core_normals=core_normals,
                                     progress=progress, read_points=read_points, reorder_inputs=reorder_inputs,
                                     **params)
    diagnostics.warn(result, values, *(as_points(n, c) for n, c in zip(("reference", "compared"), given)))
    return result


def compare_quietly(reference, compared, core_points=None, **kwargs) -> Result:
    """compare() without the warnings: for runs made to diagnose another one (m3c2kit.quality)."""
    return _compare(reference, compared, core_points, **kwargs)[0]


def _compare(reference, compared, core_points=None, *, core=None, **kwargs):
    if core is not None and core_points is not None:
        raise UsageError("give core_points or core (the same parameter), not both")
    core_points = core if core_points is None else core_points
    return in_memory.compare(reference, compared, core_points, **kwargs)


def normals(cloud, core_points=None, *, progress=None, read_points=None, **params) -> dict:
    """Normals at the most planar scale (section 3.2, 6.3) of any cloud, oriented, with roughness.
    Keywords: the parameter table's that `m3c2 normals` takes (normal_scale, orient, ...)."""
    values = resolve(params, "normals")
    pts = as_points("cloud", cloud)
    core = pts if core_points is None else as_points("core_points", core_points)
    sensor = getattr(cloud if core_points is None else core_points, "scan_positions", None)
    p = engine_params(values, "normals", read_points, core_points=core, scan_positions=sensor)
    out = engine.compute_normals(pts, core, p, threads=values["threads"], progress=progress)
    out["core"] = core
    return out


def subsample(points, spacing: float) -> np.ndarray:
    """Indices of points kept with no two closer than `spacing` (greedy in input order)."""
    pts = as_points("points", points)
    spacing = check_spacing("--spacing", positive("--spacing", spacing), pts)
    return engine.subsample_min_spacing(pts, spacing, "--spacing")


