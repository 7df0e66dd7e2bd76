"""The clouds as the empty-cylinder diagnosis (m3c2kit.run.quality.cylinder_diagnosis) reads them:
their extent, and an index of their points in a set of cylinders (the sampled core points' lines,
as long as the clouds' extent). In memory (:class:`WholeCloud`) the index is the whole cloud's;
in a tiled run (:class:`StreamedCloud`) the cloud is streamed and only the points that may lie in
one of the cylinders are kept, in file order, before the same index is built on them.

Why the diagnosis is the same bits: the engine's cylinder index orders points on a grid that
depends on the projection scale alone, keeps the relative input order within a cell, and sums a
cylinder's points in that order (docs/scaling.md, "Why the result is bit-identical"; the argument
that makes tiles exact). A subsequence of the cloud holding every point of a cylinder gives that
cylinder the same points in the same order, so the same count, mean and spread.

Which points are kept: those within the cylinders grown by a relative margin (more points never
change a cylinder's sums: membership is the engine's exact predicate). Each cylinder's axis is
clipped to the clouds' box and sampled every G (a cell side of at least the cylinder's diameter);
the cells of a grid of side G around each sample hold every point within the radius of the axis;
a streamed point in one of those cells is tested against the cylinders through it. Memory: the
kept points (those of the sampled cylinders, at most :data:`m3c2kit.run.quality.WARNING_SAMPLE`
per cloud) and the cells' table (at most about 27 x :data:`MAX_SAMPLES` entries)."""
from __future__ import annotations

import numpy as np

from .. import engine
from ..io.arrays import bounds

__all__ = ["WholeCloud", "StreamedCloud", "CylinderSelection", "MAX_SAMPLES"]

#: Samples along all the cylinders' axes together, at most (the cell side grows to keep to it).
MAX_SAMPLES = 1 << 16
#: Relative growth of each cylinder's radius and half-length for the selection (a superset).
MARGIN = 1e-6
#: Absolute growth, relative to the coordinates' magnitude (float64 rounding is ~1e-16 of it).
HAIR = 1e-9
#: Cylinder-point pairs tested at once (bounds the selection's temporaries).
PAIRS_AT_ONCE = 1 << 21


class _NoPoints:
    """The index of an empty selection: no cylinder holds a point."""

    def statistics(self, core, normals, diameter, half_length, *, threads=0) -> dict:
        n = len(core)
        return {"count": np.zeros(n, np.uint32), "mean": np.full(n, np.nan), "sigma": np.full(n, np.nan)}


class WholeCloud:
    """A cloud held in memory: its own index answers every cylinder."""

    def __init__(self, xyz: np.ndarray):
        self.xyz = xyz

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return bounds(self.xyz)

    def cylinder_index(self, core, normals, radius: float, half_length: float, smallest_diameter: float, *,
                       threads: int = 0):
        return engine.CylinderIndex(self.xyz, smallest_diameter, threads=threads)


class StreamedCloud:
    """A cloud streamed from a PointSource (`rows` points a chunk); its extent from one pass."""

    def __init__(self, source, rows: int):
        self.source, self.rows = source, rows
        self._bounds = None

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        if self._bounds is None:
            lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
            for xyz in self.source.chunks(self.rows):
                lo, hi = np.minimum(lo, xyz.min(axis=0)), np.maximum(hi, xyz.max(axis=0))
            self._bounds = (lo, hi)
        return self._bounds

    def cylinder_index(self, core, normals, radius: float, half_length: float, smallest_diameter: float, *,
                       threads: int = 0):
        """The index of the points that may lie within `radius` of the cylinders' axes (core point
        +- half_length along the normal): every point of those cylinders, in file order."""
        selection = CylinderSelection(core, normals, radius, half_length, self.bounds())
        parts = [xyz[selection.holding(xyz)] for xyz in self.source.chunks(self.rows)]
        kept = np.ascontiguousarray(np.concatenate(parts)) if parts else np.empty((0, 3))
        if not len(kept):
            return _NoPoints()
        return engine.CylinderIndex(kept, smallest_diameter, threads=threads)


class CylinderSelection:
    """The points within `radius` of cylinder axes (each core point +- `half_length` along its
    normal; normals of any length, a zero or non-finite one has no cylinder), each cylinder grown
    by :data:`MARGIN` (and a hair of the coordinates' magnitude); `box`: (lo, hi), the extent of
    every point that will be asked. Holds the cells (side `side`, from `origin`) the cylinders
    pass through: (cell key, cylinder) pairs sorted by key."""

    def __init__(self, core, normals, radius: float, half_length: float, box):
        core = np.asarray(core, dtype=np.float64).reshape(-1, 3)
        normals = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
        length = np.linalg.norm(normals, axis=1)
        usable = np.isfinite(length) & (length > 0) & np.isfinite(core).all(axis=1)
        core, axes = core[usable], normals[usable] / length[usable, None]
        lo, hi = (np.asarray(b, dtype=np.float64) for b in box)
        hair = HAIR * max(float(np.max(np.abs(np.concatenate([lo, hi])))), 1.0) if np.isfinite(lo).all() else 0.0
        radius, half_length = radius * (1 + MARGIN) + hair, half_length * (1 + MARGIN) + hair
        self.core, self.axes, self.radius, self.half_length = core, axes, radius, half_length
        self.keys = self.owners = np.empty(0, dtype=np.int64)
        if len(core) and np.isfinite(lo).all() and np.isfinite(hi).all():
            self._cells(lo, hi)

    def _cells(self, lo: np.ndarray, hi: np.ndarray) -> None:
        core, axes, radius, half_length = self.core, self.axes, self.radius, self.half_length
        grown_lo, grown_hi = lo - radius, hi + radius
        start, stop = _clipped(core - half_length * axes, core + half_length * axes, grown_lo, grown_hi)
        length = np.where(np.isfinite(start), stop - start, 0.0)
        extent = float(np.max(grown_hi - grown_lo))
        # Cells of at least 1.25 diameters (a sample's neighbourhood then spans at most 3 cells a
        # side), at most MAX_SAMPLES samples, and cell numbers below 2**20 on every axis.
        self.side = max(2.5 * radius, float(length.sum()) / MAX_SAMPLES, extent / float(1 << 20), 1e-300)
        self.origin = grown_lo - self.side
        samples = np.where(np.isfinite(start), np.ceil(length / self.side).astype(np.int64) + 1, 0)
        cyl = np.repeat(np.arange(len(core)), samples)
        step = np.arange(len(cyl)) - np.repeat(np.cumsum(samples) - samples, samples)
        t = np.minimum(start[cyl] + step * self.side, stop[cyl])
        at = core[cyl] + t[:, None] * axes[cyl]
        # A point within the radius of the axis is within radius + side / 2 of a sample (the
        # samples are at most a side apart), on every axis too.
        reach = radius + 0.5 * self.side * (1 + MARGIN)
        first = np.floor((at - reach - self.origin) / self.side).astype(np.int64)
        last = np.floor((at + reach - self.origin) / self.side).astype(np.int64)
        keys, owners = [], []
        for dx in range(3):
            for dy in range(3):
                for dz in range(3):
                    cell = first + (dx, dy, dz)
                    ok = (cell <= last).all(axis=1)
                    keys.append(self._key(cell[ok]))
                    owners.append(cyl[ok])
        keys, owners = np.concatenate(keys), np.concatenate(owners)
        order = np.lexsort((owners, keys))
        keys, owners = keys[order], owners[order]
        new = np.concatenate([[True], (keys[1:] != keys[:-1]) | (owners[1:] != owners[:-1])])
        self.keys, self.owners = keys[new], owners[new]

    @staticmethod
    def _key(cell: np.ndarray) -> np.ndarray:
        return (cell[:, 0] << 42) | (cell[:, 1] << 21) | cell[:, 2]

    def holding(self, xyz: np.ndarray) -> np.ndarray:
        """A mask of the points of `xyz` within a cylinder (grown by the margin)."""
        keep = np.zeros(len(xyz), dtype=bool)
        if not len(self.keys) or not len(xyz):
            return keep
        cell = np.floor((xyz - self.origin) / self.side).astype(np.int64)
        inside = ((cell >= 0) & (cell < (1 << 21))).all(axis=1)
        idx = np.flatnonzero(inside)
        keys = self._key(cell[idx])
        begin, end = np.searchsorted(self.keys, keys, "left"), np.searchsorted(self.keys, keys, "right")
        some = end > begin
        idx, begin, end = idx[some], begin[some], end[some]
        counts = end - begin
        edges = np.searchsorted(np.cumsum(counts), np.arange(PAIRS_AT_ONCE, int(counts.sum()), PAIRS_AT_ONCE),
                                "right")
        for part in np.split(np.arange(len(idx)), edges):
            if not len(part):
                continue
            n = counts[part]
            point = np.repeat(idx[part], n)
            pair = np.repeat(begin[part] - np.cumsum(n) + n, n) + np.arange(int(n.sum()))
            c = self.owners[pair]
            v = xyz[point] - self.core[c]
            t = np.einsum("ij,ij->i", v, self.axes[c])
            off = v - t[:, None] * self.axes[c]
            hit = (np.abs(t) <= self.half_length) & (np.einsum("ij,ij->i", off, off) <= self.radius ** 2)
            keep[point[hit]] = True
        return keep


def _clipped(a: np.ndarray, b: np.ndarray, lo: np.ndarray, hi: np.ndarray):
    """The parameters (distance from the core point along the axis) where segments a->b enter and
    leave the box [lo, hi] (Liang-Barsky); NaN where they miss it."""
    centre = (a + b) / 2.0
    half = np.linalg.norm(b - a, axis=1) / 2.0
    with np.errstate(divide="ignore", invalid="ignore"):
        axis = (b - a) / (2.0 * half[:, None])
        t0 = (lo - centre) / axis
        t1 = (hi - centre) / axis
    enter = np.where(axis == 0, np.where((centre >= lo) & (centre <= hi), -np.inf, np.inf), np.minimum(t0, t1))
    leave = np.where(axis == 0, np.where((centre >= lo) & (centre <= hi), np.inf, -np.inf), np.maximum(t0, t1))
    start = np.maximum(enter.max(axis=1), -half)
    stop = np.minimum(leave.min(axis=1), half)
    miss = ~(start <= stop)
    return np.where(miss, np.nan, start), np.where(miss, np.nan, stop)
