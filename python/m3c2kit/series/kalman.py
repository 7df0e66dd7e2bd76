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
every epoch, in the staging folder and publishes them together (view.publish_many): a kill
leaves the previous variables, or all of them marked half-written, never a mix.

Incremental (independent only): after `add`, a rerun with the same model, noise, process noise
and observation model filters only the new epochs, from the kept moments of the last computed
one, then smooths backward over every epoch (the RTS pass needs all of them); the result is the
from-scratch run's, bit for bit (tests/python/series/test_kalman_store.py). The shared model's
pooled scatter changes with each epoch added, so every shared run filters from scratch (its
moments are kept for inspection, never resumed from)."""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..base import fault_hook
from ..base.errors import UsageError
from .. import engine as facade
from ..run.checks import threads_count
from ..base.quantiles import z_critical
from ..settings.series_rows import KALMAN_ORDERS, row
from .epochs import microseconds
from . import integrity
from . import store as st
from .view import MICROSECONDS_PER_DAY, StoreView, writing

MODELS = KALMAN_ORDERS  # the state's name -> its size (the parameter table's --model)
NOISES = row("noise").choices
OBSERVATIONS = row("observation").choices
#: The smoothed state's variables, (mean, standard deviation) per state component (d, d', d''),
#: then the flag and the filtered moments: the store's names (store.KALMAN_VARIABLES, in that order).
STATE_VARIABLES = tuple(zip(st.KALMAN_VARIABLES[0:6:2], st.KALMAN_VARIABLES[1:6:2]))
SIGNIFICANT, MOMENTS = st.KALMAN_VARIABLES[6:8]
#: Bytes of float64 per core point and epoch a block holds (inputs, moments, outputs), and the
#: most a block may hold: memory is bounded by one block of core points.
BLOCK_BYTES = 256 << 20
#: `auto`: the core points whose likelihood is maximised, evenly spread, at most this many
#: observations (core points x epochs) in memory.
AUTO_SAMPLE = 2_000_000


@dataclass(frozen=True)
class KalmanOptions:
    """`m3c2 series kalman`'s options; their defaults the parameter table's (settings/series_rows.py)."""
    model: str = row("model").default_for()
    process_noise: float | str = row("process_noise").default_for()  # q >= 0, or "auto"
    noise: str = row("noise").default_for()
    confidence: float | None = None  # the store's when None
    from_scratch: bool = row("from_scratch").default_for()
    threads: int = 0
    observation: str = row("observation").default_for()  # or independent (kalman4d's, over-confident)


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


def _observations(view: StoreView, params, rows: slice, n: int, observation: str, threads: int) -> Inputs:
    """The observations of core points `rows` over the first n epochs."""
    sel = (rows, slice(0, n))
    read = lambda name: view.read(name, sel)  # noqa: E731
    contiguous = lambda a: np.ascontiguousarray(a, dtype=np.float64)  # noqa: E731
    z = contiguous(read("distance"))
    spread = tuple(contiguous(a) for a in (read("sigma1"), _counts(read("n1")), read("sigma2"), _counts(read("n2"))))
    if observation == "shared":
        return Inputs(z, spread=spread)
    arrays = [np.ascontiguousarray(read("lod"), dtype=np.float64).ravel(), *(a.ravel() for a in spread)]
    var = facade.lod_observation_variance(params, *arrays, threads=threads).reshape(z.shape)
    return Inputs(z, variance=var)


def _reference(view: StoreView, n: int) -> tuple[float | None, int | None]:
    """(the reference's time in days since the first epoch, the epoch that is the reference file):
    each None when the store does not know it (docs/series.md, "Kalman filter", the anchor)."""
    epoch = None
    sha = str(view.group.attrs.get("reference_sha256", "") or "")
    if sha and "source_sha256" in view.group:
        hashes = view.read("source_sha256", slice(0, n))
        same = [e for e in range(n) if str(hashes[e]) == sha]
        epoch = same[0] if same else None
    text = str(view.group.attrs.get("reference_time", "") or "")
    if not text:
        return None, epoch
    first = view.read("time", slice(0, 1)).astype(np.int64)[0]
    ref = microseconds(text, f"{view.shown}: reference_time")
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


def _sample(view: StoreView, params, n: int, observation: str, threads: int) -> Inputs:
    """Evenly spread core points (at most AUTO_SAMPLE observations) for `auto`, read block by block."""
    stride = max(1, -(-view.n_core * n // AUTO_SAMPLE))
    parts = []
    for begin, end in _blocks(view, n, 3):
        first = -begin % stride  # rows begin + first, + stride, ... are the sample's
        block = _observations(view, params, slice(begin, end), n, observation, threads)
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


def _blocks(view: StoreView, n: int, k: int) -> list[tuple[int, int]]:
    """Core-point blocks of at most BLOCK_BYTES (a state of k components over n epochs)."""
    per_row = max(1, n) * 8 * (10 + 3 * k + (k + 1) * (k + 2) // 2)  # the shared state's moments at most
    return view.blocks(per_row, BLOCK_BYTES)


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
    with writing(store, "kalman", st.KALMAN_VARIABLES, "Kalman variables") as view:
        if not options.from_scratch:  # a half-written run is resumed from nothing but replaced whole
            integrity.require_whole(view.group, st.KALMAN_VARIABLES, store)
        n = view.n_epochs
        if n == 0:
            raise UsageError(f"{store} has no epoch to filter")
        days = view.days("the Kalman filter")
        params = view.engine_params()
        confidence = params.confidence if options.confidence is None else options.confidence
        reference = _reference(view, n)
        resume, q = _resumable(view.group, options, n)
        note = ""
        if q is None:
            if options.process_noise == "auto":
                sample = _sample(view, params, n, options.observation, threads)
                fit = _kalman_params(options.model, options.noise, 0.0, options.observation, reference=reference,
                                     params=params)
                q, note = fit_process_noise(sample, days, fit, threads)
            else:
                q = float(options.process_noise)
        source = "auto" if options.process_noise == "auto" else "given"
        _require_representable(q, days, options.model)
        run = _Run(options, q, source, confidence, params, days, resume, threads, reference)
        done = _write(view, run)
        removed = [name for name in st.KALMAN_VARIABLES if name in view.group and name not in done]
        view.publish(done, removed)
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



def _write(view: StoreView, run: _Run) -> list[str]:
    """The run's variables in the staging folder, block by block of core points."""
    model, k, observation = run.options.model, MODELS[run.options.model], run.options.observation
    size = k + (observation == "shared")  # the state: d, d' (d'') and, shared, b
    n, m = len(run.days), size + size * (size + 1) // 2
    names = variables(model)
    p = _kalman_params(model, run.options.noise, run.q, observation, reference=run.reference, params=run.params)
    common = {"model": model, "noise": run.options.noise, "observation": observation, "process_noise": run.q,
              "process_noise_source": run.source, "epochs": int(n), "time_unit": "days since the first epoch"}
    if observation == "shared":  # the step test's false-alarm rate (kalman.hpp), which the estimates depend on
        common["step_false_alarm"] = p.step_false_alarm
    out = {}
    for j, (mean, sd) in enumerate(STATE_VARIABLES[:k]):
        what = ("distance", "rate (per day)", "acceleration (per day^2)")[j]
        out[mean] = view.staged(mean, np.float64, np.nan, dict(common, long_name=f"Kalman-smoothed {what}"))
        out[sd] = view.staged(sd, np.float64, np.nan,
                              dict(common, long_name=f"standard deviation of the smoothed {what}"))
    out[SIGNIFICANT] = view.staged(
        SIGNIFICANT, np.int8, -1,
        dict(common, confidence=run.confidence, _FillValue=-1,
             long_name="|kalman_distance| > z_C kalman_distance_sigma (1 yes, 0 no, -1 no estimate)"))
    # The filtered moments: (core, epoch, moment), whole along moment.
    out[MOMENTS] = view.staged(MOMENTS, np.float64, np.nan,
                               dict(common, long_name="filtered state at each epoch: mean, then the covariance's "
                                                      "upper triangle row by row"), extra=("kalman_moment", m))
    z_c = z_critical(run.confidence)
    kept = view.group[MOMENTS] if run.resume else None
    fault_hook.checkpoint("store-write")
    for begin, end in _blocks(view, n, k):
        block = _observations(view, run.params, slice(begin, end), n, observation, run.threads)
        moments = np.full((end - begin, n, m), np.nan)
        if kept is not None:
            moments[:, :run.resume] = view.read(MOMENTS, (slice(begin, end), slice(0, run.resume)))
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
