"""What makes a top view a map: axis names and units from the CRS, a scale bar, a north arrow,
and colour bars with enough labelled ticks."""
from __future__ import annotations

import math

import numpy as np

_SHORT = {"metre": "m", "foot": "ft", "US survey foot": "US ft", "kilometre": "km", "degree": "°"}


def unit_symbol(units: str | None) -> str | None:
    """"m" for "metre", "ft" for "foot", ...; the horizontal unit of a combined hint."""
    if not units:
        return None
    horizontal = units.split(" (horizontal)")[0]
    return _SHORT.get(horizontal, horizontal)


def axis_labels(projected: bool, units: str | None) -> tuple[str, str]:
    """("easting (m)", "northing (m)") for a projected CRS, ("x (m)", "y (m)") otherwise;
    "(units unknown)" without units."""
    sym = unit_symbol(units)
    suffix = f" ({sym})" if sym else " (units unknown)"
    return (("easting" if projected else "x") + suffix, ("northing" if projected else "y") + suffix)


def nice_length(span: float) -> float:
    """The largest 1, 2 or 5 x 10^k not above a fifth of `span` (a scale bar's length)."""
    target = span / 5.0
    if not target > 0 or not math.isfinite(target):
        return 1.0
    k = math.floor(math.log10(target))
    for m in (5.0, 2.0, 1.0):
        if m * 10**k <= target:
            return m * 10**k
    return 10**k


def add_scale_bar(ax, span: float, units: str | None) -> float:
    """A scale bar in the lower left corner, of a nice length (nice_length); returns it."""
    from mpl_toolkits.axes_grid1.anchored_artists import AnchoredSizeBar

    length = nice_length(span)
    sym = unit_symbol(units) or "units"
    bar = AnchoredSizeBar(ax.transData, length, f"{length:g} {sym}", "lower left", pad=0.4, borderpad=0.6,
                          sep=4, frameon=True, size_vertical=span / 300.0, fontproperties={"size": 9})
    bar.patch.set_alpha(0.8)
    ax.add_artist(bar)
    return length


def add_north_arrow(ax, projected: bool) -> None:
    """An arrow pointing up the y axis, labelled N when y is northing (a projected CRS), else +y
    (a local or unknown frame: north is not known)."""
    ax.annotate("N" if projected else "+y", xy=(0.95, 0.95), xytext=(0.95, 0.83), xycoords="axes fraction",
                ha="center", va="center", fontsize=11, fontweight="bold",
                arrowprops={"arrowstyle": "-|>", "color": "k", "lw": 1.5},
                bbox={"boxstyle": "round,pad=0.2", "fc": "white", "ec": "none", "alpha": 0.8})


def symlog_ticks(linthresh: float, vmax: float) -> list[float]:
    """Ticks of a symmetric-log colour bar: 0, +-linthresh, and 1-2-5 values up to +-vmax (at
    least 7 ticks), so that a reader can read values off it."""
    values = {0.0, linthresh, vmax}
    k = math.floor(math.log10(linthresh))
    while 10**k <= vmax * 1.0001:
        for m in (1.0, 2.0, 5.0):
            v = m * 10**k
            if linthresh * 1.2 < v < vmax * 0.95:
                values.add(v)
        k += 1
    pos = sorted(values - {0.0})
    if len(pos) > 9:  # keep it legible: thin to every other value, keeping the ends
        pos = pos[:1] + pos[1:-1][::2] + pos[-1:]
    return sorted([-v for v in pos] + [0.0] + pos)


def format_tick(v: float) -> str:
    return "0" if v == 0 else f"{v:.2g}" if abs(v) < 1e-2 or abs(v) >= 1e4 else f"{v:.3g}"


def log_ticks(lo: float, hi: float) -> list[float]:
    """1-2-5 ticks between lo and hi (and the ends): at least 4 on any logarithmic range."""
    values = {lo, hi}
    k = math.floor(math.log10(lo))
    while 10**k <= hi:
        for m in (1.0, 2.0, 5.0):
            v = m * 10**k
            if lo * 1.1 < v < hi * 0.9:
                values.add(v)
        k += 1
    return sorted(values)


def linear_ticks(lo: float, hi: float) -> list[float]:
    """About 6 evenly spaced round ticks (numpy's 1-2-5 steps)."""
    from matplotlib.ticker import MaxNLocator

    return [float(v) for v in MaxNLocator(nbins=6).tick_values(lo, hi) if lo - 1e-12 <= v <= hi + 1e-12]


def extent_span(xy: np.ndarray) -> float:
    return float(max(np.ptp(xy[:, 0]), np.ptp(xy[:, 1]), 1e-9)) if len(xy) else 1.0
