"""What makes a region polygon unusable, checked when the file is read (issue 42): a region of
zero area (a degenerate ring, every vertex on one line) sums over nothing, and a self-intersecting
one (a bow tie, two rings that cross) has no well-defined inside: the even-odd rule counts its
lobes in or out by how its edges happen to cross. OGC simple features (ISO 19125-1, 6.1.11.1)
forbid both; rings may touch at points, as OGC allows.

The crossing test is a sweep over the edges sorted by their smallest x: each edge is tested, with
one vectorised orientation test, against the edges whose x-range starts inside its own, so a ring
of k vertices costs about k log k plus the pairs that overlap in x, never k^2 for ordinary
regions."""
from __future__ import annotations

import math

import numpy as np

from ..base.errors import UsageError

__all__ = ["check_region"]

#: Relative to the region's extent: an area below it squared is zero (rounding of the coordinates).
AREA_EPSILON = 1e-12


def check_region(rings: list[np.ndarray], area: float, path, where: str) -> None:
    """A UsageError naming `path` and `where` when the region has no area or its edges cross."""
    crossing = _first_crossing(rings)
    if crossing is not None:
        raise UsageError(f"{path}: {where}: self-intersecting (edges cross near x {crossing[0]:.6g}, "
                         f"y {crossing[1]:.6g}); its inside is undefined: fix the polygon (OGC simple features)")
    xy = np.concatenate(rings)
    with np.errstate(over="ignore", invalid="ignore"):
        extent = float(np.max(xy.max(axis=0) - xy.min(axis=0)))
        if not math.isfinite(area) or not math.isfinite(extent * extent):  # 1e300 vertices: "zero area" before
            raise UsageError(f"{path}: {where}: its coordinates (up to {float(np.abs(xy).max()):.6g}) are too large for "
                             f"its area to be computed: not a region of the data")
    if not area > AREA_EPSILON * extent * extent:
        raise UsageError(f"{path}: {where}: a region of zero area (its vertices lie on a line or a point)")


def _edges(rings: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(start points, end points, ring of each edge, index of each edge within its ring)."""
    starts, ends, ring_of, index = [], [], [], []
    for r, ring in enumerate(rings):
        starts.append(ring)
        ends.append(np.roll(ring, -1, axis=0))
        ring_of.append(np.full(len(ring), r))
        index.append(np.arange(len(ring)))
    return np.concatenate(starts), np.concatenate(ends), np.concatenate(ring_of), np.concatenate(index)


def _orientation(ax, ay, bx, by, cx, cy):
    return np.sign((bx - ax) * (cy - ay) - (by - ay) * (cx - ax))


def _first_crossing(rings: list[np.ndarray]):
    """A point where two edges cross properly (or overlap along a length), None when none do."""
    a, b, ring_of, index = _edges(rings)
    sizes = np.array([len(r) for r in rings])
    lo_x, hi_x = np.minimum(a[:, 0], b[:, 0]), np.maximum(a[:, 0], b[:, 0])
    lo_y, hi_y = np.minimum(a[:, 1], b[:, 1]), np.maximum(a[:, 1], b[:, 1])
    order = np.argsort(lo_x, kind="stable")
    sorted_lo = lo_x[order]
    for pos, i in enumerate(order):
        end = int(np.searchsorted(sorted_lo, hi_x[i], side="right"))
        j = order[pos + 1:end]
        j = j[(lo_y[j] <= hi_y[i]) & (hi_y[j] >= lo_y[i])]
        same = ring_of[j] == ring_of[i]
        gap = np.abs(index[j] - index[i])
        adjacent = same & ((gap == 1) | (gap == sizes[ring_of[i]] - 1))
        j = j[~adjacent]
        if len(j) == 0:
            continue
        p, q = a[i], b[i]
        o1 = _orientation(p[0], p[1], q[0], q[1], a[j, 0], a[j, 1])
        o2 = _orientation(p[0], p[1], q[0], q[1], b[j, 0], b[j, 1])
        o3 = _orientation(a[j, 0], a[j, 1], b[j, 0], b[j, 1], p[0], p[1])
        o4 = _orientation(a[j, 0], a[j, 1], b[j, 0], b[j, 1], q[0], q[1])
        proper = (o1 * o2 < 0) & (o3 * o4 < 0)
        collinear = (o1 == 0) & (o2 == 0) & _overlap_length(p, q, a[j], b[j])
        hit = np.flatnonzero(proper | collinear)
        if len(hit):
            k = j[hit[0]]
            return (a[i] + b[i] + a[k] + b[k]) / 4.0
    return None


def _overlap_length(p, q, c, d) -> np.ndarray:
    """For collinear segments: do [p, q] and each [c, d] share more than a point?"""
    axis = 0 if abs(q[0] - p[0]) >= abs(q[1] - p[1]) else 1
    lo1, hi1 = min(p[axis], q[axis]), max(p[axis], q[axis])
    lo2, hi2 = np.minimum(c[:, axis], d[:, axis]), np.maximum(c[:, axis], d[:, axis])
    return np.minimum(hi1, hi2) > np.maximum(lo1, lo2)
