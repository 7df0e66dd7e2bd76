"""Partitioning a run into tiles (docs/scaling.md): core point i goes to the square XY tile
``(floor((x - x0) / S), floor((y - y0) / S))``; a tile's box is its core points' bounding box grown
by the halo on every axis; each cloud is streamed once and every point appended, in file order,
to the spill of every tile whose box holds it (with the per-point inputs it carries)."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..io.arrays import bounds
from ..io.streaming import PointSource
from .spill import SpillFolder


class CoreStream:
    """Core points in order, in chunks: the reference stream, or an in-memory array."""

    def __init__(self, source: PointSource | None = None, array: np.ndarray | None = None,
                 normals: np.ndarray | None = None):
        self.source, self.array, self.normals = source, array, normals

    def chunks(self, size: int):
        if self.source is not None:
            for xyz in self.source.chunks(size):
                yield xyz, None
        else:
            for start in range(0, len(self.array), size):
                yield self.array[start:start + size], (None if self.normals is None
                                                      else self.normals[start:start + size])


@dataclass
class Tiles:
    """The tiles of a run: key (tile indices) -> tile number, each tile's box and core-point count."""

    ids: dict
    lo: np.ndarray
    hi: np.ndarray
    counts: np.ndarray
    origin: np.ndarray
    n_core: int
    size: float

    def __len__(self) -> int:
        return len(self.ids)


def plan_tiles(spills: SpillFolder, cores: CoreStream, size: float, origin, rows: int, *, stem: str = "core",
               tile_of: str = "tile_of.u32") -> Tiles:
    """Tile of every core point (the file `tile_of`, uint32 per core point, in core order), per-tile
    core (and normal) spills, bounding boxes (not yet grown) and counts."""
    ids: dict[tuple[int, int], int] = {}
    lo_l: list = []
    hi_l: list = []
    count_l: list = []
    n_core = 0
    with spills.stream(tile_of) as out:
        for xyz, nrm in cores.chunks(rows):
            if origin is None:
                origin = xyz[0, :2].copy()
            keys = np.floor((xyz[:, :2] - origin) / size).astype(np.int64)
            uniq, inverse = np.unique(keys, axis=0, return_inverse=True)
            del keys
            inverse = inverse.reshape(-1)
            local = np.empty(len(uniq), dtype=np.uint32)
            for j, k in enumerate(map(tuple, uniq.tolist())):
                if k not in ids:
                    ids[k] = len(ids)
                    lo_l.append(np.full(3, np.inf))
                    hi_l.append(np.full(3, -np.inf))
                    count_l.append(0)
                local[j] = ids[k]
            tid = local[inverse]
            out.write(tid)
            for j in range(len(uniq)):
                t = int(local[j])
                pts = xyz[inverse == j]
                pts_lo, pts_hi = bounds(pts)
                lo_l[t], hi_l[t] = np.minimum(lo_l[t], pts_lo), np.maximum(hi_l[t], pts_hi)
                count_l[t] += len(pts)
            spills.append(stem, tid, xyz)
            if nrm is not None:
                spills.append("normals", tid, np.ascontiguousarray(nrm, dtype=np.float64))
            n_core += len(xyz)
    return Tiles(ids, np.array(lo_l).reshape(-1, 3), np.array(hi_l).reshape(-1, 3), np.array(count_l, dtype=np.int64),
                 origin, n_core, float(size))


def distribute(src, spills: SpillFolder, stem: str, tiles: Tiles, hp: float, rows: int, *, carried=(),
               moved=None, name: str = "cloud") -> int:
    """Streams one cloud once, appending each point to the spill `stem` of every tile whose box
    (tiles.lo, tiles.hi, halo included) holds it, in file order within each tile. `carried`
    (uncertainty_inputs.Carried) makes the spill rows records with those per-point inputs;
    `moved(xyz)` is where the engine will see the points (EP's transformation), for the box test.
    Returns the points read."""
    from .tasks import record_dtype

    ids, lo, hi, origin, size = tiles.ids, tiles.lo, tiles.hi, tiles.origin, tiles.size
    karr = np.array(list(ids.keys()), dtype=np.int64)
    kmin, kmax = karr.min(axis=0), karr.max(axis=0)
    key_of = np.full(tuple(kmax - kmin + 1), -1, dtype=np.int64)
    key_of[karr[:, 0] - kmin[0], karr[:, 1] - kmin[1]] = np.array(list(ids.values()))
    reach = int(math.floor(2 * hp / size)) + 2
    dtype = record_dtype([c.column for c in carried])
    names = tuple(n for c in carried for n in c.names)
    total = 0
    chunks = src.records(rows, names) if carried else ((xyz, None) for xyz in src.chunks(rows))
    for xyz, fields in chunks:
        total += len(xyz)
        seen = xyz if moved is None else moved(xyz)
        base = np.floor((seen[:, :2] - hp - origin) / size).astype(np.int64) - kmin
        top = np.floor((seen[:, :2] + hp - origin) / size).astype(np.int64) - kmin
        sel_t, sel_i = [], []
        for dx in range(reach):
            for dy in range(reach):
                kx, ky = base[:, 0] + dx, base[:, 1] + dy
                ok = (kx <= top[:, 0]) & (ky <= top[:, 1]) & (kx >= 0) & (ky >= 0) \
                    & (kx < key_of.shape[0]) & (ky < key_of.shape[1])
                idx = np.flatnonzero(ok)
                t = key_of[kx[idx], ky[idx]]
                del kx, ky, ok
                keep = t >= 0
                idx, t = idx[keep], t[keep]
                p = seen[idx]
                inside = ((p[:, 0] >= lo[t, 0]) & (p[:, 0] <= hi[t, 0]) & (p[:, 1] >= lo[t, 1])
                          & (p[:, 1] <= hi[t, 1]) & (p[:, 2] >= lo[t, 2]) & (p[:, 2] <= hi[t, 2]))
                del p
                sel_t.append(t[inside])
                sel_i.append(idx[inside])
        del base, top, seen
        t_all, i_all = np.concatenate(sel_t), np.concatenate(sel_i)
        del sel_t, sel_i
        # Within a tile, points must keep file order: sort by (tile, index in chunk).
        order = np.lexsort((i_all, t_all))
        if dtype is None:
            spills.append(stem, t_all[order], xyz[i_all[order]])
        else:
            records = np.empty(len(xyz), dtype=dtype)
            records["xyz"] = xyz
            for c in carried:
                records[c.keyword] = c.values(fields, f"{name} cloud")
            spills.append(stem, t_all[order], records[i_all[order]])
        del t_all, i_all, order
    return total
