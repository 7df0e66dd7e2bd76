"""The series report's Kalman part (docs/series.md, "Kalman filter" and "py4dgeo archives and the
report"): after `m3c2 series kalman`, each chosen core point's plot shows the raw distances with
their LOD bars and the smoothed series with its band kalman_distance +- z_C sigma at the
confidence the run recorded (the one its `kalman_significant` flags use: the band and the flags
say the same thing), the plotted numbers embedded beside the figure as JSON (a reader of the page
gets the values, not only a picture), and one paragraph states the model, the process noise and
the share of core points significant at the last epoch. A store without the Kalman variables
never reaches this module: its report is the one it always was."""
from __future__ import annotations

import html
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from ..base.errors import M3C2Error
from ..base.quantiles import z_critical
from . import integrity
from . import store as st

MEAN, SIGMA = st.KALMAN_VARIABLES[0:2]
SIGNIFICANT = st.KALMAN_VARIABLES[6]
#: The state each model carries (series/kalman.py's MODELS), as the report names it.
STATES = {"velocity": "[d, d']", "acceleration": "[d, d', d'']"}
#: What each observation model (series/kalman.py's OBSERVATIONS) means, in the paragraph.
OBSERVATION_TEXT = {
    "shared": "shared observation: the state also holds b, the reference cylinder's error that every distance "
              "shares, and each epoch is weighted by the core point's scatter pooled over its epochs (calibrated band)",
    "independent": "independent observation: each epoch weighted by its own LOD as independent noise, the model of "
                   "kalman4d and the tum-rsa fork (over-confident where the reference is no denser than the epochs)"}


@dataclass(frozen=True)
class KalmanRun:
    """What the store records of its Kalman run (the attributes series/kalman.py writes)."""
    model: str
    noise: str
    process_noise: float
    source: str  # "auto" (maximum likelihood) or "given"
    confidence: float
    epochs: int  # the epochs the run covered; later ones were added since (NaN, flag -1)
    observation: str = "independent"  # a run from before --observation was independent

    @property
    def z(self) -> float:
        return z_critical(self.confidence)


def kalman_run(store: Path, group) -> KalmanRun | None:
    """The store's Kalman run, None when it has none; a half-written or incomplete set is an error
    naming the fix (drawn, it would mix two runs)."""
    # the mark first: a first run killed while publishing has marked its variables before the
    # store's metadata lists them
    integrity.require_whole(group, st.KALMAN_VARIABLES, store)
    if MEAN not in group:
        return None
    missing = [name for name in (SIGMA, SIGNIFICANT) if name not in group]
    if missing:
        raise M3C2Error(f"{store}: {MEAN} without {', '.join(missing)}; rerun m3c2 series kalman {store} "
                        f"--from-scratch")
    attrs, flags = group[MEAN].attrs, group[SIGNIFICANT].attrs
    try:
        return KalmanRun(str(attrs["model"]), str(attrs["noise"]), float(attrs["process_noise"]),
                         str(attrs["process_noise_source"]), float(flags["confidence"]), int(attrs["epochs"]),
                         str(attrs.get("observation", "independent")))
    except (KeyError, TypeError, ValueError) as e:
        raise M3C2Error(f"{store}: the Kalman variables lack their run's record ({e}); rerun m3c2 series kalman "
                        f"{store} --from-scratch") from None


def _state(run: KalmanRun) -> str:
    state = STATES.get(run.model, "?")
    return state[:-1] + ", b]" if run.observation == "shared" and state != "?" else state


def _percent(confidence: float) -> str:
    return f"{100 * confidence:g} %"


def summary(store: Path, group, run: KalmanRun, n: int) -> list[str]:
    """The paragraph on the run: model, process noise, band, and the share flagged at the last epoch."""
    source = "chosen by maximum likelihood" if run.source == "auto" else "given"
    text = (f"Smoothed by <code>m3c2 series kalman</code> (Kalman filter and Rauch-Tung-Striebel smoother, "
            f"docs/series.md): model {html.escape(run.model)} (state {_state(run)}), "
            f"{html.escape(OBSERVATION_TEXT.get(run.observation, run.observation))}, "
            f"{html.escape(run.noise)} process noise q = {run.process_noise:.6g} ({source}); bands "
            f"kalman_distance ± {run.z:.4f} σ, the {_percent(run.confidence)} level of kalman_significant.")
    if n:
        flags = st.read(store, group, SIGNIFICANT, (slice(None), n - 1))
        estimated = int((flags >= 0).sum())
        flagged = int((flags == 1).sum())
        share = f" ({100 * flagged / estimated:.1f} %)" if estimated else ""
        text += (f" At the last epoch ({n - 1}), {flagged} of the {estimated} core points with an estimate{share} "
                 f"are kalman_significant (|d| > {run.z:.4f} σ); {len(flags) - estimated} have no estimate.")
    if run.epochs < n:
        text += (f" The run covers the first {run.epochs} of the {n} epochs: rerun <code>m3c2 series kalman "
                 f"{html.escape(str(store))}</code> for the epochs added since.")
    return ["<h2>Kalman filter</h2>", f"<p>{text}</p>"]


@dataclass(frozen=True)
class CoreSeries:
    """One core point's plotted numbers."""
    core: int
    distance: np.ndarray
    lod: np.ndarray
    smoothed: np.ndarray
    sigma: np.ndarray


def read_core(store: Path, group, core: int, n: int, distance, lod) -> CoreSeries:
    sel = (core, slice(0, n))
    return CoreSeries(core, distance, lod, st.read(store, group, MEAN, sel), st.read(store, group, SIGMA, sel))


def figure(x, xlabel: str, series: CoreSeries, run: KalmanRun, title: str) -> Figure:
    fig = Figure(figsize=(7, 2.6))
    ax = fig.add_subplot()
    half = run.z * series.sigma
    ax.fill_between(x, series.smoothed - half, series.smoothed + half, color="C1", alpha=0.25, lw=0,
                    label=f"{_percent(run.confidence)} band")
    ax.errorbar(x, series.distance, yerr=series.lod, fmt="o", ms=2.5, color="C0", ecolor="0.6", elinewidth=0.8,
                capsize=0, label="distance ± LOD")
    ax.plot(x, series.smoothed, color="C1", lw=1.2, label="Kalman-smoothed")
    ax.axhline(0, color="0.5", lw=0.5)
    ax.set_title(title, fontsize=9)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("distance")
    ax.legend(fontsize=7, loc="best")  # a series with a pile or a slump can fill any fixed corner
    fig.tight_layout()
    return fig


def _values(a: np.ndarray) -> list:
    # repr of a float64 reads back to the same bits; NaN (no value) is JSON's null.
    return [None if not np.isfinite(v) else float(v) for v in np.asarray(a, dtype=np.float64)]


def data_block(x, series: CoreSeries, run: KalmanRun) -> str:
    """The plotted numbers as JSON in the page (a script element browsers do not run)."""
    half = run.z * series.sigma
    times = [str(t) for t in x] if np.issubdtype(np.asarray(x).dtype, np.datetime64) else None
    data = {"core": series.core, "time": times, "distance": _values(series.distance), "lod": _values(series.lod),
            "kalman_distance": _values(series.smoothed), "kalman_distance_sigma": _values(series.sigma),
            "confidence": run.confidence, "z": run.z,
            "band_low": _values(series.smoothed - half), "band_high": _values(series.smoothed + half)}
    text = json.dumps(data, allow_nan=False, separators=(",", ":")).replace("</", "<\\/")
    return f'<script type="application/json" class="m3c2-kalman" data-core="{series.core}">{text}</script>'
