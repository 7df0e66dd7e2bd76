"""`m3c2 series kalman`: a Kalman filter and Rauch-Tung-Striebel smoother over each core point's
distance series (docs/series.md, "Kalman filter"; Winiwarter et al. 2023, Earth Surf. Dynam. 11:
593), the engine's (include/m3c2/kalman.hpp), run one block of core points at a time.

Each epoch observes the distance with the variance (LOD / c)^2, c the critical value its LOD was
made with (the engine's own rule, kalman.hpp: lod_observation_variance); times are the epochs'
(in days). The step writes the smoothed distance, rate (and acceleration) with their standard
deviations, `kalman_significant` (|d| > z_C sigma) and `kalman_moments`, the filtered state at
every epoch, in the staging folder and publishes them together (analysis.publish_many): a kill
leaves the previous variables, or all of them marked half-written, never a mix.

Incremental: after `add`, a rerun with the same model, noise and process noise filters only the
new epochs, from the kept moments of the last computed one, then smooths backward over every
epoch (the RTS pass needs all of them); the result is the from-scratch run's, bit for bit
(tests/python/series/test_kalman.py)."""
from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..base import fault_hook
from ..base.errors import UsageError
from .. import engine as facade
from ..run.checks import threads_count
from ..base.quantiles import z_critical
from . import analysis
from . import integrity
from . import parameters
from . import step
from . import store as st

MODELS = {"velocity": 2, "acceleration": 3}
NOISES = ("continuous", "discrete")
#: The smoothed state's variables, (mean, standard deviation) per state component (d, d', d''),
#: then the flag and the filtered moments: the store's names (store.KALMAN_VARIABLES, in that order).
STATE_VARIABLES = tuple(zip(st.KALMAN_VARIABLES[0:6:2], st.KALMAN_VARIABLES[1:6:2]))
SIGNIFICANT, MOMENTS = st.KALMAN_VARIABLES[6:8]
MICROSECONDS_PER_DAY = 86_400_000_000
#: Bytes of float64 per core point and epoch a block holds (inputs, moments, outputs), and the
#: most a block may hold: memory is bounded by one block of core points.
BLOCK_BYTES = 256 << 20
#: `auto`: the core points whose likelihood is maximised, evenly spread, at most this many
#: observations (core points x epochs) in memory.
AUTO_SAMPLE = 2_000_000
#: `auto`: the search in log10 q around q0 = (median observation variance) / M00(median dt).
AUTO_DECADES = (-8.0, 4.0)
AUTO_TOLERANCE = 1e-3  # in log10 q


@dataclass(frozen=True)
class KalmanOptions:
    model: str = "velocity"
    process_noise: float | str = "auto"  # q >= 0, or "auto"
    noise: str = "continuous"
    confidence: float | None = None  # the store's when None
    from_scratch: bool = False
    threads: int = 0


def _check(options: KalmanOptions) -> None:
    if options.model not in MODELS:
        raise UsageError(f"--model must be one of {', '.join(MODELS)}, got {options.model!r}")
    if options.noise not in NOISES:
        raise UsageError(f"--noise must be one of {', '.join(NOISES)}, got {options.noise!r}")
    q = options.process_noise
    if q != "auto" and not (isinstance(q, (int, float)) and math.isfinite(q) and q >= 0):
        raise UsageError(f"--process-noise must be 'auto' or a finite number >= 0, got {q!r}")
    c = options.confidence
    if c is not None and not 0.0 < c < 1.0:
        raise UsageError(f"--confidence must be in (0, 1), got {c!r}")


def variables(model: str) -> list[str]:
    """The variables a run of `model` writes."""
    names = [n for pair in STATE_VARIABLES[:MODELS[model]] for n in pair]
    return [*names, SIGNIFICANT, MOMENTS]


def _days(store: Path, group, n: int) -> np.ndarray:
    """The epochs' times in days since the first epoch; every epoch needs one."""
    times = st.read(store, group, "time", slice(0, n)).astype(np.int64)
    if (times == st.NAT).any():
        first = int(np.flatnonzero(times == st.NAT)[0])
        raise UsageError(f"{store}: epoch {first} has no time (NaT): the Kalman filter needs every epoch's time "
                         f"(give it in the epoch list file, 'PATH, TIME')")
    return (times - times[0]).astype(np.float64) / MICROSECONDS_PER_DAY


def _engine_params(store: Path, group):
    """The store's engine Params (its LOD's rule and confidence). An imported py4dgeo store keeps
    no parameters: py4dgeo's LOD is 1.96 (...), z at 95 %."""
    if "imported_from" in group.attrs:
        return facade.make_params({"lod": "z", "confidence": 0.95})
    core = np.column_stack([st.read(store, group, a) for a in "xyz"])
    return parameters.engine_params(json.loads(group.attrs["parameters"]), core)


def _counts(values: np.ndarray) -> np.ndarray:
    """n1 / n2 as stored (uint32, fill 2^32 - 1 for NaN) as float64 with NaN."""
    fill = st.INT_FILL["n1"][1]
    out = values.astype(np.float64)
    out[values == fill] = np.nan
    return out


def _observations(store: Path, group, params, rows: slice, n: int, threads: int) -> tuple[np.ndarray, np.ndarray]:
    """(distance, observation variance) of core points `rows` over the first n epochs."""
    sel = (rows, slice(0, n))
    read = lambda name: st.read(store, group, name, sel)
    z = np.ascontiguousarray(read("distance"), dtype=np.float64)
    arrays = [np.ascontiguousarray(a, dtype=np.float64).ravel()
              for a in (read("lod"), read("sigma1"), _counts(read("n1")), read("sigma2"), _counts(read("n2")))]
    var = facade.lod_observation_variance(params, *arrays, threads=threads).reshape(z.shape)
    return z, var


def _kalman_params(model: str, noise: str, q: float):
    # The rate's (acceleration's) initial variance: the engine's, 1 (unit / day)^2 (kalman.hpp).
    return facade.kalman_params(order=MODELS[model], discrete_noise=noise == "discrete", process_noise=q)


def unit_m00(model: str, noise: str, dt: float) -> float:
    """M(dt)[0, 0] of Q = q M(dt) (kalman.hpp): the variance q = 1 adds to d over dt."""
    k = MODELS[model]
    if noise == "discrete":
        return 0.25 * dt ** 4
    return dt ** 3 / 3.0 if k == 2 else dt ** 5 / 20.0


def _sample(store: Path, group, params, n: int, threads: int):
    """Evenly spread core points (at most AUTO_SAMPLE observations) for `auto`, read block by block."""
    n_core = group["distance"].shape[0]
    stride = max(1, -(-n_core * n // AUTO_SAMPLE))
    zs, vs = [], []
    for begin, end in _block_rows(group, n, 3):
        first = -begin % stride  # rows begin + first, + stride, ... are the sample's
        z, v = _observations(store, group, params, slice(begin, end), n, threads)
        zs.append(z[first::stride]), vs.append(v[first::stride])
    return np.ascontiguousarray(np.concatenate(zs)), np.ascontiguousarray(np.concatenate(vs))


def fit_process_noise(values: np.ndarray, variance: np.ndarray, days: np.ndarray, model: str, noise: str,
                      threads: int = 0) -> tuple[float, str]:
    """`--process-noise auto`: the q maximising the likelihood of the observations (the
    prediction error decomposition, Harvey 1989, 3.4; one q for every core point, as the papers
    use one for a scene), over log10 q: a grid of half decades around q0 (the median
    observation variance over M00 of the median epoch spacing), refined by golden section.
    Returns q and a note when the maximum is at the grid's edge."""
    dts = np.diff(days)
    dts = dts[dts > 0]
    finite = variance[np.isfinite(variance) & np.isfinite(values)]
    if len(dts) == 0 or len(finite) == 0:
        raise UsageError("--process-noise auto needs at least two epochs at distinct times and observations "
                         "with a LOD; give --process-noise Q")
    q0 = max(float(np.median(finite)), 1e-300) / unit_m00(model, noise, float(np.median(dts)))
    u0 = math.log10(q0)

    def loglik(u: float) -> float:
        p = _kalman_params(model, noise, 10.0 ** u)
        return facade.kalman_log_likelihood(values, variance, days, p, threads=threads)

    grid = np.arange(u0 + AUTO_DECADES[0], u0 + AUTO_DECADES[1] + 1e-9, 0.5)
    scores = [loglik(float(u)) for u in grid]
    best = int(np.nanargmax(scores))
    note = ""
    if best in (0, len(grid) - 1):
        note = (f"the likelihood is highest at the edge of the searched range ({'smallest' if best == 0 else 'largest'}"
                f" q tried, {10.0 ** grid[best]:.3g})")
    lo, hi = grid[max(0, best - 1)], grid[min(len(grid) - 1, best + 1)]
    g = (math.sqrt(5.0) - 1.0) / 2.0
    a, b = hi - g * (hi - lo), lo + g * (hi - lo)
    fa, fb = loglik(a), loglik(b)
    while hi - lo > AUTO_TOLERANCE:
        if fa > fb:
            hi, b, fb = b, a, fa
            a = hi - g * (hi - lo)
            fa = loglik(a)
        else:
            lo, a, fa = a, b, fb
            b = lo + g * (hi - lo)
            fb = loglik(b)
    u = max([(scores[best], float(grid[best])), (fa, a), (fb, b)])[1]
    return 10.0 ** u, note


def _block_rows(group, n: int, k: int) -> list[tuple[int, int]]:
    """Core-point blocks: the store's core chunks, split so that one holds at most BLOCK_BYTES."""
    per_row = max(1, n) * 8 * (8 + 3 * k + k * (k + 1) // 2)
    most = max(1, BLOCK_BYTES // per_row)
    out = []
    for begin, end in analysis._core_chunks(group):
        out.extend((b, min(end, b + most)) for b in range(begin, end, most))
    return out


def _resumable(group, options: KalmanOptions, n: int) -> tuple[int, float | None]:
    """(epochs kept, the kept q) of the store's Kalman run when this one may resume from it, else (0, None)."""
    if options.from_scratch or MOMENTS not in group:
        return 0, None
    attrs = group[MOMENTS].attrs
    same = attrs.get("model") == options.model and attrs.get("noise") == options.noise
    kept_q = attrs.get("process_noise")
    if options.process_noise == "auto":
        same = same and attrs.get("process_noise_source") == "auto"
    else:
        same = same and kept_q == float(options.process_noise)
    epochs = int(attrs.get("epochs", 0))
    if not same or not 0 < epochs <= n:
        return 0, None
    return epochs, float(kept_q)


def kalman(store: Path, options: KalmanOptions = KalmanOptions()) -> dict:
    """Runs the filter and smoother on the store and publishes its variables; returns what it did."""
    _check(options)
    store = Path(store)
    threads = threads_count(options.threads)
    kept = lambda folder: analysis.what_was_kept(store, folder, st.KALMAN_VARIABLES, "Kalman variables")  # noqa: E731
    with step.writing(store, "kalman", kept) as folder:
        group = st.open_group(folder)
        if not options.from_scratch:  # a half-written run is resumed from nothing but replaced whole
            integrity.require_whole(group, st.KALMAN_VARIABLES, store)
        n = group["distance"].shape[1]
        if n == 0:
            raise UsageError(f"{store} has no epoch to filter")
        days = _days(store, group, n)
        params = _engine_params(store, group)
        confidence = params.confidence if options.confidence is None else options.confidence
        resume, q = _resumable(group, options, n)
        note = ""
        if q is None:
            if options.process_noise == "auto":
                z, v = _sample(store, group, params, n, threads)
                q, note = fit_process_noise(z, v, days, options.model, options.noise, threads)
            else:
                q = float(options.process_noise)
        source = "auto" if options.process_noise == "auto" else "given"
        done = _write(store, folder, group, _Run(options, q, source, confidence, params, days, resume, threads))
        removed = [name for name in st.KALMAN_VARIABLES if name in group and name not in done]
        analysis.publish_many(folder, done, removed)
    return {"epochs": n, "resumed_from": resume, "process_noise": q, "source": source, "note": note,
            "confidence": confidence, "variables": done}


@dataclass(frozen=True)
class _Run:
    options: KalmanOptions
    q: float
    source: str
    confidence: float
    params: object
    days: np.ndarray
    resume: int
    threads: int


def _write(store: Path, folder: Path, group, run: _Run) -> list[str]:
    """The run's variables in the staging folder, block by block of core points."""
    model, k = run.options.model, MODELS[run.options.model]
    n, m = len(run.days), k + k * (k + 1) // 2
    names = variables(model)
    common = {"model": model, "noise": run.options.noise, "process_noise": run.q,
              "process_noise_source": run.source, "epochs": int(n), "time_unit": "days since the first epoch"}
    integrity.make_staging(folder)  # once: every variable of the run is staged in it
    out = {}
    for j, (mean, sd) in enumerate(STATE_VARIABLES[:k]):
        what = ("distance", "rate (per day)", "acceleration (per day^2)")[j]
        out[mean] = _staged(folder, group, mean, np.float64, np.nan, dict(common, long_name=f"Kalman-smoothed {what}"))
        out[sd] = _staged(folder, group, sd, np.float64, np.nan,
                          dict(common, long_name=f"standard deviation of the smoothed {what}"))
    out[SIGNIFICANT] = _staged(
        folder, group, SIGNIFICANT, np.int8, -1,
        dict(common, confidence=run.confidence, _FillValue=-1,
             long_name="|kalman_distance| > z_C kalman_distance_sigma (1 yes, 0 no, -1 no estimate)"))
    out[MOMENTS] = _staged_moments(folder, group, m, common)
    z_c = z_critical(run.confidence)
    p = _kalman_params(model, run.options.noise, run.q)
    kept = group[MOMENTS] if run.resume else None
    fault_hook.checkpoint("store-write")
    for begin, end in _block_rows(group, n, k):
        z, v = _observations(store, group, run.params, slice(begin, end), n, run.threads)
        moments = np.full((end - begin, n, m), np.nan)
        if kept is not None:
            moments[:, :run.resume] = st.read(store, group, MOMENTS, (slice(begin, end), slice(0, run.resume)))
        r = facade.kalman_smooth(z, v, run.days, moments, p, resume_from=run.resume, threads=run.threads)
        for j, (mean, sd) in enumerate(STATE_VARIABLES[:k]):
            out[mean][begin:end, :n] = r["mean"][:, :, j]
            out[sd][begin:end, :n] = r["sd"][:, :, j]
        d, s = r["mean"][:, :, 0], r["sd"][:, :, 0]
        with np.errstate(invalid="ignore"):
            out[SIGNIFICANT][begin:end, :n] = np.where(np.isnan(d), -1, np.abs(d) > z_c * s).astype(np.int8)
        out[MOMENTS][begin:end, :n] = moments
    return names


def _staged(folder: Path, group, name: str, dtype, fill, attrs: dict):
    """A (core, epoch) array `name` in the step's staging folder, shaped and chunked like distance."""
    _, zarr = st.require_extra()
    return zarr.create_array(store=str(integrity.staged_name(folder, name)), zarr_format=3, config=st.WRITE_CONFIG,
                             **analysis._variable_spec(group, dtype, fill, attrs))


def _staged_moments(folder: Path, group, m: int, attrs: dict):
    """The (core, epoch, moment) array of the filtered moments, chunked as distance and whole along moment."""
    _, zarr = st.require_extra()
    model = group["distance"]
    return zarr.create_array(store=str(integrity.staged_name(folder, MOMENTS)), zarr_format=3, config=st.WRITE_CONFIG,
                             shape=(*model.shape, m), chunks=(*model.chunks, m), dtype=np.float64,
                             fill_value=np.nan, compressors=st.codecs(),
                             dimension_names=("core", "epoch", "kalman_moment"),
                             attributes=dict(attrs, long_name="filtered state at each epoch: mean, then the "
                                                              "covariance's upper triangle row by row"))
