"""The engine facade: the ONLY module that imports the C++ binding ``m3c2kit._core``.

Every engine call goes through a function here, and every engine error is translated once
(:func:`translated`): the engine's InvalidArgument (a ValueError in Python) and nanobind's
TypeError for a value its C++ type cannot hold become :class:`~m3c2kit.base.errors.UsageError`, a run
stopped by the progress callback becomes :class:`~m3c2kit.base.errors.Cancelled`. Geometry the front
end needs before a run (a tile's halo, the index memory per point, the coordinate range of the
spatial index, the largest subsampling grid) comes from the engine, never re-derived in Python.

Engine parameters travel as plain values keyed by the C++ field names (:data:`PARAM_FIELDS`);
enum fields take the enum member's name (``"two_pass"``). See docs/architecture.md.
"""
from __future__ import annotations

import enum
import math
from contextlib import contextmanager
from typing import Callable, Iterator

import numpy as np

from .. import _core
from ..base import fault_hook
from ..base.errors import Cancelled, UsageError

__all__ = ["PARAM_FIELDS", "RESULT_FIELDS", "OPTIONAL_RESULT_FIELDS", "STATUS_NAMES", "MAX_CELLS_PER_AXIS", "MAX_BOOTSTRAP_SAMPLES", "INDEX_MEMORY", "Params",
           "translated", "make_params", "default_fields", "params_fields", "compute", "compute_normals",
           "subsample_min_spacing", "match_rows", "CylinderIndex", "grid_core_points", "roughness_by_scale", "variogram_pairs", "component_values", "region_covariance_sum", "dimensionality", "c2c", "max_abs_coordinate",
           "neighbourhood_reach", "tile_halo", "fdr_q_values"]

Params = _core.Params
#: Fields of the engine's Params, in the struct's order (include/m3c2/params.hpp visit_param_fields).
PARAM_FIELDS: tuple[str, ...] = tuple(_core.PARAM_FIELDS)
#: Per-core-point arrays of the engine's Result (include/m3c2/result.hpp visit_result_fields),
#: always present, and those present only when a parameter asks for them (uncertainty models).
RESULT_FIELDS: tuple[str, ...] = tuple(_core.RESULT_FIELDS)
OPTIONAL_RESULT_FIELDS: tuple[str, ...] = tuple(_core.OPTIONAL_RESULT_FIELDS)
#: Reason codes of the `status` column, by code.
STATUS_NAMES: tuple[str, ...] = tuple(_core.status_names())
#: Most cells along an axis of the subsampling and 2D grids (extent / cell).
MAX_CELLS_PER_AXIS: float = float(_core.MAX_CELLS_PER_AXIS)
#: Bootstrap resamples per core point the engine accepts (m3c2::kMaxBootstrapSamples, params.hpp).
MAX_BOOTSTRAP_SAMPLES: int = int(_core.MAX_BOOTSTRAP_SAMPLES)
#: What compute() allocates beyond its inputs (m3c2::IndexMemory): bytes_per_point (each cloud),
#: copy_bytes_per_point (each cloud copied, not ordered in place),
#: moments_bytes_per_point (each cloud whose normals are computed), overhead, bytes_per_core_point.
INDEX_MEMORY: dict = dict(_core.index_memory())


@contextmanager
def translated(option: str | None = None) -> Iterator[None]:
    """Runs an engine call, turning its errors into the package's: a bad argument is a
    UsageError (prefixed by `option`, the user's name for the value, when given), a cancelled run
    Cancelled. Python errors raised by a progress callback pass through unchanged."""
    try:
        yield
    except _core.Cancelled:
        raise Cancelled("computation cancelled by the progress callback") from None
    except (ValueError, TypeError) as e:
        message = _user_message(e)
        raise UsageError(f"{option}: {message}" if option else message) from None


#: nanobind's words for a value its C++ type cannot hold, and the C++ library's for an allocation
#: past max_size(): neither may reach a user (their text names the binding's signature or std::).
_BINDING_TYPE_ERROR = "incompatible function arguments"
_CPP_WORDS = ("std::", "max_size()", "vector::", "basic_string::", "_M_")  # libstdc++'s std::length_error texts


def _user_message(err: Exception) -> str:
    text = str(err)
    if isinstance(err, TypeError) and _BINDING_TYPE_ERROR in text:
        return ("a value the engine cannot take: integers must be >= 0 and below 2^32 (threads below 2^31), "
                "coordinates and lengths real numbers")
    if any(word in text for word in _CPP_WORDS):
        return "the sizes asked for are larger than any allocation can hold; use smaller counts or inputs"
    return text


#: The largest values the binding's integer types hold: the engine's std::uint32_t counts (points,
#: resamples, epochs) and its int thread count. Every check of a count against the engine is these.
COUNT_MAX = 2**32 - 1
THREADS_MAX = 2**31 - 1


def _count(name: str, value, high: int = COUNT_MAX) -> int:
    """`value` as an integer the binding's std::uint32_t takes, else a UsageError naming `name`
    (nanobind would raise a TypeError quoting its signature)."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not 0 <= int(value) <= high:
        raise UsageError(f"{name} must be an integer from 0 to {high}, got {value!r}")
    return int(value)


def _threads(value) -> int:
    return _count("threads", value, THREADS_MAX)


def _progress(progress):
    if progress is not None and not callable(progress):
        raise TypeError(f"progress must be a callable progress(done, total) or None, got {type(progress).__name__}")
    return progress


def _enum_type(name: str):
    value = getattr(_DEFAULT, name)
    return type(value) if isinstance(value, enum.Enum) else None


def make_params(fields: dict) -> _core.Params:
    """Engine Params from plain values keyed by field name (unknown names are a UsageError)."""
    p = _core.Params()
    for name, value in fields.items():
        if name not in PARAM_FIELDS:
            raise UsageError(f"the engine has no parameter {name!r}")
        kind = _enum_type(name)
        with translated(name):
            setattr(p, name, kind[value] if kind is not None and isinstance(value, str) else value)
    return p


def params_fields(p: _core.Params) -> dict:
    """Plain values of every field of `p` (enum fields by member name)."""
    out = {}
    for name in PARAM_FIELDS:
        value = getattr(p, name)
        out[name] = value.name if isinstance(value, enum.Enum) else value
    return out


def default_fields(struct: str = "Params") -> dict:
    """The engine's defaults, the one place every default of the front end comes from: those of
    Params (params.hpp) or of another bound parameter struct by name (ObjectsParams,
    Tam3c2Params, KalmanParams: the series steps' options); enum fields by member name."""
    if struct == "Params":
        return params_fields(_core.Params())
    defaults = getattr(_core, struct)()
    values = {name: getattr(defaults, name) for name in dir(defaults) if not name.startswith("_")}
    return {name: value.name if isinstance(value, enum.Enum) else value for name, value in values.items()}


def compute(reference: np.ndarray, compared: np.ndarray, core: np.ndarray, params: _core.Params,
            core_normals: np.ndarray | None = None, *, threads: int = 0,
            progress: Callable[[int, int], object] | None = None, order_in_place: bool = False,
            **uncertainty_inputs) -> dict:
    """M3C2 at each core point: a dict of RESULT_FIELDS arrays (and OPTIONAL_RESULT_FIELDS ones).
    `uncertainty_inputs`: the per-point inputs of params.uncertainty (m3c2kit.run.uncertainty_inputs).
    `order_in_place`: the engine may order the two clouds' arrays in place instead of copying
    them, every row back before it returns (RunOptions::order_clouds_in_place); taken only where
    both are writeable."""
    progress = _with_fault_checkpoint(_progress(progress))
    threads = _threads(threads)
    order_in_place = bool(order_in_place) and all(np.asarray(a).flags.writeable for a in (reference, compared))
    inputs = _bound_struct(_core.UncertaintyArrays, uncertainty_inputs)
    with translated():
        return _core.compute(reference, compared, core, params, core_normals, threads=threads, progress=progress,
                             uncertainty=inputs, order_in_place=order_in_place)


def _with_fault_checkpoint(progress):
    """The testing aid's "computing" phase (m3c2kit.base.fault_hook): at the first progress callback,
    inside the computation, or now when there is no callback. Unarmed: `progress` unchanged."""
    if not fault_hook.armed("computing"):
        return progress
    if progress is None:
        fault_hook.checkpoint("computing")
        return None

    def checked(done, total):
        fault_hook.checkpoint("computing")
        return progress(done, total)

    return checked


def compute_normals(cloud: np.ndarray, core: np.ndarray, params: _core.Params, *, threads: int = 0,
                    progress=None) -> dict:
    with translated():
        return _core.compute_normals(cloud, core, params, threads=_threads(threads), progress=_progress(progress))


def subsample_min_spacing(points: np.ndarray, spacing: float, option: str = "min_spacing") -> np.ndarray:
    """Indices of the points kept with no two closer than `spacing` (greedy in input order)."""
    with translated(option):
        return np.asarray(_core.subsample_min_spacing(points, spacing))


def match_rows(points: np.ndarray, queries: np.ndarray) -> np.ndarray | None:
    """For each row of `queries` ((m, 3)), the index of the first row of `points` ((n, 3)) equal to
    it as numbers (-0.0 equals 0.0, NaN equals nothing), or None when some query is no row
    (m3c2::match_rows: a table of the distinct queries and one pass over the points)."""
    as_rows = lambda a: np.ascontiguousarray(a, dtype=np.float64).reshape(-1, 3)  # noqa: E731
    with translated():
        return _core.match_rows(as_rows(points), as_rows(queries))


def grid_core_points(points: np.ndarray, cell: float, option: str = "cell") -> dict:
    with translated(option):
        return _core.grid_core_points(points, cell)


def roughness_by_scale(cloud, core, diameters, variance: str = "sample", min_points: int = 3, *, threads: int = 0,
                       progress=None) -> np.ndarray:
    diameters = list(diameters)
    with translated():
        out = _core.roughness_by_scale(cloud, core, diameters, _core.Variance[variance],
                                       _count("min_points", min_points), threads=_threads(threads),
                                       progress=_progress(progress))
    return np.asarray(out).reshape(-1, len(diameters))  # (core points, scales): the binding drops a single scale's axis


def variogram_pairs(points: np.ndarray, values: np.ndarray, edges, *, seed: int, centres: int, near_radius: float,
                    max_neighbours: int, far_pairs: int, planar: bool, threads: int = 0, progress=None) -> dict:
    """Pair sums of the empirical variogram over sampled pairs (include/m3c2/variogram.hpp):
    per lag bin `pairs`, `lag_sum`, `half_sq_sum`."""
    with translated():
        return _core.variogram_pairs(np.ascontiguousarray(points, dtype=np.float64),
                                     np.ascontiguousarray(values, dtype=np.float64),
                                     [float(e) for e in edges], int(seed), int(centres), float(near_radius),
                                     _count("max_neighbours", max_neighbours), int(far_pairs), bool(planar),
                                     _threads(threads), _progress(progress))


#: the binding's codes of the covariance kinds (include/m3c2/region_covariance.hpp)
_COVARIANCE_KINDS = {"spherical": 0, "exponential": 1}


def component_values(kind: str, sill: float, range_: float, h, *, variogram: bool = False) -> np.ndarray:
    """C(h) (or gamma(h) with `variogram`) of one covariance component at the lags `h` (any
    shape): the engine's formulas (include/m3c2/region_covariance.hpp), their one place."""
    h = np.asarray(h, dtype=np.float64)
    with translated():
        flat = _core.component_values(_COVARIANCE_KINDS[kind], float(sill), float(range_),
                                      np.ascontiguousarray(h.ravel()), variogram)
    return flat.reshape(h.shape)


def region_covariance_sum(xy: np.ndarray, components, *, exact: bool = False, threads: int = 0,
                          progress=None) -> tuple[float, list[float]]:
    """sum_i sum_j C(|x_i - x_j|) over the plan-view points `xy` ((n, 2)) for `components`
    (objects with kind, sill, range: an error model's correlated part), by bins
    (include/m3c2/region_covariance.hpp); (sum, the bin side per component). `exact`: the O(N^2)
    sum, for tests (bin sides then empty)."""
    xy = np.ascontiguousarray(xy, dtype=np.float64)
    kinds = [_COVARIANCE_KINDS[c.kind] for c in components]
    sills = [float(c.sill) for c in components]
    ranges = [float(c.range) for c in components]
    with translated():
        if exact:
            return float(_core.region_covariance_exact(xy, kinds, sills, ranges, _threads(threads),
                                                       _progress(progress))), []
        total, sides = _core.region_covariance_sum(xy, kinds, sills, ranges, threads=_threads(threads),
                                                   progress=_progress(progress))
    return float(total), [float(v) for v in sides]


def dimensionality(cloud: np.ndarray, core: np.ndarray, diameters, min_points: int = 3, *, threads: int = 0,
                   progress=None) -> dict:
    """Multi-scale dimensionality features (Brodu & Lague 2012; include/m3c2/dimensionality.hpp)."""
    with translated():
        return _core.dimensionality(cloud, core, [float(d) for d in diameters], _count("min_points", min_points),
                                    _threads(threads), _progress(progress))


def c2c(reference, compared, **kwargs) -> dict:
    """Closest-point distances (include/m3c2/baselines.hpp); keywords as the binding's."""
    if "model_neighbours" in kwargs:
        kwargs["model_neighbours"] = _count("model_neighbours", kwargs["model_neighbours"])
    if "threads" in kwargs:
        kwargs["threads"] = _threads(kwargs["threads"])
    if "progress" in kwargs:
        kwargs["progress"] = _progress(kwargs["progress"])
    with translated():
        return _core.c2c(reference, compared, **kwargs)


def register_clouds(reference: np.ndarray, compared: np.ndarray, params: dict, *, threads: int = 0,
                    progress=None) -> dict:
    """Point-to-plane ICP of `compared` onto `reference` (include/m3c2/registration.hpp); `params`:
    RegistrationParams' fields by name (the engine's defaults for the others). Returns matrix (4, 4),
    covariance (6, 6), centre (3,), registration_error, rms, pairs, candidates, iterations, converged."""
    bound = _bound_struct(_core.RegistrationParams, params)
    with translated():
        out = _core.register_clouds(np.ascontiguousarray(reference, dtype=np.float64),
                                    np.ascontiguousarray(compared, dtype=np.float64), bound, threads=_threads(threads),
                                    progress=_progress(progress))
    out["matrix"] = np.asarray(out["matrix"]).reshape(4, 4)
    out["covariance"] = np.asarray(out["covariance"]).reshape(6, 6)
    out["centre"] = np.asarray(out["centre"])
    return out


def max_abs_coordinate(params: _core.Params) -> float:
    """The largest |coordinate| compute() accepts with these parameters (its spatial index)."""
    return float(_core.max_abs_coordinate(params))


def neighbourhood_reach(params: _core.Params) -> float:
    """Largest distance from a core point to a point that can change its result."""
    return float(_core.neighbourhood_reach(params))


def memory_estimate(n_reference: int, n_compared: int, n_core: int, params: _core.Params,
                    order_in_place: bool = False) -> int:
    """Bytes compute() allocates beyond its inputs for clouds of these sizes (INDEX_MEMORY; an
    upper estimate), with `order_in_place` as compute() is given it."""
    return int(_core.memory_estimate(int(n_reference), int(n_compared), int(n_core), params, bool(order_in_place)))


class CylinderIndex:
    """One cloud's index, queried with cylinders of any diameter >= `smallest_diameter` along given
    axes (include/m3c2/cylinder_index.hpp): each call gives the points' count and the mean and
    spread of their offsets along the axis, as compute() summarises a cylinder."""

    def __init__(self, cloud: np.ndarray, smallest_diameter: float, *, threads: int = 0):
        with translated():
            self._impl = _core.CylinderIndex(cloud, smallest_diameter, threads=threads)

    def statistics(self, core: np.ndarray, normals: np.ndarray, diameter: float, half_length: float, *,
                   threads: int = 0) -> dict:
        with translated():
            return self._impl.statistics(core, normals, diameter, half_length, threads=threads)


def tile_halo(params: _core.Params) -> float:
    """The halo a tile of core points needs: the reach plus a hair of margin."""
    return float(_core.tile_halo(params))


def fdr_q_values(p: np.ndarray, method: str) -> np.ndarray:
    """Benjamini-Hochberg ("bh") or Benjamini-Yekutieli ("by") adjusted p-values of `p` (float64,
    NaN where p is NaN), ranked globally by (p, index): m3c2::fdr_q_values (src/uncertainty/fdr.cpp)."""
    with translated():
        return _core.fdr_q_values(np.ascontiguousarray(p, dtype=np.float64), method)


_DEFAULT = _core.Params()


# ----------------------------------------------------------------------------------------------
# Time series (include/m3c2/series.hpp, include/m3c2/objects_by_change.hpp; docs/series.md)


class Comparison:
    """A reference prepared once (its index, the core points' normals) to compare epochs one at a
    time; each compare() equals compute(reference, epoch, core) bit for bit."""

    def __init__(self, reference: np.ndarray, core: np.ndarray, params: _core.Params, core_normals=None, *,
                 threads: int = 0):
        with translated():
            self._impl = _core.Comparison(reference, core, params, core_normals, threads=threads)

    def compare(self, compared: np.ndarray, *, threads: int = 0) -> dict:
        with translated():
            return self._impl.compare(compared, threads=threads)

    def normals(self) -> dict:
        return self._impl.normals()


def temporal_median(values: np.ndarray, window: int, *, threads: int = 0) -> np.ndarray:
    with translated("--window"):
        return _core.temporal_median(values, window, threads=threads)


def change_points(series: np.ndarray, width: int, min_size: int, jump: int, penalty: float) -> np.ndarray:
    with translated():
        return _core.change_points(series, width, min_size, jump, penalty)


def kalman_params(*, order: int, discrete_noise: bool, process_noise: float, initial_variance=None,
                  prior_time: float | None = None, observation: str = "shared", reference=None,
                  registration_error: float = 0.0, population_spread: bool = False,
                  step_false_alarm: float | None = None) -> "_core.KalmanParams":
    """The engine's KalmanParams (include/m3c2/kalman.hpp; initial_variance: the engine's default
    when None); `prior_time` (independent model): start every row there (its prior mean given to
    kalman_smooth) instead of at its first observation. `observation`: shared (the reference's
    error in the state; kalman_smooth then needs `spread`) or independent; `reference` (shared):
    (its time or None, the epoch that is the reference file or None); `step_false_alarm` (shared):
    the step test's false-alarm rate, 0 for none (None: the engine's default)."""
    p = _core.KalmanParams()
    with translated("--observation"):
        p.observation = observation
    ref_time, ref_epoch = reference if reference is not None else (None, None)
    p.reference_time = math.nan if ref_time is None else float(ref_time)
    p.reference_epoch = -1 if ref_epoch is None else int(ref_epoch)
    p.registration_error = float(registration_error)
    p.population_spread = bool(population_spread)
    if step_false_alarm is not None:
        p.step_false_alarm = float(step_false_alarm)
    with translated("--model"):
        p.order = int(order)
    p.discrete_noise = bool(discrete_noise)
    p.process_noise = float(process_noise)
    if initial_variance is not None:
        p.initial_variance = [float(v) for v in initial_variance]
    p.prior_given = prior_time is not None
    p.prior_time = 0.0 if prior_time is None else float(prior_time)
    return p


def kalman_smooth(values, variance, times, moments, params, *, resume_from: int = 0, prior_mean=None,
                  spread=None, threads: int = 0) -> dict:
    """Forward filter and RTS smoother; `moments` (core x epoch x moments) is read before
    `resume_from` and written after; `variance` for the independent observation model, `spread`
    = (sigma1, n1, sigma2, n2), core x epoch each, for the shared one. Returns mean and sd (core x
    epoch x order) and log_likelihood."""
    rows, epochs = values.shape
    with translated("--process-noise"):
        out = _core.kalman_smooth(values, variance, times, moments, params, resume_from=resume_from,
                                  prior_mean=prior_mean, spread=spread, threads=threads)
    k = params.order
    return {"mean": out["mean"].reshape(rows, epochs, k), "sd": out["sd"].reshape(rows, epochs, k),
            "log_likelihood": out["log_likelihood"]}


def kalman_log_likelihood(values, variance, times, params, *, prior_mean=None, spread=None, threads: int = 0) -> float:
    with translated("--process-noise"):
        return _core.kalman_log_likelihood(values, variance, times, params, prior_mean=prior_mean, spread=spread,
                                           threads=threads)


def kalman_fit_process_noise(values, variance, times, params, *, spread=None, threads: int = 0) -> tuple[float, int]:
    """`--process-noise auto` (include/m3c2/kalman.hpp): the q of maximum likelihood and where it
    fell on the searched grid (-1 / +1: its smallest / largest q, else 0)."""
    with translated():  # the engine's message names --process-noise itself
        return _core.kalman_fit_process_noise(values, variance, times, params, spread=spread, threads=threads)


def lod_observation_variance(params, lod, sigma1, n1, sigma2, n2, *, threads: int = 0) -> np.ndarray:
    """(LOD / critical value)^2 per core point and epoch (include/m3c2/kalman.hpp)."""
    with translated():
        return _core.lod_observation_variance(params, lod, sigma1, n1, sigma2, n2, threads=threads)


def tam3c2_pool(clouds, times) -> "_core.Tam3c2Pool":
    """The epochs of a TAM3C2 run (include/m3c2/tam3c2.hpp): float64 (N, 3) clouds and their
    times, each cloud indexed once; the pool keeps the arrays alive."""
    with translated():
        return _core.Tam3c2Pool([np.ascontiguousarray(c, dtype=np.float64) for c in clouds],
                                [float(t) for t in times])


#: Each enum field of Tam3c2Params and its option names, in order (include/m3c2/tam3c2.hpp's own).
TAM3C2_CHOICES = {k: tuple(v) for k, v in _core.TAM3C2_CHOICES.items()}
#: Where a TAM3C2 cell's numbers came from (tam3c2.hpp, Tam3c2Source): its windows, or the epoch's own M3C2.
TAM3C2_SOURCE_WINDOWS, TAM3C2_SOURCE_EPOCH = _core.Tam3c2Source.windows.value, _core.Tam3c2Source.epoch.value
#: The fields of the epochs' own M3C2 that TAM3C2's fallback and breaks read, in the engine's order.
TAM3C2_EPOCHWISE = ("distance", "lod", "significant", "n1", "n2")


def tam3c2_params(**settings) -> "_core.Tam3c2Params":
    """The engine's Tam3c2Params (include/m3c2/tam3c2.hpp) from its fields by name: normal_radii,
    window_ratios, min_points, cylinder_radius, max_distance, weights, sigma_ratio,
    space_time_ratio, registration_error, orientation, lod, confidence (the LOD's level; the
    engine owns its quantile), fallback, breaks, break_width, break_min_size, break_jump,
    break_penalty; the engine's default for the others."""
    return _bound_struct(_core.Tam3c2Params, settings)


def _bound_struct(kind: type, fields: dict):
    """A bound C++ struct of `kind` (its defaults the engine's) with `fields` set by name; a name
    it lacks is a TypeError naming it."""
    out = kind()
    with translated():
        for name, value in fields.items():
            if not hasattr(out, name):
                raise TypeError(f"{kind.__name__} has no field {name!r}")
            setattr(out, name, value)
    return out


def tam3c2(pool, core, reference: int, targets, settings: dict, *, orientations=None, epochwise=None,
           threads: int = 0) -> dict:
    """TAM3C2 of `core` between the pool's epoch `reference` and each of `targets`; `settings`:
    tam3c2_params' fields. `orientations`: None or (N, 3), the side each core point's normal points
    to (the engine falls back to `orientation` where a row is not finite or zero). `epochwise`:
    None or a dict of TAM3C2_EPOCHWISE's (N, pool size) arrays, the epochs' own M3C2 (NaN where
    none; the reference's own column distance 0), which fallback and breaks read.
    Per-(core, target) arrays are core x targets; normal core x 3, scale per core point."""
    core = np.ascontiguousarray(core, dtype=np.float64).reshape(-1, 3)
    targets = [int(t) for t in targets]
    if orientations is not None:
        orientations = np.ascontiguousarray(orientations, dtype=np.float64).reshape(-1, 3)
    if epochwise is not None:
        epochwise = np.ascontiguousarray(np.stack([np.asarray(epochwise[k], dtype=np.float64)
                                                   for k in TAM3C2_EPOCHWISE]))
    params = tam3c2_params(**settings)
    with translated():
        out = _core.tam3c2(pool, core, int(reference), targets, params, orientations=orientations,
                           epochwise=epochwise, threads=threads)
    shape = (len(core), len(targets))
    return {k: (v if k in ("normal", "scale") else v.reshape(shape)) for k, v in out.items()}


def normalised_dtw(a: np.ndarray, b: np.ndarray, norm_a=0.0, norm_b=0.0, dmax_origin=0.0) -> float:
    with translated():
        return float(_core.normalised_dtw(a, b, norm_a, norm_b, dmax_origin))


def objects_params(**fields):
    p = _core.ObjectsParams()
    with translated():
        for name, value in fields.items():
            if name == "dtw" and isinstance(value, str):
                value = getattr(_core.ObjectsDtw, value.replace("-", "_"))  # the command line's spelling
            if value is not None:
                setattr(p, name, value)
    return p


def objects_by_change(distances: np.ndarray, core: np.ndarray, params, *, threads: int = 0, progress=None) -> dict:
    with translated():
        return _core.objects_by_change(distances, core, params, threads=threads, progress=progress)
