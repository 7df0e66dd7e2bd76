"""`m3c2 series report`: a self-contained HTML page of a store: per chosen core point its
distance series with the LOD band (change is detected outside +-LOD, section 3.3) and, after
`m3c2 series objects`, a map of the objects' extents and each object's series."""
from __future__ import annotations

import base64
import csv
import html
from pathlib import Path

import numpy as np

from ..optional import require

require("matplotlib", extra="report", purpose="the series report's figures")
from matplotlib.figure import Figure  # noqa: E402

from ..report.figures import png
from . import store as st

MAX_OBJECT_PLOTS = 12


def _img(fig: Figure, alt: str) -> str:
    return f'<img alt="{html.escape(alt)}" src="data:image/png;base64,{base64.b64encode(png(fig)).decode()}">'


def _x_axis(group, n):
    t = np.asarray(group["time"][:n])
    if n and (t != st.NAT).all():
        return t.astype("datetime64[us]"), "time (UTC)"
    return np.arange(n), "epoch"


def _core_figure(x, xlabel, d, lod, title) -> Figure:
    fig = Figure(figsize=(7, 2.6))
    ax = fig.add_subplot()
    ax.fill_between(x, -lod, lod, color="0.85", label="±LOD", step=None)
    ax.plot(x, d, color="C0", lw=1, label="distance")
    ax.axhline(0, color="0.5", lw=0.5)
    ax.set_title(title, fontsize=9)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("distance")
    ax.legend(fontsize=7, loc="upper left")
    fig.tight_layout()
    return fig


def write_report(store: Path, output: Path, cores=None, objects_table=None) -> None:
    group = st.open_group(store)
    n_core, n = group["distance"].shape
    x, xlabel = _x_axis(group, n)
    if cores is None:
        cores = sorted({0, n_core // 2, n_core - 1}) if n_core else []
    parts = [f"<h1>M3C2 time series: {html.escape(str(store))}</h1>",
             f"<p>{n_core} core points, {n} epochs. Parameters: <code>{html.escape(group.attrs.get('parameters', ''))}"
             f"</code></p>", "<h2>Core points</h2>"]
    for c in cores:
        if not 0 <= c < n_core:
            from ..errors import UsageError
            raise UsageError(f"--core {c} is not a core point of {store} (0..{n_core - 1})")
        d = np.asarray(group["distance"][c, :n])
        lod = np.asarray(group["lod"][c, :n])
        xyz = [float(group[a][c]) for a in "xyz"]
        parts.append(_img(_core_figure(x, xlabel, d, lod, f"core point {c} at ({xyz[0]:.3f}, {xyz[1]:.3f}, "
                                                            f"{xyz[2]:.3f})"), f"core {c}"))
    if objects_table is not None:
        parts += _objects_section(group, Path(objects_table), x, xlabel, n)
    Path(output).write_text("<!doctype html><meta charset='utf-8'><title>m3c2 series report</title>"
                            "<body style='font-family:sans-serif'>" + "\n".join(parts) + "</body>")


def _objects_section(group, table: Path, x, xlabel, n) -> list[str]:
    rows = list(csv.DictReader(open(table)))
    members_path = table.with_name(table.stem + "_members.csv")
    members: dict[int, list[int]] = {}
    for r in csv.DictReader(open(members_path)):
        members.setdefault(int(r["object"]), []).append(int(r["core"]))
    xy = np.column_stack([np.asarray(group["x"][:]), np.asarray(group["y"][:])])
    fig = Figure(figsize=(6, 5))
    ax = fig.add_subplot()
    ax.scatter(xy[:, 0], xy[:, 1], s=1, color="0.85")
    for k, r in enumerate(rows):
        idx = np.array(members.get(int(r["object"]), []), dtype=int)
        ax.scatter(xy[idx, 0], xy[idx, 1], s=2, label=f"object {r['object']} (epochs {r['start_epoch']}-{r['end_epoch']})")
    ax.set_aspect("equal")
    ax.set_title("extent of the objects (all epochs)", fontsize=9)
    if len(rows) <= 15:
        ax.legend(fontsize=6, markerscale=4)
    fig.tight_layout()
    out = ["<h2>4D objects-by-change</h2>", f"<p>{len(rows)} objects ({html.escape(str(table))})</p>",
           _img(fig, "object extents")]
    for r in rows[:MAX_OBJECT_PLOTS]:
        idx = np.array(members.get(int(r["object"]), []), dtype=int)
        d = np.asarray(group["distance"].get_orthogonal_selection((idx, slice(0, n))))
        lod = np.asarray(group["lod"].get_orthogonal_selection((idx, slice(0, n))))
        f = _core_figure(x, xlabel, np.nanmedian(d, axis=0), np.nanmedian(lod, axis=0),
                         f"object {r['object']}: median of {len(idx)} core points, epochs {r['start_epoch']}-"
                         f"{r['end_epoch']}")
        ax = f.axes[0]
        s, e = int(r["start_epoch"]), int(r["end_epoch"])
        ax.axvspan(x[s], x[e], color="C1", alpha=0.15)
        out.append(_img(f, f"object {r['object']}"))
    return out
