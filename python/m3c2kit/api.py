"""The Python API: M3C2 on numpy arrays. Parameter names are the command line's (with _ for -).

D (``normal_scale``) and d (``projection_scale``) are DIAMETERS, as in the paper and
CloudCompare; ``max_depth`` is the half-length of the cylinder along the normal.
"""
from __future__ import annotations

import math
from typing import Callable

import numpy as np

from . import diagnostics, engine, uncertainty_inputs
from .io.arrays import as_coordinates
from .errors import CloudReadError, M3C2Error, UsageError
from .io.guard import available_memory, format_bytes
from .result import Result
from .settings import build_params, engine_params, resolve  # build_params: the engine's Params for keywords
from .settings.parsers import positive
from .settings.table import by_name


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
            extent = float(np.max(cloud.max(axis=0) - cloud.min(axis=0)))
            if not extent / spacing <= engine.MAX_CELLS_PER_AXIS:
                raise UsageError(f"{name} {spacing!r} is too small for clouds spanning {extent:.6g} on an axis "
                                 f"(at most 2**40 spacings); remove far outliers or use a larger spacing")
    return spacing


def check_coordinate_range(name: str, source, points: np.ndarray, limit: float) -> None:
    """The engine's spatial index keys coordinates below `limit` in magnitude (2**41 cells of a
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


def core_points_for(reference: np.ndarray, core_points=None, core_spacing=None) -> np.ndarray:
    """The core points: given ones, the reference subsampled to a minimum spacing, or the reference."""
    if core_points is not None and core_spacing is not None:
        raise UsageError("give either core points (--core) or --core-spacing, not both")
    if core_points is not None:
        return as_points("core_points", core_points)
    if core_spacing is not None:
        spacing = check_spacing("--core-spacing", positive("--core-spacing", core_spacing), reference)
        kept = engine.subsample_min_spacing(reference, spacing, "--core-spacing")
        return reference[kept]
    return reference


#: Keywords of compare() besides the parameter table's (m3c2kit.settings.table).
_COMPARE_INPUTS = ("core_points", "core", "core_normals", "progress", "read_points")


def compare(reference, compared, core_points=None, *, core=None, core_normals=None,
            progress: Callable[[int, int], object] | None = None, read_points=None, **params) -> Result:
    """M3C2 distance, level of detection and significance at each core point, with the run's
    data-quality warnings (m3c2kit.diagnostics) emitted as M3C2Warning. Arguments: compare_quietly."""
    result, values = _compare(reference, compared, core_points, core=core, core_normals=core_normals,
                              progress=progress, read_points=read_points, **params)
    ref, cmp_ = as_points("reference", reference), as_points("compared", compared)
    diagnostics.warn(result, values, ref, cmp_)
    return result


def compare_quietly(reference, compared, core_points=None, **kwargs) -> Result:
    """compare() without the warnings: for runs made to diagnose another one (m3c2kit.quality)."""
    return _compare(reference, compared, core_points, **kwargs)[0]


def _compare(reference, compared, core_points=None, *, core=None, core_normals=None,
             progress: Callable[[int, int], object] | None = None, read_points=None, **params):
    """M3C2 distance, level of detection and significance at each core point.

    reference, compared, core_points (or ``core``, the command line's name): (N, 3) float64
    arrays (viewed without a copy when C-contiguous float64) or objects with an ``xyz``
    attribute such as m3c2kit.io.Cloud. core_points defaults to the reference itself, or to it
    subsampled with ``core_spacing``. The other keywords are the parameter table's
    (m3c2kit.settings.table, docs/cli.md), with the command line's names; an unknown one is a
    UsageError naming the closest valid one.
    """
    if core is not None and core_points is not None:
        raise UsageError("give core_points or core (the same parameter), not both")
    core_points = core if core_points is None else core_points
    values = resolve(params, "compare", api=True)
    sensor = getattr(reference if core_points is None else core_points, "scan_positions", None)
    reference, compared = _vegetation_removed(values, reference, compared)
    ref = as_points("reference", reference)
    cmp_ = as_points("compared", compared)
    for name, cloud in (("reference", ref), ("compared", cmp_)):
        if len(cloud) == 0:
            raise UsageError(f"the {name} cloud is empty (0 points)")
    core_xyz = core_points_for(ref, core_points, values["core_spacing"])
    if len(core_xyz) == 0:
        raise UsageError("core_points is empty: there is nothing to compute")
    engine_p = engine_params(values, "compare", read_points, core_points=core_xyz, scan_positions=sensor)
    check_memory(len(ref), len(cmp_), len(core_xyz))
    if values["normal_subsample"] is not None:
        check_spacing("--normal-subsample", values["normal_subsample"], ref, cmp_)
    limit = engine.max_abs_coordinate(engine_p)
    check_coordinate_range("reference", reference, ref, limit)
    check_coordinate_range("compared", compared, cmp_, limit)

    normals = None
    if values["normal_source"] == "core":
        if core_normals is None:
            raise UsageError("--normal-source core needs core_normals (one normal per core point)")
        normals = as_points("core_normals", core_normals)
        if len(normals) != len(core_xyz):
            raise UsageError(f"core_normals has {len(normals)} rows for {len(core_xyz)} core points")
    # Per-point inputs of --uncertainty pm / ep from the clouds' fields (docs/algorithm.md §6.5).
    uncertainty = uncertainty_inputs.inputs_for(values, reference, compared)
    raw = engine.compute(ref, cmp_, core_xyz, engine_p, normals, threads=values["threads"], progress=progress,
                         **uncertainty)
    return Result.from_engine(core_xyz, raw, run_record(params, engine_p)), values


def _vegetation_removed(values: dict, reference, compared):
    """--classifier FILE --keep CLASS: both clouds reduced to the points classified as a kept class
    (section 4.3, CANUPO; m3c2kit.classify), each classified with its own neighbourhoods."""
    if (values["classifier"] is None) != (values["keep"] is None):
        raise UsageError("--classifier and --keep go together: the classifier's classes to keep, e.g. "
                         "--classifier veg.json --keep ground")
    if values["classifier"] is None:
        return reference, compared
    from .classify import filtered, read_classifier
    clf = read_classifier(values["classifier"])
    keep = [k.strip() for k in str(values["keep"]).split(",") if k.strip()]
    return tuple(filtered(clf, cloud, keep, name, threads=values["threads"])
                 for name, cloud in (("reference", reference), ("compared", compared)))


def run_record(given: dict, engine_p) -> dict:
    """The parameters a Result records (its report shows them): those given, with D as a list."""
    return dict({k: v for k, v in given.items() if k != "threads"}, normal_scale=list(engine_p.normal_diameters))


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


class InsufficientMemory(M3C2Error):
    """A run would need more memory than is available (exit status 1)."""


#: Memory model of a run (the input arrays are already in memory): the engine's spatial index
#: takes about (24 + 4) bytes per point of each cloud (a float64 copy of the coordinates and a
#: uint32 index) plus a few percent of tree nodes, and the results about 120 bytes per core point.
INDEX_BYTES_PER_POINT = engine.INDEX_MEMORY["bytes_per_point"]
INDEX_OVERHEAD = engine.INDEX_MEMORY["overhead"]
RESULT_BYTES_PER_CORE_POINT = engine.INDEX_MEMORY["bytes_per_core_point"]


def estimate_memory(n_reference: int, n_compared: int, n_core: int) -> int:
    """Bytes a compare run allocates beyond its inputs (see INDEX_BYTES_PER_POINT)."""
    index = INDEX_BYTES_PER_POINT * INDEX_OVERHEAD * (int(n_reference) + int(n_compared))
    return int(index + RESULT_BYTES_PER_CORE_POINT * int(n_core))


def check_memory(n_reference: int, n_compared: int, n_core: int, available: int | None = None) -> int:
    """Raises InsufficientMemory when estimate_memory(...) exceeds `available` bytes (default:
    m3c2kit.io.guard.available_memory(), which honours $M3C2_AVAILABLE_MEMORY); returns the estimate."""
    needed = estimate_memory(n_reference, n_compared, n_core)
    available = available_memory() if available is None else available
    if available is not None and needed > available:
        raise InsufficientMemory(
            f"not enough memory: this run needs about {format_bytes(needed)} (spatial index of "
            f"{n_reference} + {n_compared} points, results for {n_core} core points) but only "
            f"{format_bytes(available)} is available; process the clouds in tiles (--tile-size S or "
            f"--memory-limit SIZE), or use fewer core points (--core-spacing, or a smaller --core file)")
    return needed
