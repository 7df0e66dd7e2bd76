"""What a series run (create, add) is asked beside its compare parameters, in small named
groups: how clouds are read and compared, where the epochs are computed, the core points given,
and the store's chunking."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class EpochReading:
    """How the reference and every epoch are read and compared (picklable: Dask tasks carry it).
    `drop_nonfinite`: drop points with NaN/Inf coordinates (--drop-nonfinite); `ignore_crs`:
    accept epochs whose CRS or units differ from the reference's (--ignore-crs); `threads`: the
    engine's threads (0: every core; the results do not depend on it)."""

    drop_nonfinite: bool = False
    ignore_crs: bool = False
    threads: int = 0


@dataclass(frozen=True)
class DaskTarget:
    """Where the epochs are computed: here (neither given), or as tasks of a Dask scheduler at
    `address` through `client`, connected by the caller once, bounded in time, before any work
    (run.dask.connect; without a client the run connects to `address` itself, the same way)."""

    address: str | None = None
    client: object = None

    @property
    def used(self) -> bool:
        return self.address is not None or self.client is not None


@dataclass(frozen=True)
class CoreInput:
    """The core points given to a new store: `path` (--core; default: the reference, or its
    subsampling by --core-spacing) and `normals` (--core-normals, with --normal-source core;
    default: the core file's nx, ny, nz: run.core_normals)."""

    path: Path | None = None
    normals: Path | None = None


@dataclass(frozen=True)
class StoreLayout:
    """A new store's chunks: core points per chunk (--core-chunk) and epochs per chunk (--epoch-chunk)."""

    core_chunk: int = 16384
    epoch_chunk: int = 8
