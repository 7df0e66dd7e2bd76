"""The checks every run makes on its inputs before any work, in every mode: arrays of real
coordinates, thread counts, subsampling spacings and the spatial index's coordinate range (the
engine's limits, m3c2kit.engine)."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .. import engine
from ..base.errors import CloudReadError, UsageError
from ..io.arrays import as_coordinates, bounds
from ..settings.table import by_name

def as_points(name: str, values) -> np.ndarray:
    """(N, 3) float64 C-contiguous view of `values` (no copy when it already is one); only real
    numbers (io.arrays.as_coordinates: bool, complex, datetime, strings are refused)."""
    return as_coordinates(name, values)


def threads_count(threads) -> int:
    """--threads as the engine's int: 0 (all hardware threads) or a positive count."""
    p = by_name()["threads"]
    return p.kind(p.flag, 0 if threads is None else threads)


def check_spacing(name: str, spacing: float, *clouds) -> float:
    """`spacing`, or a UsageError naming the option when a cloud's extent spans more than the
    engine's subsampling grid allows (engine.MAX_CELLS_PER_AXIS spacings on an axis, docs/errors.md)."""
    for cloud in clouds:
        if len(cloud):
            lo, hi = bounds(cloud)
            extent = float(np.max(hi - lo))
            if not extent / spacing <= engine.MAX_CELLS_PER_AXIS:
                raise UsageError(f"{name} {spacing!r} is too small for clouds spanning {extent:.6g} on an axis "
                                 f"(at most 2**40 spacings); remove far outliers or use a larger spacing")
    return spacing


def check_coordinate_range(name: str, source, points: np.ndarray, limit: float) -> None:
    """The engine's spatial index keys coordinates below `limit` in magnitude (2**40 cells of a
    grid that follows the smallest diameter, docs/errors.md): a far outlier, or coordinates far
    from any local origin, is refused naming the file when there is one (exit 1), else the array."""
    if len(points) == 0:
        return
    worst = max(float(points.max()), -float(points.min()))  # no |points| temporary
    if worst < limit or not math.isfinite(worst):
        return  # non-finite coordinates: the engine counts and names them first
    message = (f"a coordinate ({worst:.6g}) lies beyond +-{limit:.6g}, the range of the spatial index for these "
               f"scales; remove far outliers or shift the coordinates to a local origin")
    path = getattr(source, "path", None)
    if path is not None:
        raise CloudReadError(f"{path}: {message}")
    raise UsageError(f"the {name} cloud: {message}")


def check_moved_range(shared: dict, points: np.ndarray, limit: float) -> None:
    """M3C2-EP moves the compared cloud by --transform inside the engine: a translation of 1e300
    was reported as a far coordinate of the compared FILE (hostile round 2). The moved bounding
    box's corners bound every moved point (the motion is affine)."""
    from .uncertainty_inputs import moved_compared
    if len(points) == 0 or "transform" not in shared or shared.get("transform_applied"):
        return
    lo, hi = points.min(axis=0), points.max(axis=0)
    corners = np.array([[(lo, hi)[(k >> a) & 1][a] for a in range(3)] for k in range(8)])
    with np.errstate(over="ignore", invalid="ignore"):
        worst = float(np.max(np.abs(moved_compared(shared, corners))))
    if not worst < limit:
        raise UsageError(f"--transform moves the compared cloud to a coordinate ({worst:.6g}) beyond +-{limit:.6g}, "
                         f"the range of the spatial index for these scales: check its translation and "
                         f"--reduction-point (or give --transform-applied when the cloud is already moved)")


def check_core_normals(values, core_normals, name: str = "core_normals") -> None:
    """Given normals are used only by --normal-source core (the other sources fit or impose their
    own): given with another source they would change nothing, a usage error naming `name`."""
    if core_normals is not None and values.get("normal_source") != "core":
        raise UsageError(f"{name} would change nothing in this run: it applies only with --normal-source core "
                         f"(this run's: --normal-source {values.get('normal_source') or by_name()['normal_source'].default_for()})")


def check_all_fields(output, all_fields) -> None:
    """--all-fields chooses the columns of a LAS/LAZ output only (text and PLY outputs have every
    column): with another output, or none, it would change nothing."""
    from ..io.registry import format_for  # noqa: PLC0415 - only runs given --all-fields need it

    if not all_fields:
        return
    fmt = format_for(Path(output), writing=True) if output is not None else None
    if output is None or (fmt is not None and not fmt.quantises):  # no format: the writer names the extension
        where = "no output file" if output is None else f"-o {output} is {fmt.name}, which has every column already"
        raise UsageError(f"--all-fields would change nothing in this run: it applies only to a LAS/LAZ output "
                         f"({where})")
