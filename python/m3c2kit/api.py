"""The Python API: M3C2 on numpy arrays. Parameter names are the command line's (with _ for -).

D (``normal_scale``) and d (``projection_scale``) are DIAMETERS, as in the paper and
CloudCompare; ``max_depth`` is the half-length of the cylinder along the normal.
"""
from __future__ import annotations

from typing import Callable

from .classify.vegetation import vegetation_filter
from .engine.result import Result
from .run import in_memory


def compare(reference, compared, core_points=None, *, core=None, core_normals=None,
            progress: Callable[[int, int], object] | None = None, read_points=None, reorder_inputs: bool = False,
            **params) -> Result:
    """M3C2 distance, level of detection and significance at each core point, with the run's
    data-quality warnings (m3c2kit.run.diagnostics) emitted as M3C2Warning.

    reference, compared, core_points (or ``core``, the command line's name): (N, 3) float64
    arrays (viewed without a copy when C-contiguous float64) or objects with an ``xyz``
    attribute such as m3c2kit.io.Cloud. core_points defaults to the reference itself, or to it
    subsampled with ``core_spacing``. The other keywords are the parameter table's
    (m3c2kit.settings.table, docs/cli.md), with the command line's names; an unknown one is a
    UsageError naming the closest valid one. The run is m3c2kit.run's plan executed in memory
    (m3c2kit.run.tiled.run_tiled executes the same plan in tiles, with the same bits);
    ``classifier`` and ``keep`` become its vegetation filter (m3c2kit.classify.vegetation).

    reorder_inputs: True lets the engine order the two clouds' coordinate arrays in place during
    the call instead of copying them (24 bytes per point less at the peak; about 0.1 s per
    million points more); every row is back in its place when the call returns or raises. Only
    for arrays nothing else reads during the call; read-only arrays, and runs that read a cloud
    in input order (normal subsampling, uncertainty pm / ep), are copied as without it. The
    results are the same bits. The command line passes it for the clouds it read.
    """
    vegetation = vegetation_filter(params.get("classifier"), params.get("keep"))
    return in_memory.compare(reference, compared, core_points, core=core, core_normals=core_normals,
                             vegetation=vegetation, progress=progress, read_points=read_points,
                             reorder_inputs=reorder_inputs, stacklevel=3, **params)
