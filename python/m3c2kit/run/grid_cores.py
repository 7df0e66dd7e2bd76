"""2D mode's grid of core points (paper section 6.1.2, m3c2kit.run.raster) computed by streaming the
reference, for tiled runs: the same Grid, bit for bit, as m3c2kit.run.raster.grid_core_points on the
whole cloud (the engine's src/core_points/grid.cpp).

The engine's grid depends on the points only through their extent (x0, y0, rows, cols) and, per
non-empty cell, the median z of its points (an order-free statistic of the sorted z). So:

1. one pass gives the extent; the engine, handed the two corners of that box, returns the very
   x0, y0, rows and cols (and refuses a cell too small, or rasters too large, with the messages of
   an in-memory run);
2. a second pass spills each point's cell and z into bands of grid rows (m3c2kit.run.spill);
3. each band, read back alone, gives its cells' median z with the engine's formula
   (sorted_quantile(z, 0.5): z[lo] + (h - lo) (z[lo + 1] - z[lo]), h = (n - 1) / 2), and their
   centres (x0 + (col + 0.5) cell, ...); bands in row order give the engine's row-major order.

Memory: one band's points (a band holds about a streaming chunk's worth of points when the
reference is spread evenly over its rows) and the grid itself (one core point per non-empty cell).
"""
from __future__ import annotations

import math

import numpy as np

from .. import engine
from . import raster
from .spill import SpillFolder

__all__ = ["GridCores", "streamed_grid"]

#: A band's spill rows: the cell's row-major number and the point's z.
_CELL_Z = np.dtype([("cell", np.uint64), ("z", np.float64)])


class GridCores:
    """The core points of a tiled run on a --grid of side `cell` over the reference (2D mode)."""

    def __init__(self, cell: float):
        self.cell = float(cell)

    def __repr__(self) -> str:
        return f"GridCores({self.cell!r})"


def _extent(source, rows: int) -> tuple[np.ndarray, np.ndarray, int]:
    lo, hi, n = np.full(3, np.inf), np.full(3, -np.inf), 0
    for xyz in source.chunks(rows):
        lo, hi = np.minimum(lo, xyz.min(axis=0)), np.maximum(hi, xyz.max(axis=0))
        n += len(xyz)
    return lo, hi, n


def _cell_index(v: np.ndarray, origin: float, cell: float, count: int) -> np.ndarray:
    """The engine's cell_index: floor((v - origin) / cell), 0 below, count - 1 above."""
    k = np.floor((v - origin) / cell)
    return np.where(k <= 0.0, 0.0, np.minimum(float(count - 1), k)).astype(np.uint64)


def _medians(z_sorted: np.ndarray, starts: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """detail::sorted_quantile(zs, 0.5) of each run of sorted z (src/pipeline/statistics.cpp)."""
    h = (counts.astype(np.float64) - 1.0) * 0.5
    lo = np.floor(h).astype(np.int64)
    last = lo + 1 >= counts
    below = z_sorted[starts + lo]
    above = z_sorted[np.minimum(starts + lo + 1, len(z_sorted) - 1)]
    return np.where(last, z_sorted[starts + counts - 1], below + (h - lo.astype(np.float64)) * (above - below))


def streamed_grid(source, cell: float, spills: SpillFolder, rows: int) -> raster.Grid:
    """raster.grid_core_points(whole reference, cell) from the PointSource `source`, streamed twice."""
    lo, hi, n = _extent(source, rows)
    corners = np.array([lo, hi]) if n else np.empty((0, 3))
    raster.check_raster_memory(corners, float(cell))
    g = engine.grid_core_points(corners, float(cell), "--grid")  # x0, y0, rows, cols; its checks
    x0, y0, cell = float(g["x0"]), float(g["y0"]), float(g["cell"])
    n_rows, n_cols = int(g["rows"]), int(g["cols"])
    if n == 0:
        return raster.Grid(x0, y0, cell, n_rows, n_cols, np.empty((0, 3)), np.empty(0, np.uint64),
                           np.empty(0, np.uint64))
    bands = max(1, min(n_rows, math.ceil(n / max(1, rows))))
    rows_per_band = np.uint64(math.ceil(n_rows / bands))  # bands of whole grid rows, in row order
    for xyz in source.chunks(rows):
        r = _cell_index(xyz[:, 1], y0, cell, n_rows)
        c = _cell_index(xyz[:, 0], x0, cell, n_cols)
        records = np.empty(len(xyz), dtype=_CELL_Z)
        records["cell"] = r * np.uint64(n_cols) + c
        records["z"] = xyz[:, 2]
        spills.append("grid", (r // rows_per_band).astype(np.int64), records)
    core, row, col = [], [], []
    for band in range(bands):
        records = spills.read("grid", band, _CELL_Z)
        if not len(records):
            continue
        order = np.lexsort((records["z"], records["cell"]))
        cells, z = records["cell"][order], records["z"][order]
        del records, order
        starts = np.flatnonzero(np.concatenate([[True], cells[1:] != cells[:-1]]))
        counts = np.diff(np.append(starts, len(cells)))
        here = cells[starts]
        r, c = here // np.uint64(n_cols), here % np.uint64(n_cols)
        core.append(np.column_stack([x0 + (c.astype(np.float64) + 0.5) * cell, y0 + (r.astype(np.float64) + 0.5) * cell,
                                     _medians(z, starts, counts)]))
        row.append(r)
        col.append(c)
    return raster.Grid(x0, y0, cell, n_rows, n_cols, np.concatenate(core), np.concatenate(row), np.concatenate(col))
