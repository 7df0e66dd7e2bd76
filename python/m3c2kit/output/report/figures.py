"""The report's figures, drawn with matplotlib's Agg canvas (no display, no pyplot state).

Each function returns a matplotlib Figure; :func:`png` turns one into PNG bytes.
"""
from __future__ import annotations

import io

import numpy as np

from ...base.optional import require

require("matplotlib", extra="report", purpose="drawing the report's figures")
from matplotlib import colors  # noqa: E402
from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from ...engine.result import STATUS_NAMES
from . import cartography as K

DPI = 100
GREY = "#a8a8a8"          # non-significant change
SIGNIFICANT = "#3b6ea8"   # significant change in histograms
XI_THRESHOLDS = ((20, "#e08a00"), (25, "#c0392b"))
XI_MAX = 1e4
STATUS_COLOURS = ("#2f7d32", "#9c27b0", "#6d4c41", "#f0a30a", "#d32f2f", "#0288d1")


def png(fig: Figure) -> bytes:
    FigureCanvasAgg(fig)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=DPI)
    return buf.getvalue()


def _finite(a) -> np.ndarray:
    a = np.asarray(a, dtype=float)
    return a[np.isfinite(a)]


def distance_scale(distance, lod) -> tuple[float, float]:
    """(linthresh, vmax) of the symmetric-log distance colour scale. linthresh is the 5th
    percentile of the LOD, a robust "minimum detectable change" (Fig. 10 starts its logarithmic
    scale at the lowest LOD95); vmax the 99.5th percentile of |distance|."""
    d = np.abs(_finite(distance))
    lod = _finite(lod)
    lod = lod[lod > 0]
    if lod.size:
        linthresh = float(np.percentile(lod, 5))
    elif np.any(d > 0):
        linthresh = float(np.percentile(d[d > 0], 5))
    else:
        linthresh = 1e-3
    vmax = float(np.percentile(d, 99.5)) if d.size else 10 * linthresh
    return linthresh, max(vmax, 10 * linthresh)


def distance_norm(distance, lod) -> colors.SymLogNorm:
    linthresh, vmax = distance_scale(distance, lod)
    return colors.SymLogNorm(linthresh=linthresh, linscale=1.0, vmin=-vmax, vmax=vmax, base=10)


def lod_norm(lod):
    v = _finite(lod)
    v = v[v > 0]
    if v.size == 0:
        return colors.Normalize(0, 1)
    lo, hi = np.percentile(v, [2, 98])
    if hi > 3 * lo > 0:
        return colors.LogNorm(lo, hi)
    return colors.Normalize(lo, hi if hi > lo else lo + 1e-12)


class TopView:
    """Where the top views draw: core point x, y (a seeded subsample when there are many), or a
    raster grid (2D mode), whose images are drawn pixel for pixel."""

    def __init__(self, xy: np.ndarray, plotted: np.ndarray, grid=None, images=None, units: str | None = None,
                 projected: bool = False):
        self.xy, self.plotted, self.grid, self.images = xy, plotted, grid, images
        self.units, self.projected = units, projected

    def _axes(self, title: str, wide: bool = True):
        x, y = self.xy[:, 0], self.xy[:, 1]
        w, h = max(np.ptp(x), 1e-9), max(np.ptp(y), 1e-9)
        aspect = min(max(h / w, 0.35), 2.5)
        fig = Figure(figsize=(9.0, 9.0 * aspect * 0.82 + 0.9), dpi=DPI, layout="constrained")
        ax = fig.add_subplot()
        ax.set_aspect("equal")
        ax.set_title(title, fontsize=11)
        xlabel, ylabel = K.axis_labels(self.projected, self.units)
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
        ax.ticklabel_format(useOffset=False, style="plain")
        ax.tick_params(labelsize=8)
        ax.set_facecolor("white")
        K.add_scale_bar(ax, K.extent_span(self.xy), self.units)
        K.add_north_arrow(ax, self.projected)
        return fig, ax

    def marker_size(self) -> float:
        """Square markers about one core-point spacing wide, so that the points tile the map."""
        n = max(int(self.plotted.size), 1)
        x, y = self.xy[:, 0], self.xy[:, 1]
        w, h = max(np.ptp(x), 1e-9), max(np.ptp(y), 1e-9)
        spacing = np.sqrt(w * h / n)
        aspect = min(max(h / w, 0.35), 2.5)
        axes_w, axes_h = 6.9, 9.0 * aspect * 0.82 - 0.6  # inches, as laid out by _axes
        points_per_unit = 72 * min(axes_w / w, axes_h / h)
        return float(np.clip((spacing * points_per_unit * 1.15) ** 2, 0.05, 40.0))

    def _extent(self):
        g = self.grid
        return (g.x0, g.x0 + g.cols * g.cell, g.y0, g.y0 + g.rows * g.cell)

    def scalar(self, values, significant, norm, cmap, title, label, grey_nonsignificant=True):
        """Top view of `values` coloured by `norm`/`cmap`; non-significant ones grey."""
        fig, ax = self._axes(title)
        cmap = _cmap(cmap) if isinstance(cmap, str) else cmap
        if self.grid is not None:
            image = self.images[label_key(label)]
            rgba = cmap(norm(np.ma.masked_invalid(image)))
            rgba[~np.isfinite(image)] = (1, 1, 1, 0)
            if grey_nonsignificant:
                sig = self.images["significant"]
                grey = np.isfinite(image) & (sig != 1)
                rgba[grey] = colors.to_rgba(GREY)
            ax.imshow(rgba, extent=self._extent(), origin="upper", interpolation="nearest")
        else:
            idx = self.plotted
            v = np.asarray(values, dtype=float)[idx]
            ok = np.isfinite(v)
            s = self.marker_size()
            if grey_nonsignificant:
                sig = np.asarray(significant, dtype=bool)[idx]
                g = ok & ~sig
                ax.scatter(self.xy[idx[g], 0], self.xy[idx[g], 1], s=s, c=GREY, marker="s", linewidths=0, in_layout=False,
                           rasterized=True)
                ok = ok & sig
            order = np.argsort(np.abs(v[ok]), kind="stable")  # the largest values on top
            sel = idx[ok][order]
            ax.scatter(self.xy[sel, 0], self.xy[sel, 1], s=s, c=np.asarray(values, dtype=float)[sel], cmap=cmap,
                       norm=norm, marker="s", linewidths=0, in_layout=False, rasterized=True)
            self._limits(ax)
        sm = _mappable(norm, cmap)
        cb = fig.colorbar(sm, ax=ax, shrink=0.85, extend="both", pad=0.01)
        ticks = colorbar_ticks(norm)
        cb.set_ticks(ticks, labels=[K.format_tick(t) for t in ticks])
        cb.ax.tick_params(labelsize=8)
        sym = K.unit_symbol(self.units)
        cb.set_label(f"{label} ({sym})" if sym else label)
        return fig

    def status(self, status, title):
        fig, ax = self._axes(title)
        cmap = colors.ListedColormap(STATUS_COLOURS[: len(STATUS_NAMES)])
        norm = colors.BoundaryNorm(np.arange(len(STATUS_NAMES) + 1) - 0.5, cmap.N)
        if self.grid is not None:
            image = self.images["status"].astype(float)
            image[self.images["status"] == 255] = np.nan
            ax.imshow(np.ma.masked_invalid(image), extent=self._extent(), origin="upper", cmap=cmap, norm=norm,
                      interpolation="nearest")
        else:
            idx = self.plotted
            ax.scatter(self.xy[idx, 0], self.xy[idx, 1], s=self.marker_size(), c=np.asarray(status)[idx], cmap=cmap,
                       norm=norm, marker="s", linewidths=0, in_layout=False, rasterized=True)
            self._limits(ax)
        present = set(np.unique(np.asarray(status)).tolist())
        from matplotlib.patches import Patch
        handles = [Patch(color=STATUS_COLOURS[k], label=f"{k} {name}") for k, name in enumerate(STATUS_NAMES)
                   if k in present]
        ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
        return fig

    def _limits(self, ax):
        x, y = self.xy[:, 0], self.xy[:, 1]
        pad_x, pad_y = 0.01 * max(np.ptp(x), 1e-9), 0.01 * max(np.ptp(y), 1e-9)
        ax.set_xlim(x.min() - pad_x, x.max() + pad_x)
        ax.set_ylim(y.min() - pad_y, y.max() + pad_y)


def colorbar_ticks(norm) -> list[float]:
    """Enough labelled ticks for the norm's scale (symmetric log, log or linear)."""
    if isinstance(norm, colors.SymLogNorm):
        return K.symlog_ticks(float(norm.linthresh), float(norm.vmax))
    if isinstance(norm, colors.LogNorm):
        return K.log_ticks(float(norm.vmin), float(norm.vmax))
    return K.linear_ticks(float(norm.vmin), float(norm.vmax))


def label_key(label: str) -> str:
    return "distance" if label.startswith("distance") else "lod"


def _cmap(name):
    import matplotlib
    return matplotlib.colormaps[name].copy()


def _mappable(norm, cmap):
    from matplotlib.cm import ScalarMappable
    return ScalarMappable(norm=norm, cmap=cmap)


def histograms(distance, lod, significant, clip_note: list) -> Figure:
    """Distance (significant stacked over non-significant, log counts) and LOD histograms, each
    over the 0.5-99.5 percentile range of ALL core points (not subsampled)."""
    fig = Figure(figsize=(11, 4.2), dpi=DPI, layout="constrained")
    ax1, ax2 = fig.subplots(1, 2)
    d = np.asarray(distance, dtype=float)
    ok = np.isfinite(d)
    sig = np.asarray(significant, dtype=bool) & ok
    if ok.any():
        lo, hi = np.percentile(d[ok], [0.5, 99.5])
        if hi <= lo:
            lo, hi = lo - 0.5, hi + 0.5
        bins = np.linspace(lo, hi, 101)
        ax1.hist([d[sig], d[ok & ~sig]], bins=bins, stacked=True, color=[SIGNIFICANT, GREY],
                 label=["significant", "not significant"])
        ax1.set_yscale("log")
        ax1.axvline(0, color="k", lw=0.6)
        ax1.axvline(np.median(d[ok]), color="k", ls="--", lw=1, label=f"median {np.median(d[ok]):.4g}")
        ax1.legend(fontsize=8)
        outside = int(np.count_nonzero((d[ok] < lo) | (d[ok] > hi)))
        clip_note.append(f"distance axis {lo:.4g} to {hi:.4g} (0.5-99.5 percentiles; {outside} points outside)")
    else:
        _empty(ax1, "no distance computed")
    ax1.set_xlabel("distance (compared - reference, along the normal)")
    ax1.set_ylabel("core points (log scale)")
    ax1.set_title("distance", fontsize=11)
    v = _finite(lod)
    if v.size:
        hi = float(np.percentile(v, 99.5))
        ax2.hist(v, bins=np.linspace(0, hi if hi > 0 else 1, 101), color="#5b8c5a")
        ax2.axvline(np.median(v), color="k", ls="--", lw=1, label=f"median {np.median(v):.4g}")
        ax2.legend(fontsize=8)
        clip_note.append(f"LOD axis 0 to {hi:.4g} (99.5 percentile)")
    else:
        _empty(ax2, "no LOD computed")
    ax2.set_xlabel("level of detection")
    ax2.set_ylabel("core points")
    ax2.set_title("LOD", fontsize=11)
    return fig


def normals(normal_scale, xi, vertical: bool) -> Figure:
    """Distribution of the normal scale D chosen at each core point, and of xi = D / sigma(D)
    with the thresholds 20 and 25 of section 5.1."""
    fig = Figure(figsize=(11, 4.2), dpi=DPI, layout="constrained")
    ax1, ax2 = fig.subplots(1, 2)
    scales = _finite(normal_scale)
    if scales.size:
        values, counts = np.unique(scales, return_counts=True)
        labels = [f"{v:.4g}" for v in values]
        ax1.bar(range(len(values)), 100.0 * counts / counts.sum(), color="#6a5acd", width=0.6)
        ax1.set_xlim(-0.5 - 0.5 * (len(values) < 3), len(values) - 0.5 + 0.5 * (len(values) < 3))
        ax1.set_xticks(range(len(values)), labels, rotation=45 if len(values) > 8 else 0, fontsize=8)
        ax1.set_ylabel("% of core points with a normal")
    else:
        _empty(ax1, "normals imposed (vertical): no normal scale" if vertical else "no normal computed")
    ax1.set_xlabel("normal scale D (diameter)")
    ax1.set_title("normal scale", fontsize=11)
    x = np.asarray(xi, dtype=float)
    x = x[~np.isnan(x) & (x > 0)]  # xi = inf (sigma(D) = 0, exactly planar) stays: it is > 25
    if x.size:
        # Near-perfect planes (water, flat roofs) have sigma(D) ~ 0 and xi up to 1e10: draw
        # xi > XI_MAX in the last bin so that the thresholds stay readable.
        top = min(max(x.max(), 40.0), XI_MAX)
        bins = np.geomspace(min(x[np.isfinite(x)].min(initial=10.0), 10.0), top, 81)
        ax2.hist(np.minimum(x, top), bins=bins, color="#7f7f7f")
        if x.max() > XI_MAX:
            ax2.text(0.99, 0.6, f"{100 * np.mean(x > XI_MAX):.1f}% above {XI_MAX:g}\n(last bin)", ha="right",
                     transform=ax2.transAxes, fontsize=8, color="#444")
        ax2.set_xscale("log")
        for t, c in XI_THRESHOLDS:
            ax2.axvline(t, color=c, ls="--", lw=1.5, label=f"xi = {t}: {100 * np.mean(x > t):.1f}% above")
        ax2.legend(fontsize=8)
    else:
        _empty(ax2, "normals imposed (vertical): no roughness" if vertical else "no roughness computed")
    ax2.set_xlabel("xi = D / sigma(D)")
    ax2.set_ylabel("core points")
    ax2.set_title("normal accuracy indicator xi (section 5.1)", fontsize=11)
    return fig


def _empty(ax, text: str) -> None:
    ax.text(0.5, 0.5, text, ha="center", va="center", transform=ax.transAxes, color="#555")
    ax.set_xticks([])
    ax.set_yticks([])
