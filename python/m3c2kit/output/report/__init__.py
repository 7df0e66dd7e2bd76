"""A visual report of an M3C2 run: ONE self-contained HTML file (PNG figures embedded as base64,
inline CSS, plotly.js inline for the 3D view, no external resource: it works offline) and
optionally the same figures as PNG files.

    m3c2 compare REF CMP -o change.laz ... --report change.html [--report-png figs/change]

Figures: top view of the distance on a symmetric logarithmic diverging scale (as Fig. 10 of
Lague et al. 2013: the log scale starts at the minimum detectable change), non-significant
points grey; top view of the LOD; top view of the status; histograms of distance and LOD; the
distribution of the normal scale and of xi = D / sigma(D) with the thresholds 20 and 25 of
section 5.1; an interactive 3D view of the core points coloured by distance (plotly, the
``report`` extra). Top views carry axis names and units from the CRS, a scale bar and a north
arrow. Then a summary table and every parameter in effect, with the version. See docs/report.md.

Top views draw at most ``max_points`` core points (200,000 by default): above that a uniform
random subsample with a fixed seed, said in the caption. Histograms and tables use every point.
"""
from __future__ import annotations

import base64
import html
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ...base.errors import CloudWriteError, UsageError
from ...engine.result import STATUS_NAMES, Result
from ..lod_rates import expectation_text, run_expectation
from ..summary import multiple_testing, normal_accuracy

__all__ = ["Report", "build_report", "render_html", "write_report", "png_paths", "FIGURES", "MAX_PLOT_POINTS"]

MAX_PLOT_POINTS = 200_000
SEED = 0
#: Figure keys, in report order; PNG files are <prefix>_<key>.png.
FIGURES = ("distance", "lod", "status", "histograms", "normals")


@dataclass
class Report:
    title: str
    figures: list = field(default_factory=list)     # (key, heading, png bytes, caption)
    summary: list = field(default_factory=list)     # (name, value)
    status: list = field(default_factory=list)      # (code, name, count, percent)
    parameters: list = field(default_factory=list)  # (name, value)
    view3d: tuple | None = None                      # (plotly div HTML, caption), or ("", why missing)
    uncertainty: object | None = None                # report.uncertainty.UncertaintySection (pm, ep runs)


def png_paths(prefix: str | os.PathLike) -> dict[str, Path]:
    """<prefix>_<figure>.png for each figure (prefix may name a directory: figs/run1)."""
    text = os.fspath(prefix)
    prefix = Path(prefix)
    if prefix.name in ("", ".."):  # '', '.', '/', '..': no name to prefix (pathlib's ValueError, a traceback)
        raise UsageError(f"--report-png {text!r} names a folder, not a prefix: give e.g. {os.path.join(text, 'run1')!r} "
                         f"for {os.path.join(text, 'run1')}_distance.png, ...")
    return {key: prefix.with_name(f"{prefix.name}_{key}.png") for key in FIGURES}


def _fmt(v) -> str:
    if isinstance(v, float):
        return f"{v:.6g}"
    if isinstance(v, (list, tuple)):
        return ", ".join(_fmt(x) for x in v)
    return str(v)


def _pct(k: int, n: int) -> str:
    return f"{k} ({100.0 * k / n:.1f}%)" if n else str(k)


def _summary(result: Result, linthresh: float) -> list:
    n = len(result)
    d = np.asarray(result.distance, dtype=float)
    lod = np.asarray(result.lod, dtype=float)
    sig = np.asarray(result.significant, dtype=bool)
    ok, has_lod = np.isfinite(d), np.isfinite(lod)
    rows = [("core points", str(n)), ("with a distance", _pct(int(ok.sum()), n)),
            ("with a LOD", _pct(int(has_lod.sum()), n)),
            ("significant change (|distance| > LOD)", _pct(int(sig.sum()), n)),
            ("share significant among core points with a LOD",
             f"{100.0 * sig.sum() / has_lod.sum():.1f}%" if has_lod.any() else "n/a")]
    if ok.any():
        rows += [("median distance", _fmt(float(np.median(d[ok])))),
                 ("median |distance|", _fmt(float(np.median(np.abs(d[ok]))))),
                 ("distance min / max", f"{d[ok].min():.6g} / {d[ok].max():.6g}")]
    if sig.any():
        rows += [("median significant distance", _fmt(float(np.median(d[sig])))),
                 ("significant negative (erosion) / positive (deposition)",
                  f"{int(np.sum(sig & (d < 0)))} / {int(np.sum(sig & (d > 0)))}")]
    if has_lod.any():
        rows += [("median LOD", _fmt(float(np.median(lod[has_lod])))),
                 ("min LOD / 5th percentile of LOD", f"{lod[has_lod].min():.6g} / {np.percentile(lod[has_lod], 5):.6g}")]
    rows.append(("colour scale: linear below |distance| <", _fmt(linthresh)))
    for name, arr in (("median n1", result.n1), ("median n2", result.n2)):
        a = np.asarray(arr, dtype=float)[ok]
        if a.size:
            rows.append((name, _fmt(float(np.median(a)))))
    expected = run_expectation(result)
    if expected:
        rows.append(("expected false positives on unchanged surfaces", expectation_text(expected)))
    rows += [("multiple testing over the core points", text) for text in multiple_testing(result)]
    acc = normal_accuracy(result)
    if acc:
        rows += [("core points with a roughness sigma(D) (exactly planar: xi = inf)",
                  f"{acc['core_points']} ({acc['planar']})"),
                 ("xi = D / sigma(D) > 20", f"{100 * acc['xi_over_20']:.1f}%"),
                 ("xi > 25", f"{100 * acc['xi_over_25']:.1f}%"),
                 ("median predicted normal error E_norm (eq. 5)", f"{acc['median_e_norm_percent']:.3g}%")]
    return rows


def build_report(result: Result, *, grid=None, images=None, inputs: dict | None = None,
                 max_points: int = MAX_PLOT_POINTS, seed: int = SEED, title: str = "M3C2 change report",
                 crs: str | None = None, units: str | None = None, core_spacing=None,
                 view3d: bool = True) -> Report:
    """Draws the figures and tables of `result`. With `grid` and `images` (2D mode, see
    m3c2kit.run.raster) the top views are the rasters themselves. `crs` (the reference's CRS text)
    and `units` (its units hint) name the axes and units; without them the units are "unknown"."""
    from ...io.crs import crs_label, crs_units, parse_crs
    from . import cartography as K
    from . import figures as F
    from . import view3d as V
    from .parameters import effective_parameters

    parsed = parse_crs(crs)
    projected = bool(parsed is not None and parsed.is_projected)
    units = units or crs_units(crs)

    n = len(result)
    xy = np.asarray(result.core, dtype=float)[:, :2]
    if grid is None and n > max_points:
        plotted = np.sort(np.random.default_rng(seed).choice(n, size=max_points, replace=False))
        sampling = (f"{max_points:,} of {n:,} core points plotted (uniform random subsample, seed {seed}); "
                    "histograms and tables use all of them.")
    else:
        plotted = np.arange(n)
        sampling = (f"Raster of {grid.rows} x {grid.cols} cells of {grid.cell:g}." if grid is not None
                    else f"All {n:,} core points plotted.")
    view = F.TopView(xy, plotted, grid=grid, images=images, units=units, projected=projected)
    linthresh, vmax = F.distance_scale(result.distance, result.lod)
    norm = F.distance_norm(result.distance, result.lod)
    rep = Report(title=title)

    figs = []
    fig = view.scalar(result.distance, result.significant, norm, "RdBu", "M3C2 distance (significant changes)",
                      "distance (compared - reference)")
    figs.append(("distance", "Distance", fig,
                 f"M3C2 distance, top view, on a symmetric logarithmic diverging scale (RdBu: red = negative = "
                 f"erosion/lowering, blue = positive = deposition/rise along the normal): linear within "
                 f"±{linthresh:.4g} (the 5th percentile of the LOD, the minimum detectable change as in Fig. 10 of "
                 f"Lague et al. 2013), logarithmic beyond, saturating at ±{vmax:.4g} (99.5th percentile of "
                 f"|distance|). Grey: distance computed but not significant (|distance| <= LOD, or no LOD). "
                 f"White: no distance. {sampling}"))
    fig = view.scalar(result.lod, None, F.lod_norm(result.lod), "viridis", "level of detection (LOD)", "LOD",
                      grey_nonsignificant=False)
    figs.append(("lod", "Level of detection", fig,
                 f"Level of detection at the run's confidence, top view (2nd-98th percentile colour range, "
                 f"logarithmic when it spans more than a factor 3). High values: rough surfaces, few points, "
                 f"vegetation. White: no LOD. {sampling}"))
    fig = view.status(result.status, "status of each core point")
    figs.append(("status", "Status", fig, f"Why a core point has no distance or LOD (status codes, README). {sampling}"))
    notes: list = []
    fig = F.histograms(result.distance, result.lod, result.significant, notes)
    figs.append(("histograms", "Distributions of distance and LOD", fig,
                 "Histograms over all core points: distance (significant in blue stacked on non-significant in "
                 "grey, logarithmic counts) and LOD. " + "; ".join(notes) + "."))
    vertical = result.params.get("normal_source") == "vertical"
    fig = F.normals(result.normal_scale, result.xi, vertical)
    figs.append(("normals", "Normals", fig,
                 "Left: the normal scale D (diameter) chosen at each core point (multi-scale: the most planar "
                 "scale). Right: xi = D / sigma(D), the normal-accuracy indicator of section 5.1; the normal "
                 "orientation error stays below ~2% where xi > 20 (dashed orange) and ~1% where xi > 25 (red)."))
    for key, heading, fig, caption in figs:
        rep.figures.append((key, heading, F.png(fig), caption))
    if view3d:
        if V.available():
            rep.view3d = V.view_div(result.core, result.distance, vmax, K.unit_symbol(units), seed=seed)
        else:
            rep.view3d = ("", V.MISSING)

    rep.summary = _summary(result, linthresh)
    from .uncertainty import uncertainty_section
    rep.uncertainty = uncertainty_section(result)
    counts = result.status_counts()
    rep.status = [(k, name, counts.get(name, 0), 100.0 * counts.get(name, 0) / n if n else 0.0)
                  for k, name in enumerate(STATUS_NAMES)]
    rep.parameters = [(k, _fmt(v)) for k, v in (inputs or {}).items() if k != "reference CRS"]
    rep.parameters += [(k, _fmt(v)) for k, v in effective_parameters(
        result.params, core_spacing=core_spacing, crs_label=crs_label(crs) if crs else None, units=units)]
    return rep


_CSS = """
body{font-family:system-ui,-apple-system,"Segoe UI",Helvetica,Arial,sans-serif;margin:24px auto;max-width:1100px;
color:#222;padding:0 16px}
h1{font-size:1.5em;margin-bottom:.2em}h2{font-size:1.15em;margin-top:1.6em;border-bottom:1px solid #ddd}
table{border-collapse:collapse;font-size:.9em;margin:.5em 0}td,th{border:1px solid #ddd;padding:3px 8px;text-align:left}
th{background:#f4f4f4}td.num{text-align:right;font-variant-numeric:tabular-nums}
figure{margin:1em 0}figure img{max-width:100%;height:auto;border:1px solid #eee}
figcaption{font-size:.85em;color:#444;margin-top:.3em}.tables{display:flex;gap:32px;flex-wrap:wrap;align-items:flex-start}
"""


def render_html(rep: Report) -> str:
    """The report as one HTML document with every image inline (data: URIs)."""
    e = html.escape
    parts = ["<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
             f"<title>{e(rep.title)}</title><style>{_CSS}</style></head><body>", f"<h1>{e(rep.title)}</h1>",
             "<p>M3C2 (Lague, Brodu &amp; Leroux 2013). Distance = compared - reference along the oriented "
             "normal; significant where n1, n2 &ge; min points and |distance| &gt; LOD.</p>",
             '<h2>Summary</h2><div class="tables"><table><tr><th>quantity</th><th>value</th></tr>']
    parts += [f'<tr><td>{e(k)}</td><td class="num">{e(v)}</td></tr>' for k, v in rep.summary]
    parts.append("</table><table><tr><th>status</th><th>name</th><th>core points</th><th>%</th></tr>")
    parts += [f'<tr><td class="num">{k}</td><td>{e(name)}</td><td class="num">{c}</td><td class="num">{p:.1f}</td></tr>'
              for k, name, c, p in rep.status]
    parts.append("</table></div>")
    if rep.uncertainty is not None:
        parts += _uncertainty_html(rep.uncertainty)
    for key, heading, data, caption in rep.figures:
        b64 = base64.b64encode(data).decode("ascii")
        parts.append(f'<h2 id="{e(key)}">{e(heading)}</h2><figure><img alt="{e(heading)}" '
                     f'src="data:image/png;base64,{b64}"><figcaption>{e(caption)}</figcaption></figure>')
    if rep.view3d is not None:
        div, caption = rep.view3d
        parts.append(f'<h2 id="view3d">3D view</h2><figure class="view3d">{div}'
                     f"<figcaption>{e(caption)}</figcaption></figure>")
    parts.append("<h2>Parameters</h2><table><tr><th>parameter</th><th>value</th></tr>")
    parts += [f"<tr><td>{e(k)}</td><td>{e(v)}</td></tr>" for k, v in rep.parameters]
    parts.append("</table></body></html>")
    return "\n".join(parts)


def _uncertainty_html(section) -> list[str]:
    """The --uncertainty pm|ep section: the model, its inputs, the spreads' and LOD's distribution."""
    e = html.escape
    parts = ['<h2 id="uncertainty">Uncertainty model</h2>',
             f"<p>{e(section.model)} replaced eq. (1)'s spread: {e(section.description)} "
             "(docs/algorithm.md &sect;6.5).</p>",
             '<div class="tables"><table><tr><th>input</th><th>value</th></tr>']
    parts += [f"<tr><td>{e(k)}</td><td>{e(v)}</td></tr>" for k, v in section.inputs]
    parts.append("</table><table><tr><th>quantity</th><th>core points</th><th>min</th><th>5%</th><th>median</th>"
                 "<th>95%</th><th>max</th></tr>")
    parts += ["<tr><td>" + e(row[0]) + "</td>" + "".join(f'<td class="num">{e(v)}</td>' for v in row[1:]) + "</tr>"
              for row in section.distribution]
    parts.append("</table></div>")
    return parts


def write_report(result: Result, html_path=None, png_prefix=None, *, staged: dict | None = None, **kwargs) -> list:
    """Builds the report and writes the HTML to `html_path` and/or the PNGs to
    `<png_prefix>_<figure>.png`. `staged` maps each final path to the (temporary) path to write
    (m3c2kit.io.atomic.staged_outputs); without it, files are written in place. Returns the final paths."""
    rep = build_report(result, **kwargs)
    staged = staged or {}
    written = []
    if html_path is not None:
        target = Path(html_path)
        _write_bytes(target, staged.get(target, target), render_html(rep).encode("utf-8"))
        written.append(target)
    if png_prefix is not None:
        paths = png_paths(png_prefix)
        for key, _, data, _ in rep.figures:
            _write_bytes(paths[key], staged.get(paths[key], paths[key]), data)
            written.append(paths[key])
    return written


def _write_bytes(target: Path, path, data: bytes) -> None:
    """Writes `data` to `path` (a temporary of `target`); a failure (a full disk: the OS error has
    no file name) names the report file the user asked for (docs/errors.md, "Output")."""
    try:
        Path(path).write_bytes(data)
    except OSError as e:
        raise CloudWriteError(f"{target}: {e.strerror or e}") from None
