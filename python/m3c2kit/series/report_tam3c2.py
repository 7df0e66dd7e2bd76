"""The series report's TAM3C2 part (docs/series.md, "TAM3C2" and "py4dgeo archives and the report"):
after `m3c2 series tam3c2`, each chosen core point's figure gets a second row under its plot (plain
or Kalman: both stay readable, each on its own axes) with the per-epoch M3C2 distance line and the
TAM3C2 distances with their ±LOD bars (filled where tam3c2_significant), the plotted numbers
embedded beside the figure as JSON, and one paragraph states the options the run recorded, its
completeness against per-epoch M3C2 (the paper's gain: more (core point, epoch) cells get a
distance), how many cells hold the epoch's own M3C2 (--fallback m3c2: tam3c2_window 0; drawn as
diamonds) and the share significant. A run older than the store's last epochs (`series add`
extends the variables with NaN / -1) is shown over the epochs it covered, and the page says so.
A store without the TAM3C2 variables never reaches past tam3c2_run: its report is the one it
always was."""
from __future__ import annotations

import html
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib.dates import ConciseDateFormatter
from matplotlib.figure import Figure

from ..base.errors import M3C2Error
from ..base.quantiles import z_critical
from . import integrity
from . import store as st

FROM_EPOCH = st.TAM3C2_FROM_EPOCH  # tam3c2_window of a cell holding the epoch's own M3C2

DISTANCE, LOD, SIGNIFICANT, WINDOW = st.TAM3C2_VARIABLES[0:4]
#: What the report reads of the run (the other variables may be absent without changing the page).
READ = (DISTANCE, LOD, SIGNIFICANT, WINDOW)


@dataclass(frozen=True)
class Tam3c2Run:
    """What the store records of its TAM3C2 run (the attributes series/tam3c2.py writes on each variable)."""
    min_points: int
    window_ratios: tuple
    normal_radii: tuple
    weights: str
    sigma_ratio: float
    space_time_ratio: float
    confidence: float
    epochs: int  # the epochs the run covered; later ones were added since (NaN, -1)
    lod: str = "z"  # the LOD's statistic (z, t, auto); runs before it was recorded used z
    fallback: str = "none"  # a short cell's numbers (none, m3c2); runs before it was recorded: none
    breaks: str = "none"  # where windows stop (none, changepoints); runs before it was recorded: none
    break_width: int = 0
    break_penalty: float = 0.0

    @property
    def z(self) -> float:
        return z_critical(self.confidence)


#: How the paragraph names the LOD's statistic (tam3c2.hpp, Tam3c2Lod).
LOD_WORDS = {"z": "with z", "t": "with Welch's t", "auto": "with Welch's t where a side has under 30 points, else z"}


def _rerun(group, store: Path) -> str:
    return integrity.rerun_command(group, DISTANCE, store)


def tam3c2_run(store: Path, group, n: int) -> Tam3c2Run | None:
    """The store's TAM3C2 run, None when it has none; half-written variables, a partial set or a
    missing record is an error naming the rerun (drawn, it would mix two runs or show a guess).
    The mark is checked first: a first run interrupted inside its publication leaves its
    variables marked but not yet in the committed metadata."""
    integrity.require_whole(group, st.TAM3C2_VARIABLES, store)
    if not any(name in group for name in st.TAM3C2_VARIABLES):
        return None
    missing = [name for name in READ if name not in group]
    if missing:
        raise M3C2Error(f"{store}: TAM3C2 variables without {', '.join(missing)}; rerun {_rerun(group, store)}")
    attrs = group[DISTANCE].attrs
    try:
        run = Tam3c2Run(int(attrs["min_points"]), tuple(float(r) for r in attrs["window_ratios"]),
                        tuple(float(r) for r in attrs["normal_radii"]), str(attrs["weights"]),
                        float(attrs["sigma_ratio"]), float(attrs["space_time_ratio"]), float(attrs["confidence"]),
                        int(attrs["epochs"]), str(attrs.get("lod", "z")), str(attrs.get("fallback", "none")),
                        str(attrs.get("breaks", "none")), int(attrs.get("break_width", 0)),
                        float(attrs.get("break_penalty", 0.0)))
    except (KeyError, TypeError, ValueError) as e:
        raise M3C2Error(f"{store}: the TAM3C2 variables lack their run's record ({e}); "
                        f"rerun {_rerun(group, store)}") from None
    if not 0 < run.epochs <= n:  # `add` only appends epochs: more than the store has is no run of this store
        raise M3C2Error(f"{store}: the TAM3C2 variables record {run.epochs} epochs, the store has {n}; "
                        f"rerun {_rerun(group, store)}")
    return run


def _list(values) -> str:
    return ", ".join(f"{v:g}" for v in values)


def _share(part: int, whole: int) -> str:
    return f" ({100 * part / whole:.1f} %)" if whole else ""


@dataclass(frozen=True)
class Counts:
    """Over the (core point, epoch) cells of the epochs the run covered."""
    cells: int
    m3c2: int  # cells with a per-epoch M3C2 distance
    tam3c2: int  # cells with a TAM3C2 distance
    significant: int  # of those, tam3c2_significant
    from_epoch: int = 0  # of those, the epoch's own M3C2 (tam3c2_window 0)


def counts(store: Path, group, run: Tam3c2Run) -> Counts:
    """Counted one block of core chunks at a time (memory: one block, whatever the store's size)."""
    n_core, rows = group[DISTANCE].shape[0], group[DISTANCE].chunks[0]
    m3c2 = tam = flagged = own = 0
    for begin in range(0, n_core, rows):
        sel = (slice(begin, min(n_core, begin + rows)), slice(0, run.epochs))
        m3c2 += int(np.isfinite(st.read(store, group, "distance", sel)).sum())
        tam += int(np.isfinite(st.read(store, group, DISTANCE, sel)).sum())
        flagged += int((st.read(store, group, SIGNIFICANT, sel) == 1).sum())
        own += int((st.read(store, group, WINDOW, sel) == FROM_EPOCH).sum())
    return Counts(n_core * run.epochs, m3c2, tam, flagged, own)


def summary(store: Path, group, run: Tam3c2Run, n: int) -> list[str]:
    """The paragraph on the run: its options, its completeness against per-epoch M3C2, the share significant."""
    weights = html.escape(run.weights)
    if run.weights != "none":  # the ratios act only on weights (docs/series.md, "TAM3C2")
        weights += f" (sigma ratio {run.sigma_ratio:g}, space-time ratio {run.space_time_ratio:g})"
    c = counts(store, group, run)
    text = (f"Time-adaptive M3C2 by <code>m3c2 series tam3c2</code> (docs/series.md, \"TAM3C2\"): required points "
            f"{run.min_points}, window ratios {_list(run.window_ratios)}, normal radii {_list(run.normal_radii)}, "
            f"weights {weights}, LOD {LOD_WORDS.get(run.lod, html.escape(run.lod))} at the "
            f"{100 * run.confidence:g} % level (z = {run.z:.4f}). "
            f"Completeness over the {run.epochs} epochs it covered: TAM3C2 gives a distance in {c.tam3c2} of the "
            f"{c.cells} (core point, epoch) cells{_share(c.tam3c2, c.cells)}, per-epoch M3C2 in "
            f"{c.m3c2}{_share(c.m3c2, c.cells)}; {c.significant} of the {c.tam3c2} TAM3C2 distances"
            f"{_share(c.significant, c.tam3c2)} are tam3c2_significant (|d| > LOD).")
    if run.fallback == "m3c2":
        text += (f" Fallback: {c.from_epoch} of the {c.tam3c2} distances{_share(c.from_epoch, c.tam3c2)} are the "
                 f"epoch's own M3C2 (its windows fell short of {run.min_points} points; tam3c2_window 0, "
                 f"drawn as diamonds).")
    else:
        text += " Fallback: none (the authors' rule: a short window keeps its own distance)."
    if run.breaks == "changepoints":
        text += (f" Windows stop at the change points of each core point's per-epoch M3C2 series (window "
                 f"{run.break_width} epochs, penalty {run.break_penalty:g}).")
    if run.epochs < n:
        text += (f" It was computed over the first {run.epochs} of {n} epochs; rerun "
                 f"<code>{html.escape(_rerun(group, store))}</code> for the epochs added since (not drawn).")
    return ["<h2>TAM3C2</h2>", f"<p>{text}</p>"]


@dataclass(frozen=True)
class CoreSeries:
    """One core point's plotted numbers: the M3C2 distance over every epoch, TAM3C2's over those it covered."""
    core: int
    distance: np.ndarray
    tam3c2: np.ndarray
    lod: np.ndarray
    significant: np.ndarray  # int8: 1, 0, -1 (no distance)
    window: np.ndarray  # int32: epochs aggregated, -1 without a distance


def read_core(store: Path, group, core: int, run: Tam3c2Run, distance) -> CoreSeries:
    sel = (core, slice(0, run.epochs))
    return CoreSeries(core, distance, *(st.read(store, group, name, sel) for name in READ))


def add_row(fig: Figure, x, xlabel: str, series: CoreSeries, run: Tam3c2Run) -> None:
    """A second axes row under the figure's plot, sharing its time axis: the plain M3C2 distance and
    TAM3C2's distances with ±LOD bars (hollow: not significant, filled: significant)."""
    top = fig.axes[0]
    rows = fig.add_gridspec(2, 1)
    top.set_subplotspec(rows[0])
    top.set_xlabel("")
    top.tick_params(labelbottom=False)
    ax = fig.add_subplot(rows[1], sharex=top)
    k, n = run.epochs, len(series.distance)
    xt = x[:k]
    ax.plot(x, series.distance, color="C0", lw=1, label="M3C2 distance")
    ax.errorbar(xt, series.tam3c2, yerr=series.lod, fmt="s", ms=3, color="C2", mfc="white", ecolor="C2",
                elinewidth=0.8, capsize=2, label="TAM3C2 ± LOD")
    flagged = series.significant == 1
    ax.plot(xt[flagged], series.tam3c2[flagged], "s", ms=3, color="C2", zorder=3, label="tam3c2_significant")
    own = series.window == FROM_EPOCH
    if own.any():
        ax.plot(xt[own], series.tam3c2[own], "D", ms=5, mfc="none", color="C3", zorder=4,
                label="the epoch's own M3C2 (fallback)")
    if k < n:  # from half-way to the first epoch added since: visible even for one added epoch
        ax.axvspan(x[k - 1] + (x[k] - x[k - 1]) / 2, x[n - 1], color="0.9", lw=0, label="added since the run")
    ax.axhline(0, color="0.5", lw=0.5)
    ax.set_title("TAM3C2" + (f", computed over the first {k} of {n} epochs" if k < n else ""), fontsize=9)
    if np.issubdtype(np.asarray(x).dtype, np.datetime64):  # the default date labels overlap over a day or more
        ax.xaxis.set_major_formatter(ConciseDateFormatter(ax.xaxis.get_major_locator()))
    ax.set_xlabel(xlabel)
    ax.set_ylabel("distance")
    ax.legend(fontsize=7, loc="best")
    fig.set_size_inches(7, 5.0)
    fig.tight_layout()


def _values(a: np.ndarray) -> list:
    # repr of a float64 reads back to the same bits; NaN (no value) is JSON's null.
    return [None if not np.isfinite(v) else float(v) for v in np.asarray(a, dtype=np.float64)]


def data_block(x, series: CoreSeries, run: Tam3c2Run) -> str:
    """The plotted numbers as JSON in the page (a script element browsers do not run): the M3C2
    distance and time over every epoch, the TAM3C2 arrays over the `epochs_covered` first."""
    times = [str(t) for t in x] if np.issubdtype(np.asarray(x).dtype, np.datetime64) else None
    data = {"core": series.core, "time": times, "epochs": len(series.distance), "epochs_covered": run.epochs,
            "distance": _values(series.distance), "tam3c2_distance": _values(series.tam3c2),
            "tam3c2_lod": _values(series.lod), "tam3c2_significant": [int(v) for v in series.significant],
            "tam3c2_window": [int(v) for v in series.window],
            "tam3c2_from_epoch": [int(v) == FROM_EPOCH for v in series.window], "fallback": run.fallback,
            "breaks": run.breaks, "confidence": run.confidence, "z": run.z}
    text = json.dumps(data, allow_nan=False, separators=(",", ":")).replace("</", "<\\/")
    return f'<script type="application/json" class="m3c2-tam3c2" data-core="{series.core}">{text}</script>'
