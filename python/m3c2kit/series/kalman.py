"""`m3c2 series kalman`: a Kalman filter and Rauch-Tung-Striebel smoother over each core point's
distance series (docs/series.md, "Kalman filter"; Winiwarter et al. 2023, Earth Surf. Dynam. 11:
593), the engine's (include/m3c2/kalman.hpp), run one block of core points at a time.

`--observation shared` (the default) hands the engine each block's distances with the store's
sigma1, n1, sigma2, n2: the engine pools each core point's scatter and holds the reference's error,
shared by every epoch, in the state (kalman.hpp: KalmanObservation). `independent`, the references'
model, observes each distance with the variance (LOD / c)^2, c the critical value its LOD was made
with (the engine's own rule, kalman.hpp: lod_observation_variance). Times are the epochs' (in days
since the first epoch). The step writes the smoothed distance, rate (and acceleration) with their standard
deviations, `kalman_significant` (|d| > z_C sigma) and `kalman_moments`, the filtered state at
every epoch, in the staging folder and publishes them together (analysis.publish_many): a kill
leaves the previous variables, or all of them marked half-written, never a mix.

Incremental (independent only): after `add`, a rerun with the same model, noise, process noise
and observation model filters only the new epochs, from the kept moments of the last computed
one, then smooths backward over every epoch (the RTS pass needs all of them); the result is the
from-scratch run's, bit for bit (tests/python/series/test_kalman_store.py). The shared model's
pooled scatter changes with each epoch added, so every shared run filters from scratch (its
moments are kept for inspection, never resumed from)."""
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
from .epochs import microseconds
from . import analysis
from . import integrity
from . import parameters
from . import step
from . import store as st

MODELS = {"velocity": 2, "acceleration": 3}
NOISES = ("continuous", "discrete")
OBSERVATIONS = ("shared", "independent")
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


@dataclass(frozen=True)
class KalmanOptions:
    model: str = "velocity"
    process_noise: float | str = "auto"  # q >= 0, or "auto"
    noise: str = "continuous"
    confidence: float | None = None  # the store's when None
    from_scratch: bool = False
    threads: int = 0
    observation: str = "shared"  # or "independent" (kalman4d's and the tum-rsa fork's, over-confident)


def _check(options: KalmanOptions) -> None:
    if options.model not in MODELS:
        raise UsageError(f"--model must be one of {', '.join(MODELS)}, got {options.model!r}")
    if options.noise not in NOISES:
        raise UsageError(f"--noise must be one of {', '.join(NOISES)}, got {options.noise!r}")
    if options.observation not in OBSERVATIONS:
        raise UsageError(f"--observation must be one of {', '.join(OBSERVATIONS)}, got {options.observation!r}")
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


@dataclass(frozen=True)
class Inputs:
    """One block's observations (core x epoch): the distances, and their variance (independent)
    or the store's (sigma1, n1, sigma2, n2) from which the engine pools the scatter (shared)."""
    values: np.ndarray
    variance: np.ndarray | None = None
    spread: tuple | None = None

    def rows(self, sel) -> "Inputs":
        pick = lambda a: np.ascontiguousarray(a[sel])  # noqa: E731
        return Inputs(pick(self.values), None if self.variance is None else pick(self.variance),
                      None if self.spread is None else tuple(pick(a) for a in self.spread))

    @staticmethod
    def stacked(parts: list["Inputs"]) -> "Inputs":
        cat = lambda arrays: np.ascontiguousarray(np.concatenate(arrays))  # noqa: E731
        first = parts[0]
        return Inputs(cat([p.values for p in parts]),
                      None if first.variance is None else cat([p.variance for p in parts]),
                      None if first.spread is None else tuple(cat([p.spread[i] for p in parts]) for i in range(4)))


def _observations(store: Path, group, params, rows: slice, n: int, observation: str, threads: int) -> Inputs:
    """The observations of core points `rows` over the first n epochs."""
    sel = (rows, slice(0, n))
    read = lambda name: st.read(store, group, name, sel)  # noqa: E731
    contiguous = lambda a: np.ascontiguousarray(a, dtype=np.float64)  # noqa: E731
    z = contiguous(read("distance"))
    spread = tuple(contiguous(a) for a in (read("sigma1"), _counts(read("n1")), read("sigma2"), _counts(read("n2"))))
    if observation == "shared":
        return Inputs(z, spread=spread)
    arrays = [np.ascontiguousarray(read("lod"), dtype=np.float64).ravel(), *(a.ravel() for a in spread)]
    var = facade.lod_observation_variance(params, *arrays, threads=threads).reshape(z.shape)
    return Inputs(z, variance=var)


def _reference(store: Path, group, n: int) -> tuple[float | None, int | None]:
    """(the reference's time in days since the first epoch, the epoch that is the reference file):
    each None when the store does not know it (docs/series.md, "Kalman filter", the anchor)."""
    epoch = None
    sha = str(group.attrs.get("reference_sha256", "") or "")
    if sha and "source_sha256" in group:
        hashes = st.read(store, group, "source_sha256", slice(0, n))
        same = [e for e in range(n) if str(hashes[e]) == sha]
        epoch = same[0] if same else None
    text = str(group.attrs.get("reference_time", "") or "")
    if not text:
        return None, epoch
    first = st.read(store, group, "time", slice(0, 1)).astype(np.int64)[0]
    ref = microseconds(text, f"{store}: reference_time")
    return (ref - int(first)) / MICROSECONDS_PER_DAY, epoch


def _kalman_params(model: str, noise: str, q: float, observation: str = "independent", *, reference=None,
                   params=None):
    """The engine's KalmanParams; the rate's (acceleration's) initial variance the engine's, 1
    (unit / day)^2 (kalman.hpp). `observation` defaults to independent here, the model that needs
    only each observation's variance (the tests' and the figure's series); the command's default,
    shared, is KalmanOptions'. `reference`: (time, epoch) of the store's reference (_reference);
    `params`: the store's engine Params, whose registration error and spread the shared model uses."""
    reg = 0.0 if params is None else params.registration_error
    population = params is not None and params.variance.name == "population"
    return facade.kalman_params(order=MODELS[model], discrete_noise=noise == "discrete", process_noise=q,
                                observation=observation, reference=reference, registration_error=reg,
                                population_spread=population)


def _sample(store: Path, group, params, n: int, observation: str, threads: int) -> Inputs:
    """Evenly spread core points (at most AUTO_SAMPLE observations) for `auto`, read block by block."""
    n_core = group["distance"].shape[0]
    stride = max(1, -(-n_core * n // AUTO_SAMPLE))
    parts = []
    for begin, end in _block_rows(group, n, 3):
        first = -begin % stride  # rows begin + first, + stride, ... are the sample's
        block = _observations(store, group, params, slice(begin, end), n, observation, threads)
        parts.append(block.rows(slice(first, None, stride)))
    return Inputs.stacked(parts)


def fit_process_noise(inputs: Inputs, days: np.ndarray, kalman_params, threads: int = 0) -> tuple[float, str]:
    """`--process-noise auto`: the engine's maximum-likelihood q (kalman.hpp:
    kalman_fit_process_noise, the one owner of the search) and a note when it fell at the searched
    grid's edge."""
    q, edge = facade.kalman_fit_process_noise(inputs.values, inputs.variance, np.asarray(days, np.float64),
                                              kalman_params, spread=inputs.spread, threads=threads)
    note = ""
    if edge:
        note = (f"the likelihood is highest at the edge of the searched range ({'smallest' if edge < 0 else 'largest'}"
                f" q tried, {q:.3g})")
    return q, note


def _block_rows(group, n: int, k: int) -> list[tuple[int, int]]:
    """Core-point blocks: the store's core chunks, split so that one holds at most BLOCK_BYTES."""
    per_row = max(1, n) * 8 * (10 + 3 * k + (k + 1) * (k + 2) // 2)  # the shared state's moments at most
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
    if options.observation != "independent":  # the shared model's pooled scatter changes with the epochs
        return 0, None
    same = attrs.get("model") == options.model and attrs.get("noise") == options.noise
    # a run from before the option was the independent model
    same = same and attrs.get("observation", "independent") == options.observation
    kept_q = attrs.get("process_noise")
    if options.process_noise == "auto":
        same = same and attrs.get("process_noise_source") == "auto"
    else:
        same = same and kept_q == float(options.process_noise)
    epochs = int(attrs.get("epochs", 0))
    if not same or not 0 < epochs <= n:
        return 0, None
    return epochs, float(kept_q)


#: The largest process-noise variance q dt^(2 n - 1) (n the state's size) the filter keeps finite.
LARGEST_PROCESS_VARIANCE = 1e300


def _require_representable(q: float, days: np.ndarray, model: str) -> None:
    """Hostile round 2: --process-noise 1e290 over epochs 8,000 years apart overflowed the
    process noise of the gap (q dt^3) and published every estimate as NaN with exit 0."""
    finite = days[np.isfinite(days)]
    span = float(max(np.ptp(finite), np.abs(finite).max())) if len(finite) else 0.0
    power = 2 * MODELS[model] - 1  # the state's size: q dt^3 (velocity), q dt^5 (acceleration)
    with np.errstate(over="ignore"):
        variance = q * span ** power
    if not variance <= LARGEST_PROCESS_VARIANCE:
        raise UsageError(f"--process-noise {q:g} over epochs spanning {span:g} days: the process noise of that gap, "
                         f"q dt^{power} = {variance:.3g}, is beyond the float range; give a smaller --process-noise")


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
        reference = _reference(store, group, n)
        resume, q = _resumable(group, options, n)
        note = ""
        if q is None:
            if options.process_noise == "auto":
                sample = _sample(store, group, params, n, options.observation, threads)
                fit = _kalman_params(options.model, options.noise, 0.0, options.observation, reference=reference,
                                     params=params)
                q, note = fit_process_noise(sample, days, fit, threads)
            else:
                q = float(options.process_noise)
        source = "auto" if options.process_noise == "auto" else "given"
        _require_representable(q, days, options.model)
        run = _Run(options, q, source, confidence, params, days, resume, threads, reference)
        done = _write(store, folder, group, run)
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
    reference: tuple



def _write(store: Path, folder: Path, group, run: _Run) -> list[str]:
    """The run's variables in the staging folder, block by block of core points."""
    model, k, observation = run.options.model, MODELS[run.options.model], run.options.observation
    size = k + (observation == "shared")  # the state: d, d' (d'') and, shared, b
    n, m = len(run.days), size + size * (size + 1) // 2
    names = variables(model)
    common = {"model": model, "noise": run.options.noise, "observation": observation, "process_noise": run.q,
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
    p = _kalman_params(model, run.options.noise, run.q, observation, reference=run.reference, params=run.params)
    kept = group[MOMENTS] if run.resume else None
    fault_hook.checkpoint("store-write")
    for begin, end in _block_rows(group, n, k):
        block = _observations(store, group, run.params, slice(begin, end), n, observation, run.threads)
        moments = np.full((end - begin, n, m), np.nan)
        if kept is not None:
            moments[:, :run.resume] = st.read(store, group, MOMENTS, (slice(begin, end), slice(0, run.resume)))
        r = facade.kalman_smooth(block.values, block.variance, run.days, moments, p, resume_from=run.resume,
                                 spread=block.spread, threads=run.threads)
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
