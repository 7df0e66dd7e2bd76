"""An interactive 3D view of the core points coloured by distance, for cliffs and overhangs a top
view hides: plotly's WebGL scatter, with plotly.js written into the page (no network).

plotly comes with the ``report`` extra (``pip install m3c2kit[report]``); without it the report
says so in place of the view.
"""
from __future__ import annotations

import numpy as np

#: Points drawn in the 3D view at most (a seeded uniform subsample above: WebGL stays fluid).
MAX_3D_POINTS = 60_000
#: The 3D view's element id in the report (the only one of its kind there).
DIV_ID = "m3c2-view3d"
MISSING = "The interactive 3D view needs plotly: pip install 'm3c2kit[report]' (or pip install plotly)."


def available() -> bool:
    try:
        import plotly  # noqa: F401
    except ImportError:
        return False
    return True


def view_div(core: np.ndarray, distance: np.ndarray, vmax: float, units_symbol: str | None, *,
             max_points: int = MAX_3D_POINTS, seed: int = 0) -> tuple[str, str]:
    """(HTML div with plotly.js inline, caption). Points without a distance are drawn small
    and grey; the colour scale is the diverging RdBu of the top view (red = negative),
    symmetric and linear in +-vmax."""
    import plotly.graph_objects as go
    import plotly.io as pio

    n = len(core)
    idx = np.arange(n)
    if n > max_points:
        idx = np.sort(np.random.default_rng(seed).choice(n, size=max_points, replace=False))
    xyz = np.asarray(core, dtype=float)[idx]
    d = np.asarray(distance, dtype=float)[idx]
    ok = np.isfinite(d)
    origin = xyz.min(axis=0) if len(xyz) else np.zeros(3)  # WebGL is float32: draw local coordinates
    local = xyz - origin
    unit = f" ({units_symbol})" if units_symbol else ""
    traces = [go.Scatter3d(x=local[ok, 0], y=local[ok, 1], z=local[ok, 2], mode="markers", name="distance",
                           marker={"size": 2, "color": d[ok], "colorscale": "RdBu", "cmin": -vmax, "cmax": vmax,
                                   "colorbar": {"title": {"text": f"distance{unit}"}, "nticks": 9}},
                           hovertemplate="distance %{marker.color:.4g}<extra></extra>")]
    if (~ok).any():
        traces.append(go.Scatter3d(x=local[~ok, 0], y=local[~ok, 1], z=local[~ok, 2], mode="markers",
                                   name="no distance", marker={"size": 1.5, "color": "#b0b0b0"}, hoverinfo="skip"))
    fig = go.Figure(traces)
    fig.update_layout(scene={"aspectmode": "data", "xaxis_title": f"x - {origin[0]:.6g}{unit}",
                             "yaxis_title": f"y - {origin[1]:.6g}{unit}", "zaxis_title": f"z - {origin[2]:.6g}{unit}"},
                      margin={"l": 0, "r": 0, "t": 10, "b": 0}, height=620, legend={"x": 0, "y": 1})
    # A fixed element id (plotly draws a random one): the same run writes the same report, byte for
    # byte, in memory, in tiles or on Dask (docs/report.md).
    div = pio.to_html(fig, include_plotlyjs=True, full_html=False, config={"displaylogo": False}, div_id=DIV_ID)
    sampled = (f"{len(idx):,} of {n:,} core points (uniform random subsample, seed {seed})" if n > len(idx)
               else f"all {n:,} core points")
    caption = (f"Interactive 3D view of {sampled}, coloured by distance (RdBu, linear in ±{vmax:.4g}); grey: no "
               f"distance. Drag to rotate, scroll to zoom. Coordinates relative to ({origin[0]:.6g}, "
               f"{origin[1]:.6g}, {origin[2]:.6g}). plotly.js is embedded: the file works offline.")
    return div, caption
