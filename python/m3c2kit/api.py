"""The Python API: M3C2 on numpy arrays. Parameter names are the command line's (with _ for -).

D (``normal_scale``) and d (``projection_scale``) are DIAMETERS, as in the paper and
CloudCompare; ``max_depth`` is the half-length of the cylinder along the normal.
"""
from __future__ import annotations

import math
from typing import Callable

import numpy as np

from . import _core
from .errors import CloudReadError, M3C2Error, UsageError
from .io.guard import available_memory, format_bytes
from .options import non_negative, normal_scales, orientation, positive
from .result import Result

NORMAL_SOURCES = ("reference", "compared", "mean", "vertical", "horizontal", "core")
DEPTH_SEARCHES = ("single", "two-pass", "progressive")

#: What --compat cloudcompare changes when the caller does not say otherwise (docs/validation.md).
CLOUDCOMPARE_DEFAULTS = {"variance": "population", "scale_selection": "cloudcompare",
                         "depth_search": "progressive", "min_points": 5}
DEFAULTS = {"variance": "sample", "scale_selection": "most-planar", "depth_search": "single", "min_points": 4}


def as_points(name: str, values) -> np.ndarray:
    """(N, 3) float64 C-contiguous view of `values` (no copy when it already is one)."""
    xyz = getattr(values, "xyz", values)
    arr = np.asarray(xyz, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise UsageError(f"{name} must be an (N, 3) array of coordinates, got shape {arr.shape}")
    return np.ascontiguousarray(arr)


def _choice(name: str, value: str, allowed) -> str:
    if value not in allowed:
        raise UsageError(f"{name} must be one of {', '.join(allowed)}, got {value!r}")
    return value


def build_params(*, normal_scale=None, projection_scale, max_depth, registration_error=0.0, orient="+z",
                 normal_source="reference", median=False, confidence=0.95, min_points=None,
                 t_statistic=False, bootstrap=0, seed=0, normal_subsample=None, depth_search=None,
                 first_pass_depth=None, positive_search_only=False, compat=None, variance=None,
                 scale_selection=None, min_points_normal=3, read_points=None) -> _core.Params:
    """Validates the user's parameters and turns them into the engine's."""
    if compat not in (None, "cloudcompare"):
        raise UsageError(f"--compat must be 'cloudcompare', got {compat!r}")
    defaults = CLOUDCOMPARE_DEFAULTS if compat == "cloudcompare" else DEFAULTS
    variance = variance or defaults["variance"]
    scale_selection = scale_selection or defaults["scale_selection"]
    if depth_search is None:
        depth_search = "two-pass" if first_pass_depth is not None else defaults["depth_search"]
    min_points = defaults["min_points"] if min_points is None else min_points

    p = _core.Params()
    p.normal_source = getattr(_core.NormalSource, _choice("--normal-source", normal_source, NORMAL_SOURCES))
    if normal_scale is not None:
        p.normal_diameters = normal_scales(normal_scale)
    elif normal_source not in ("vertical", "core"):
        raise UsageError("--normal-scale (D, a diameter) is required unless --normal-source is vertical or core")
    p.scale_selection = getattr(_core.ScaleSelection, _choice(
        "scale_selection", scale_selection, ("most-planar", "cloudcompare")).replace("-", "_"))
    p.min_points_normal = int(min_points_normal)
    if normal_subsample is not None:
        p.normal_subsample_spacing = positive("--normal-subsample", normal_subsample)
    direction, points = orientation(orient, read_points)
    p.orientation_direction = list(direction)
    p.orientation_points = points.ravel().tolist()

    p.projection_diameter = positive("--projection-scale", projection_scale)
    p.max_depth = positive("--max-depth", max_depth)
    p.depth_search = getattr(_core.DepthSearch, _choice("--depth-search", depth_search, DEPTH_SEARCHES).replace("-", "_"))
    if depth_search == "two-pass":
        if first_pass_depth is None:
            raise UsageError("--depth-search two-pass needs --first-pass-depth")
        p.first_pass_depth = positive("--first-pass-depth", first_pass_depth)
        if p.first_pass_depth > p.max_depth:
            raise UsageError(f"--first-pass-depth ({first_pass_depth}) must not exceed --max-depth ({max_depth})")
    p.positive_search_only = bool(positive_search_only)
    p.statistic = _core.Statistic.median if median else _core.Statistic.mean
    p.variance = getattr(_core.Variance, _choice("variance", variance, ("sample", "population")))

    p.registration_error = non_negative("--registration-error", registration_error)
    conf = float(confidence)
    if not 0.0 < conf < 1.0:
        raise UsageError(f"--confidence must be in (0, 1), got {confidence!r}")
    p.confidence = conf
    p.min_points = _integer("--min-points", min_points, 1, UINT32_MAX, "an integer >= 1")
    p.t_statistic = bool(t_statistic)
    bootstrap = _integer("--bootstrap", bootstrap, 0, UINT32_MAX, "0 (off) or >= 2 resamples")
    if bootstrap == 1:
        raise UsageError(f"--bootstrap must be 0 (off) or >= 2 resamples, got {bootstrap!r}")
    p.bootstrap_samples = bootstrap
    p.bootstrap_seed = _integer("--seed", seed, 0, 2**64 - 1, "a non-negative integer")
    return p


UINT32_MAX = 2**32 - 1


def _integer(name: str, value, lo: int, hi: int, rule: str) -> int:
    """`value` as an int in [lo, hi] (the engine's field width), or a UsageError naming the option."""
    try:
        v = int(value)
        exact = v == float(value)
    except (TypeError, ValueError, OverflowError):
        raise UsageError(f"{name} must be {rule}, got {value!r}") from None
    if not exact or not lo <= v <= hi:
        if exact and v > hi:
            rule = f"{rule}, at most {hi}"
        raise UsageError(f"{name} must be {rule}, got {value!r}")
    return v


def threads_count(threads) -> int:
    """--threads as the engine's int: 0 (all hardware threads) or a positive count."""
    return _integer("--threads", 0 if threads is None else threads, 0, 2**31 - 1, "0 (all) or a positive integer")


#: The engine's subsampling hashes (p - first point) / spacing as 64-bit integers per axis.
MAX_CELLS_PER_AXIS = 2.0**62


def check_spacing(name: str, spacing: float, *clouds) -> float:
    """`spacing`, or a UsageError when a cloud spans more than 2**62 spacings on an axis (the
    engine's subsampling grid index would overflow: docs/errors.md)."""
    for cloud in clouds:
        if len(cloud):
            extent = float(np.max(np.abs(cloud - cloud[0])))
            if extent / spacing >= MAX_CELLS_PER_AXIS:
                raise UsageError(f"{name} {spacing!r} is too small for clouds spanning {extent:.6g} on an axis "
                                 f"(at most 2**62 spacings); remove far outliers or use a larger spacing")
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
        kept = _core.subsample_min_spacing(reference, spacing)
        return reference[kept]
    return reference


def compare(reference, compared, core_points=None, *, normal_scale=None, projection_scale, max_depth,
            core_spacing=None, core_normals=None, threads: int = 0,
            progress: Callable[[int, int], object] | None = None, **params) -> Result:
    """M3C2 distance, level of detection and significance at each core point.

    reference, compared, core_points: (N, 3) float64 arrays (viewed without a copy when
    C-contiguous float64) or objects with an ``xyz`` attribute such as m3c2kit.io.Cloud.
    core_points defaults to the reference itself, or to it subsampled with ``core_spacing``.
    Other keyword parameters: see build_params and docs/python.md.
    """
    ref = as_points("reference", reference)
    cmp_ = as_points("compared", compared)
    for name, cloud in (("reference", ref), ("compared", cmp_)):
        if len(cloud) == 0:
            raise UsageError(f"the {name} cloud is empty (0 points)")
    core = core_points_for(ref, core_points, core_spacing)
    if len(core) == 0:
        raise UsageError("core_points is empty: there is nothing to compute")
    engine_params = build_params(normal_scale=normal_scale, projection_scale=projection_scale,
                                 max_depth=max_depth, **params)
    check_memory(len(ref), len(cmp_), len(core))
    if params.get("normal_subsample") is not None:
        check_spacing("--normal-subsample", engine_params.normal_subsample_spacing, ref, cmp_)
    limit = _core.max_abs_coordinate(engine_params)
    check_coordinate_range("reference", reference, ref, limit)
    check_coordinate_range("compared", compared, cmp_, limit)

    normals = None
    if params.get("normal_source") == "core":
        if core_normals is None:
            raise UsageError("--normal-source core needs core_normals (one normal per core point)")
        normals = as_points("core_normals", core_normals)
        if len(normals) != len(core):
            raise UsageError(f"core_normals has {len(normals)} rows for {len(core)} core points")
    raw = _engine_call(_core.compute, ref, cmp_, core, engine_params, normals, threads=threads_count(threads),
                       progress=progress)
    params.pop("read_points", None)
    record = dict(params, normal_scale=list(engine_params.normal_diameters), projection_scale=projection_scale,
                  max_depth=max_depth)
    return Result.from_engine(core, raw, record)


def normals(cloud, core_points=None, *, normal_scale, orient="+z", normal_subsample=None, variance="sample",
            scale_selection="most-planar", threads: int = 0, progress=None, read_points=None) -> dict:
    """Normals at the most planar scale (section 3.2, 6.3) of any cloud, oriented, with roughness."""
    pts = as_points("cloud", cloud)
    core = pts if core_points is None else as_points("core_points", core_points)
    p = build_params(normal_scale=normal_scale, projection_scale=1.0, max_depth=1.0, orient=orient,
                     normal_subsample=normal_subsample, variance=variance, scale_selection=scale_selection,
                     read_points=read_points)
    out = _engine_call(_core.compute_normals, pts, core, p, threads=threads_count(threads), progress=progress)
    out["core"] = core
    return out


def subsample(points, spacing: float) -> np.ndarray:
    """Indices of points kept with no two closer than `spacing` (greedy in input order)."""
    pts = as_points("points", points)
    return _core.subsample_min_spacing(pts, check_spacing("--spacing", positive("--spacing", spacing), pts))


class InsufficientMemory(M3C2Error):
    """A run would need more memory than is available (exit status 1)."""


#: Memory model of a run (the input arrays are already in memory): the engine's spatial index
#: takes about (24 + 4) bytes per point of each cloud (a float64 copy of the coordinates and a
#: uint32 index) plus a few percent of tree nodes, and the results about 120 bytes per core point.
INDEX_BYTES_PER_POINT = 24 + 4
INDEX_OVERHEAD = 1.05
RESULT_BYTES_PER_CORE_POINT = 120


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


def _engine_call(fn, *args, **kwargs):
    try:
        return fn(*args, **kwargs)
    except ValueError as e:  # the engine's InvalidArgument
        raise UsageError(str(e)) from None
