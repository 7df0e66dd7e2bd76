"""`m3c2 series report`: a self-contained HTML page of a store: per chosen core point its
distance series with the LOD band (change is detected outside +-LOD, section 3.3) and, after
`m3c2 series objects`, a map of the objects' extents and each object's series; after `m3c2 series
kalman`, the smoothed series with its band over the raw distances (report_kalman.py); after `m3c2
series tam3c2`, a row of TAM3C2 distances under each core point's plot (report_tam3c2.py)."""
from __future__ import annotations

import base64
import csv
import html
import warnings
from pathlib import Path

import numpy as np

from ..base.errors import M3C2Error, UsageError, printable
from ..io.atomic import atomic_output
from ..base.optional import require

require("matplotlib", extra="report", purpose="the series report's figures")
from matplotlib.figure import Figure  # noqa: E402

from ..output.report.figures import png
from . import report_kalman as rk
from . import report_tam3c2 as rt
from . import store as st
from .analysis import LABEL
from .outputs import members_path, require_objects_of

MAX_OBJECT_PLOTS = 12


def _img(fig: Figure, alt: str) -> str:
    return f'<img alt="{html.escape(alt)}" src="data:image/png;base64,{base64.b64encode(png(fig)).decode()}">'


def _x_axis(store, group, n):
    t = st.read(store, group, "time", slice(0, n))
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
    """The report of `store` at `output`, written whole or not at all (io.atomic); an objects table
    is read, and refused with a message naming it, before anything is drawn."""
    group = st.open_group(store)
    n_core, n = group["distance"].shape
    objects = read_objects(Path(objects_table), n_core, n) if objects_table is not None else None
    if objects_table is not None:  # read (and checked as a table) first: then, is it this store's?
        require_objects_of(store, group[LABEL].attrs if LABEL in group else None, Path(objects_table))
    x, xlabel = _x_axis(store, group, n)
    if cores is None:
        cores = sorted({0, n_core // 2, n_core - 1}) if n_core else []
    parts = [f"<h1>M3C2 time series: {html.escape(str(store))}</h1>",
             f"<p>{n_core} core points, {n} epochs. Parameters: <code>{html.escape(group.attrs.get('parameters', ''))}"
             f"</code></p>"]
    kalman = rk.kalman_run(store, group)  # None: the report is the one a store without the filter always had
    tam = rt.tam3c2_run(store, group, n)  # None: likewise without TAM3C2
    if kalman is not None:
        parts += rk.summary(store, group, kalman, n)
    if tam is not None:
        parts += rt.summary(store, group, tam, n)
    parts.append("<h2>Core points</h2>")
    for c in cores:
        if not 0 <= c < n_core:
            raise UsageError(f"--core {c} is not a core point of {store} (0..{n_core - 1})")
        # Every read through store.read: a damaged chunk is an error naming it, never drawn as NaN.
        d = st.read(store, group, "distance", (c, slice(0, n)))
        lod = st.read(store, group, "lod", (c, slice(0, n)))
        xyz = [float(st.read(store, group, a, c)) for a in "xyz"]
        title = f"core point {c} at ({xyz[0]:.3f}, {xyz[1]:.3f}, {xyz[2]:.3f})"
        if kalman is None:
            fig, blocks = _core_figure(x, xlabel, d, lod, title), []
        else:
            series = rk.read_core(store, group, c, n, d, lod)
            fig, blocks = rk.figure(x, xlabel, series, kalman, title), [rk.data_block(x, series, kalman)]
        if tam is not None:
            adaptive = rt.read_core(store, group, c, tam, d)
            rt.add_row(fig, x, xlabel, adaptive, tam)
            blocks.append(rt.data_block(x, adaptive, tam))
        parts += [_img(fig, f"core {c}"), *blocks]
    if objects is not None:
        parts += _objects_section(store, group, Path(objects_table), objects, x, xlabel, n)
    with atomic_output(output) as tmp:
        Path(tmp).write_text("<!doctype html><meta charset='utf-8'><title>m3c2 series report</title>"
                             "<body style='font-family:sans-serif'>" + "\n".join(parts) + "</body>")


#: The columns of the objects tables the report reads (series.analysis.write_tables writes them).
OBJECT_COLUMNS = ("object", "start_epoch", "end_epoch")
MEMBER_COLUMNS = ("object", "core")


def _csv_rows(path: Path, columns) -> list[dict]:
    """The rows of a CSV file with at least `columns`, or an M3C2Error naming the file and the problem."""
    if not path.exists():
        raise M3C2Error(f"{path}: no such file")
    if not path.is_file():  # a folder, a FIFO (reading would block), a device
        raise M3C2Error(f"{path}: not a regular file")
    try:
        with open(path, newline="", encoding="utf-8") as f:
            reader = csv.DictReader(f)
            missing = [c for c in columns if c not in (reader.fieldnames or ())]
            if missing:
                raise M3C2Error(f"{path}: not a table of m3c2 series objects: no column {', '.join(missing)} "
                                f"(header: {printable(','.join(reader.fieldnames or []))!s})")
            return list(reader)
    except (OSError, UnicodeDecodeError, csv.Error) as e:
        problem = e.strerror if isinstance(e, OSError) and e.strerror else str(e)
        raise M3C2Error(f"{path}: cannot read the table: {printable(problem)}") from None


def _integer(path: Path, line: int, row: dict, column: str, low: int, high: int) -> int:
    text = row.get(column)
    try:
        value = int(str(text).strip())
    except ValueError:
        raise M3C2Error(f"{path}: line {line}: {column} {printable(text)!r} is not an integer") from None
    if not low <= value <= high:
        raise M3C2Error(f"{path}: line {line}: {column} {value} is outside 0..{high} (the store's range)")
    return value


def read_objects(table: Path, n_core: int, n_epochs: int) -> tuple[list[dict], dict[int, list[int]]]:
    """The objects (object, start and end epoch) and each object's core points, checked against
    the store's sizes (an index outside them would fail while drawing, or draw nonsense)."""
    objects = []
    for line, row in enumerate(_csv_rows(table, OBJECT_COLUMNS), start=2):
        start = _integer(table, line, row, "start_epoch", 0, max(n_epochs - 1, 0))
        end = _integer(table, line, row, "end_epoch", start, max(n_epochs - 1, 0))
        objects.append({"object": _integer(table, line, row, "object", 0, 2**31 - 1), "start": start, "end": end})
    members_table = members_path(table)
    members: dict[int, list[int]] = {}
    for line, row in enumerate(_csv_rows(members_table, MEMBER_COLUMNS), start=2):
        obj = _integer(members_table, line, row, "object", 0, 2**31 - 1)
        members.setdefault(obj, []).append(_integer(members_table, line, row, "core", 0, max(n_core - 1, 0)))
    return objects, members


def _objects_section(store, group, table: Path, objects, x, xlabel, n) -> list[str]:
    rows, members = objects
    xy = np.column_stack([st.read(store, group, "x"), st.read(store, group, "y")])
    fig = Figure(figsize=(6, 5))
    ax = fig.add_subplot()
    ax.scatter(xy[:, 0], xy[:, 1], s=1, color="0.85")
    for r in rows:
        idx = np.array(members.get(r["object"], []), dtype=int)
        ax.scatter(xy[idx, 0], xy[idx, 1], s=2, label=f"object {r['object']} (epochs {r['start']}-{r['end']})")
    ax.set_aspect("equal")
    ax.set_title("extent of the objects (all epochs)", fontsize=9)
    if 0 < len(rows) <= 15:
        ax.legend(fontsize=6, markerscale=4)
    fig.tight_layout()
    out = ["<h2>4D objects-by-change</h2>", f"<p>{len(rows)} objects ({html.escape(str(table))})</p>",
           _img(fig, "object extents")]
    for r in rows[:MAX_OBJECT_PLOTS]:
        idx = np.array(members.get(r["object"], []), dtype=int)
        d = st.read(store, group, "distance", (idx, slice(0, n)))
        lod = st.read(store, group, "lod", (idx, slice(0, n)))
        with np.errstate(all="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # an object without members: an all-NaN median
            d_med, lod_med = np.nanmedian(d, axis=0), np.nanmedian(lod, axis=0)
        f = _core_figure(x, xlabel, d_med, lod_med,
                         f"object {r['object']}: median of {len(idx)} core points, epochs {r['start']}-{r['end']}")
        ax = f.axes[0]
        ax.axvspan(x[r["start"]], x[r["end"]], color="C1", alpha=0.15)
        out.append(_img(f, f"object {r['object']}"))
    return out
