"""Merging a tiled run's results (docs/scaling.md): the tile of each core point is streamed and
each row taken from its tile's result spill in order, so that the merged table is the in-memory
run's, row for row; written chunk by chunk with m3c2kit.io.streaming.TableWriter (atomically),
with the columns named and typed as the in-memory writer names and types them."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from ..base.errors import M3C2Error
from ..io.fields import typed_columns
from ..io.registry import format_for
from ..io.streaming import TableWriter
from ..engine.result import STATUS_NAMES, Result
from .outcome import TiledReport
from .spill import SpillFolder

#: The columns m3c2kit.run.diagnostics reads, gathered over the tiles (about 17 B per core point).
EVIDENCE = ("status", "n1", "n2", "normal_scale", "roughness")


def _output_xyz(chunk: Result, projected: bool, position: str) -> np.ndarray:
    table = chunk.columns(projected=projected, position=position)
    return np.column_stack([table["x"], table["y"], table["z"]])


@dataclass(frozen=True)
class Storage:
    """How the merged table is stored: m3c2kit.write's names (`field_names`), float64 or the
    compact stored types, and every column in LAS/LAZ (`all_fields`) or CloudCompare's set."""
    field_names: str = "m3c2"
    float64: bool = False
    all_fields: bool = False


def merge(spills: SpillFolder, dtype: np.dtype, counts, n_core: int, report: TiledReport, *, output, like,
          projected, position, storage: Storage = Storage(), return_result, chunk_size, record) -> None:
    keys = tuple(k for k in dtype.names if k != "core")
    spaces = output is not None and getattr(format_for(Path(output), writing=True), "name", None) == "LAS/LAZ"

    def chunks():
        offsets = np.zeros(len(counts), dtype=np.int64)
        taken = np.zeros(len(counts), dtype=np.int64)
        with open(spills.path("tile_of.u32"), "rb") as f:
            while True:
                tid = np.fromfile(f, dtype=np.uint32, count=chunk_size)
                if len(tid) == 0:
                    break
                rows = np.empty(len(tid), dtype=dtype)
                for t in np.unique(tid):
                    sel = tid == t
                    c = int(sel.sum())
                    part = spills.read("result", int(t), dtype, count=c, offset=int(offsets[t]) * dtype.itemsize)
                    if len(part) != c:
                        raise M3C2Error(f"tile {t}: result spill is short")
                    rows[sel] = part
                    offsets[t] += c
                    taken[t] += c
                raw = {k: rows[k] for k in keys}
                chunk = Result.from_engine(np.ascontiguousarray(rows["core"]), raw, record)
                del rows, raw  # one chunk alive at a time: the caller drops it before the next
                yield chunk
                del chunk
        if not np.array_equal(taken, counts):
            raise M3C2Error("core-point bookkeeping failed: rows taken per tile differ from the plan")

    xyz_min = xyz_max = None
    if output is not None and (like is None or like.scale is None):
        xyz_min, xyz_max = np.full(3, np.inf), np.full(3, -np.inf)
        for chunk in chunks():
            # fmin/fmax: rows without a projection (--position reference|compared) have NaN coordinates.
            xyz = _output_xyz(chunk, projected, position)
            xyz_min = np.fmin(xyz_min, np.fmin.reduce(xyz, axis=0, initial=np.inf))
            xyz_max = np.fmax(xyz_max, np.fmax.reduce(xyz, axis=0, initial=-np.inf))
            del chunk, xyz
    gathered = []
    evidence = {k: [] for k in EVIDENCE}
    status = np.zeros(256, dtype=np.int64)
    rows_written = 0

    def consume(chunk: Result, writer=None):
        nonlocal rows_written
        rows_written += len(chunk)
        status[:] += np.bincount(chunk.status, minlength=256)
        report.significant += int(chunk.significant.sum())
        report.with_distance += int(np.isfinite(chunk.distance).sum())
        for k in EVIDENCE:
            evidence[k].append(np.asarray(getattr(chunk, k)))
        if writer is not None:
            table = chunk.columns(projected=projected, position=position)
            xyz = np.column_stack([table.pop("x"), table.pop("y"), table.pop("z")])
            writer.write(xyz, typed_columns(table, field_names=storage.field_names, float64=storage.float64,
                                             spaces=spaces, las=writer.mode == "las",
                                             all_fields=storage.all_fields))  # the stored types of m3c2kit.write
            del xyz, table
        if return_result:
            gathered.append(chunk)

    if output is not None:
        with TableWriter(output, like=like, xyz_min=xyz_min, xyz_max=xyz_max) as writer:
            for chunk in chunks():
                consume(chunk, writer)
                del chunk
    else:
        for chunk in chunks():
            consume(chunk)
            del chunk
    if rows_written != n_core:
        raise M3C2Error(f"wrote {rows_written} rows for {n_core} core points")
    report.evidence = SimpleNamespace(**{k: np.concatenate(v) for k, v in evidence.items()})
    report.status_counts = {STATUS_NAMES[c]: int(n) for c, n in enumerate(status) if n}
    if return_result:
        arrays = {k: np.concatenate([getattr(c, k) for c in gathered]) for k in ("core",) + keys}
        core_xyz = arrays.pop("core")
        report.result = Result(core=core_xyz, params=record, **arrays)
