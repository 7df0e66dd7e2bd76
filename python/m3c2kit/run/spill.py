"""The spill folder of a tiled run: every file a tiled run writes besides its output goes through
:class:`SpillFolder` (per-tile core points, cloud points and results, the tile of each core point,
the classifier's keep masks), so that a write that fails (a full disk: ENOSPC, a quota: EDQUOT,
any OSError) is one clean :class:`SpillError` naming the user's folder (where the private work folder
lives) and the problem. The folder is a private one beside the output (m3c2kit.io.private: pinned,
locked, removed through its descriptor whatever happens); the output itself is written atomically,
so nothing partial is left.

This process writes and reads every spill file through the folder's pinned path, so a swap of the
folder's name redirects nothing. Tasks run on a Dask cluster's workers (other processes, other
machines sharing the storage) can reach the folder only by its name: :meth:`SpillFolder.path`, the
path a task is handed, is that name then (a swap there could only feed a worker other points to
read; every write still goes through the pinned path)."""
from __future__ import annotations

import os
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

import numpy as np

from ..base.errors import CloudWriteError


def _tofile(rows: np.ndarray, f) -> None:
    """The one write of every spill file (the array's bytes through the file object, not tofile(),
    whose short write raises an OSError without errno)."""
    f.write(np.ascontiguousarray(rows).reshape(-1).view(np.uint8).data)


class SpillError(CloudWriteError):
    """A tiled run could not write its spill files (exit status 1)."""


class SpillFolder:
    """Per-tile append-only binary files ``<stem>-<tile>.bin`` and whole files in one folder."""

    def __init__(self, folder: Path, shown: Path | None = None, named: Path | None = None):
        """`folder`: where this process writes and reads (the pinned path); `shown`: the user's
        folder that holds it, for messages (its parent by default); `named`: the folder by name,
        for tasks of other processes (None: they get `folder`)."""
        self.folder = Path(folder)
        self.shown = Path(shown) if shown is not None else self.folder.parent
        self.named = Path(named) if named is not None else self.folder

    def _name(self, stem: str, tile: int | None) -> str:
        return stem if tile is None else f"{stem}-{tile}.bin"

    def path(self, stem: str, tile: int | None = None) -> str:
        """The path of a spill file for a task, which may run in another process."""
        return str(self.named / self._name(stem, tile))

    def local(self, stem: str, tile: int | None = None) -> str:
        """The path of a spill file for this process (through the pinned folder)."""
        return str(self.folder / self._name(stem, tile))

    @contextmanager
    def writing(self) -> Iterator[None]:
        """Turns an OSError of the writes in the block into a SpillError naming the folder."""
        try:
            yield
        except OSError as e:
            # Named by the user's folder (the private work folder lives there until the run ends).
            raise SpillError(f"{self.shown}: cannot write the tiled run's spill files (kept in a work "
                             f"folder there until the run ends): {e.strerror or e}") from None

    def append(self, stem: str, tiles: np.ndarray, rows: np.ndarray) -> None:
        """Appends rows[i] to tile tiles[i]'s file, keeping the rows' order within each tile."""
        if len(tiles) == 0:
            return
        order = np.argsort(tiles, kind="stable")
        tiles, rows = tiles[order], rows[order]
        cuts = np.flatnonzero(np.diff(tiles)) + 1
        starts = np.concatenate([[0], cuts])
        stops = np.concatenate([cuts, [len(tiles)]])
        with self.writing():
            for a, b in zip(starts, stops):
                with open(self.local(stem, int(tiles[a])), "ab") as f:
                    _tofile(rows[a:b], f)

    def write(self, stem: str, tile: int | None, rows: np.ndarray) -> None:
        """(Re)writes one whole file."""
        with self.writing(), open(self.local(stem, tile), "wb") as f:
            _tofile(rows, f)

    @contextmanager
    def stream(self, stem: str) -> Iterator[object]:
        """A file written sequentially (its .write(array) appends the array's bytes)."""
        with self.writing(), open(self.local(stem), "wb") as f:
            yield _Stream(f)

    def read(self, stem: str, tile: int | None, dtype, count: int = -1, offset: int = 0) -> np.ndarray:
        path = self.local(stem, tile)
        if not os.path.exists(path):
            return np.empty(0, dtype=dtype)
        return np.fromfile(path, dtype=dtype, count=count, offset=offset)


class _Stream:
    def __init__(self, f):
        self._f = f

    def write(self, rows: np.ndarray) -> None:
        _tofile(rows, self._f)
