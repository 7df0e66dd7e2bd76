"""The epochs' points cropped to blocks of core points, each epoch's file read once (TAM3C2's pool,
series/tam3c2.py; docs/series.md, "TAM3C2").

A block of core points needs, of every epoch, only the points within the reach of its box (the
normal's sphere, the cylinder's bounding sphere). Reading every file again for each block would
read the whole series once per block (dozens of times at a thousand epochs); holding every file
would hold the whole series. Instead each file is read once, and the points of each block's
widened box are appended to that block's spill file in a private folder (io/private.py: nobody
can swap it), epoch after epoch; a block's pool is then read back from its spill alone. Memory:
one file's points while spilling, one block's crops while computing. Disk: the crops (a point
near a block boundary is in the spills of every block whose widened box holds it)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..base.errors import M3C2Error
from ..io.private import describe


class EpochCrops:
    """The crops of `epochs` epochs for blocks of core points with boxes (lo, hi), already
    widened by the reach, spilled in `folder` (one raw float64 file per block)."""

    def __init__(self, folder: Path, boxes: list[tuple[np.ndarray, np.ndarray]], epochs: int, shown: Path):
        self.folder, self.boxes, self.shown = Path(folder), boxes, shown
        self.counts = np.zeros((len(boxes), epochs), dtype=np.int64)
        self.added = 0

    def _spill(self, block: int) -> Path:
        return self.folder / f"block-{block}.f64"

    def add(self, xyz: np.ndarray) -> None:
        """The next epoch's points (float64, N x 3): each block's crop appended to its spill."""
        e = self.added
        for b, (lo, hi) in enumerate(self.boxes):
            crop = np.ascontiguousarray(xyz[np.all((xyz >= lo) & (xyz <= hi), axis=1)], dtype=np.float64)
            try:
                with open(self._spill(b), "ab") as f:
                    f.write(crop.tobytes())
            except OSError as err:  # a full disk, most likely: named, nothing published
                raise M3C2Error(f"{self.shown}: TAM3C2 could not spill the epochs' crops beside it: "
                                f"{describe(err)}") from None
            self.counts[b, e] = len(crop)
        self.added += 1

    def block(self, b: int) -> list[np.ndarray]:
        """Block b's crop of every epoch, in the order added."""
        if self.counts[b].sum() == 0:
            return [np.empty((0, 3)) for _ in range(self.added)]
        values = np.fromfile(self._spill(b), dtype=np.float64)
        self._spill(b).unlink()  # each block is read once: its disk is handed back at once
        if values.size != 3 * self.counts[b].sum():
            raise M3C2Error(f"{self.shown}: TAM3C2's spill of block {b} changed under it; rerun")
        xyz = values.reshape(-1, 3)
        ends = np.cumsum(self.counts[b])
        return [xyz[end - count:end] for count, end in zip(self.counts[b], ends)]
