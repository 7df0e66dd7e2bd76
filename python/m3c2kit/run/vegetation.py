"""--classifier FILE --keep CLASS (section 4.3: vegetation removed by CANUPO before the comparison):
both clouds reduced to the points classified as a kept class, each point classified from its
neighbourhoods in its whole cloud. The filter is the plan's input (the caller builds it with
m3c2kit.classify.vegetation): this module only cuts the work into tiles.

In memory the clouds are classified whole. A tiled run classifies each cloud tile by tile first:
its points are cut into the run's XY tiles, each tile's points are classified from the cloud's
points within the classifier's reach (half its largest scale, plus a margin) of the tile's box,
and the keep mask is merged back into file order; the cloud is then read through that mask
(:class:`MaskedSource`), so that the comparison, its core points and its subsampling see exactly
the points an in-memory run keeps."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..base.errors import M3C2Error, UsageError
from ..io.streaming import DEFAULT_CHUNK
from .partition import CoreStream, distribute, plan_tiles
from .spill import SpillFolder


def filtered_clouds(filt, reference, compared, threads: int = 0):
    """The in-memory filter: (reference, compared) reduced to their kept points."""
    if filt is None:
        return reference, compared
    return tuple(filt.filtered(cloud, name, threads=threads)
                 for name, cloud in (("reference", reference), ("compared", compared)))


@dataclass
class ClassifyTask:
    """One tile of the classification pass (picklable): its own points and their neighbours."""

    tile: int
    n_own: int
    own_path: str
    near_path: str
    vegetation: object  # the plan's filter (picklable: the worker reads the classifier file)


def classify_tile(task: ClassifyTask, threads: int = 0) -> dict:
    from .tasks import worker_threads

    own = np.fromfile(task.own_path, dtype=np.float64).reshape(-1, 3)
    if len(own) != task.n_own:
        raise M3C2Error(f"classification tile {task.tile}: {len(own)} points spilled, expected {task.n_own}")
    near = np.fromfile(task.near_path, dtype=np.float64).reshape(-1, 3)
    return {"tile": task.tile, "keep": task.vegetation.keep_mask(near, own, threads=worker_threads(threads))}


class MaskedSource:
    """A PointSource read through a keep mask (one uint8 per point in file order, a spill file)."""

    kind = "masked"

    def __init__(self, source, mask_path: str, kept: int):
        self.source, self.mask_path, self.kept = source, mask_path, kept
        self.path, self.drop_nonfinite = source.path, source.drop_nonfinite

    @property
    def cloud(self):
        return None

    def like(self):
        return self.source.like()

    def point_count(self) -> int:
        return self.kept

    def _masks(self):
        mask = np.memmap(self.mask_path, dtype=np.uint8, mode="r") if self.kept else np.zeros(0, np.uint8)
        return mask

    def chunks(self, size: int = DEFAULT_CHUNK):
        for xyz, _ in self.records(size, ()):
            yield xyz

    def records(self, size: int = DEFAULT_CHUNK, fields=()):
        mask, at = self._masks(), 0
        for xyz, values in self.source.records(size, fields):
            m = np.asarray(mask[at:at + len(xyz)], dtype=bool)
            at += len(xyz)
            if m.any():
                yield np.ascontiguousarray(xyz[m]), {k: v[m] for k, v in values.items()}

    def query_box(self, lo, hi, size: int = DEFAULT_CHUNK):
        from ..io.streaming import _in_box
        parts = [xyz[_in_box(xyz, np.asarray(lo, float), np.asarray(hi, float))] for xyz in self.chunks(size)]
        return np.concatenate(parts) if parts else np.empty((0, 3))


def classify_tiled(filt, name: str, source, spills: SpillFolder, size: float, rows: int, execute,
                   threads: int = 0) -> MaskedSource:
    """The tiled classification pass of one cloud (`execute(tasks, fn, accept)` runs the tasks,
    on this machine or on Dask); the cloud read through its keep mask."""
    stem = f"classify-{name}"
    tiles = plan_tiles(spills, CoreStream(source=source), size, None, rows, stem=f"{stem}-own",
                       tile_of=f"{stem}-tile_of.u32")
    if tiles.n_core == 0:
        raise UsageError(f"the {name} cloud is empty (0 points)")
    margin = filt.reach
    tiles.lo -= margin
    tiles.hi += margin
    distribute(source, spills, f"{stem}-near", tiles, margin, rows)
    tasks = [ClassifyTask(t, int(tiles.counts[t]), spills.path(f"{stem}-own", t), spills.path(f"{stem}-near", t),
                          filt) for t in range(len(tiles))]
    done = set()

    def accept(out: dict) -> None:
        t = int(out["tile"])
        if t in done or len(out["keep"]) != tiles.counts[t]:
            raise M3C2Error(f"classification tile {t}: returned twice or with the wrong number of points")
        spills.write(f"{stem}-keep", t, out["keep"])
        done.add(t)

    execute(tasks, classify_tile, accept, (threads,))
    if len(done) != len(tiles):
        raise M3C2Error(f"only {len(done)} of {len(tiles)} classification tiles were computed")
    offsets = np.zeros(len(tiles), dtype=np.int64)
    kept = 0
    with spills.stream(f"{stem}-keep.u8") as out, open(spills.path(f"{stem}-tile_of.u32"), "rb") as f:
        while True:
            tid = np.fromfile(f, dtype=np.uint32, count=rows)
            if len(tid) == 0:
                break
            mask = np.empty(len(tid), dtype=np.uint8)
            for t in np.unique(tid):
                sel = tid == t
                c = int(sel.sum())
                mask[sel] = spills.read(f"{stem}-keep", int(t), np.uint8, count=c, offset=int(offsets[t]))
                offsets[t] += c
            kept += int(mask.sum())
            out.write(mask)
    if kept == 0:
        raise UsageError(f"the {name} cloud has no point classified as {', '.join(map(str, filt.keep))} "
                         f"({tiles.n_core} points classified)")
    return MaskedSource(source, spills.path(f"{stem}-keep.u8"), kept)
