"""Merging a tiled run's results (docs/scaling.md): the tile of each core point is streamed and
each row taken from its tile's result spill in order, so that the merged table is the in-memory
run's, row for row; written chunk by chunk with m3c2kit.io.streaming.TableWriter (atomically),
with the columns named and typed as the in-memory writer names and types them (one
m3c2kit.io.fields.TableStyle) and the core points' own attributes beside them (m3c2kit.run.attributes)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Iterator

import numpy as np

from ..base.errors import M3C2Error
from ..engine.result import STATUS_NAMES, Result
from ..io.fields import TableStyle, carried_columns
from ..io.registry import quantises
from ..io.streaming import TableWriter
from .attributes import AttributeRows
from .fdr import Fdr
from .outcome import TiledReport
from .spill import SpillFolder

#: The columns m3c2kit.run.diagnostics reads, gathered over the tiles (about 17 B per core point).
EVIDENCE = ("status", "n1", "n2", "normal_scale", "roughness")


@dataclass(frozen=True)
class ResultSpills:
    """A tiled run's per-tile result rows (spills "result-<tile>", of `dtype`), `counts` rows per
    tile, read back in core order through the tile of each core point (the file tile_of.u32)."""

    spills: SpillFolder
    dtype: np.dtype
    counts: np.ndarray
    n_core: int
    record: dict  # the parameters each Result records (m3c2kit.run.plan.Plan.record)

    def chunks(self, rows: int) -> Iterator[Result]:
        """The merged rows as Results of at most `rows` core points, in core order."""
        keys = tuple(k for k in self.dtype.names if k != "core")
        offsets = np.zeros(len(self.counts), dtype=np.int64)
        with open(self.spills.local("tile_of.u32"), "rb") as f:
            while True:
                tid = np.fromfile(f, dtype=np.uint32, count=rows)
                if len(tid) == 0:
                    break
                part = np.empty(len(tid), dtype=self.dtype)
                for t in np.unique(tid):
                    sel = tid == t
                    c = int(sel.sum())
                    read = self.spills.read("result", int(t), self.dtype, count=c,
                                            offset=int(offsets[t]) * self.dtype.itemsize)
                    if len(read) != c:
                        raise M3C2Error(f"tile {t}: result spill is short")
                    part[sel] = read
                    offsets[t] += c
                raw = {k: part[k] for k in keys}
                chunk = Result.from_engine(np.ascontiguousarray(part["core"]), raw, self.record)
                del part, raw  # one chunk alive at a time: the caller drops it before the next
                yield chunk
                del chunk
        if not np.array_equal(offsets, self.counts):
            raise M3C2Error("core-point bookkeeping failed: rows taken per tile differ from the plan")

    def p_values(self, rows: int) -> np.ndarray:
        """Every core point's p_value in core order (8 bytes each): what --fdr ranks (m3c2kit.run.fdr)."""
        out = np.empty(self.n_core, dtype=np.float64)
        start = 0
        for chunk in self.chunks(rows):
            out[start:start + len(chunk)] = chunk.p_value
            start += len(chunk)
            del chunk
        return out

    def rows_at(self, idx: np.ndarray, rows: int) -> tuple[np.ndarray, np.ndarray]:
        """The core points and normals of the merged rows `idx` (sorted), in one more pass."""
        core, normal, start = [], [], 0
        for chunk in self.chunks(rows):
            here = idx[(idx >= start) & (idx < start + len(chunk))] - start
            core.append(chunk.core[here])
            normal.append(chunk.normal[here])
            start += len(chunk)
        return np.concatenate(core), np.concatenate(normal)


@dataclass(frozen=True)
class MergeTarget:
    """Where the merged rows go: the `output` file (None: none) written in `style` with `like`'s
    LAS scale, offset and CRS, the core points' `attributes` beside them (None: none), and
    whether the Result (and the attributes) are gathered in memory (`gather`)."""

    output: object = None
    like: object = None
    style: TableStyle = TableStyle()
    attributes: AttributeRows | None = None
    gather: bool = False


class Evidence:
    """What the run's warnings read (m3c2kit.run.diagnostics): the EVIDENCE columns of every core
    point, and rows_at(idx) -> the core points and normals of some rows (the diagnosis of empty
    cylinders, m3c2kit.run.quality), read back from the spills or the gathered Result."""

    def __init__(self, columns: dict, rows_at: Callable):
        for k, v in columns.items():
            setattr(self, k, v)
        self.rows_at = rows_at


def _bounds(results: ResultSpills, style: TableStyle, rows: int) -> tuple[np.ndarray, np.ndarray]:
    """The output rows' coordinate range (a LAS scale for a reference without one)."""
    xyz_min, xyz_max = np.full(3, np.inf), np.full(3, -np.inf)
    for chunk in results.chunks(rows):
        xyz, _ = style.rows(chunk)
        # fmin/fmax: rows without a projection (--position reference|compared) have NaN coordinates.
        xyz_min = np.fmin(xyz_min, np.fmin.reduce(xyz, axis=0, initial=np.inf))
        xyz_max = np.fmax(xyz_max, np.fmax.reduce(xyz, axis=0, initial=-np.inf))
        del chunk, xyz
    return xyz_min, xyz_max


def merge(results: ResultSpills, target: MergeTarget, report: TiledReport, rows: int,
          merged: Callable[[Evidence], object] = lambda evidence: None, fdr: Fdr | None = None) -> None:
    """Streams the merged rows into `target`, filling `report` (status counts, significant
    changes, distances, the evidence, the gathered Result); `merged(evidence)` is called once
    every row is written and before the output file is closed (the warnings then come before
    the writer's own, as in memory). `fdr` (--fdr): the q-values of every core point's p-value,
    ranked once before the first row is written, go beside each chunk's rows."""
    style, output = target.style, target.output
    las = output is not None and quantises(output)
    gathered, carried = [], []
    evidence = {k: [] for k in EVIDENCE}
    status = np.zeros(256, dtype=np.int64)
    rows_written = 0
    q = fdr.q_values(results.p_values(rows)) if fdr is not None else None

    def consume(chunk: Result, writer=None) -> None:
        nonlocal rows_written
        if q is not None:
            fdr.attach(chunk, q[rows_written:rows_written + len(chunk)])
            report.significant_fdr += int(chunk.significant_fdr.sum())
        rows_written += len(chunk)
        status[:] += np.bincount(chunk.status, minlength=256)
        report.significant += int(chunk.significant.sum())
        report.with_p_value += int(np.isfinite(chunk.p_value).sum())
        report.with_distance += int(np.isfinite(chunk.distance).sum())
        for k in EVIDENCE:
            evidence[k].append(np.asarray(getattr(chunk, k)))
        attributes = target.attributes.take(len(chunk)) if target.attributes is not None else None
        if writer is not None:
            xyz, table = style.rows(chunk)
            fields = style.stored(table, las, output)  # the stored types of m3c2kit.write
            if attributes:
                fields.update(carried_columns(attributes, set(fields)))
            writer.write(xyz, fields)
            del xyz, table, fields
        if target.gather:
            gathered.append(chunk)
            if attributes is not None:
                carried.append(attributes)

    def finish() -> None:
        if rows_written != results.n_core:
            raise M3C2Error(f"wrote {rows_written} rows for {results.n_core} core points")
        report.status_counts = {STATUS_NAMES[c]: int(n) for c, n in enumerate(status) if n}
        if target.gather:
            keys = ("core",) + tuple(k for k in results.dtype.names if k != "core")
            arrays = {k: np.concatenate([getattr(c, k) for c in gathered]) for k in keys}
            report.result = Result(core=arrays.pop("core"), params=results.record, **arrays)
            if q is not None:
                fdr.attach(report.result, q)
            if carried:
                report.attributes = {k: np.concatenate([c[k] for c in carried]) for k in carried[0]}
            elif target.attributes is not None:
                report.attributes = {}
            rows_at = lambda idx: (report.result.core[idx], report.result.normal[idx])  # noqa: E731
        else:
            rows_at = lambda idx: results.rows_at(idx, rows)  # noqa: E731
        # Each column's chunks are released as it is joined (the writer is still open: its peak).
        report.evidence = Evidence({k: np.concatenate(evidence.pop(k)) for k in EVIDENCE}, rows_at)
        merged(report.evidence)

    if output is None:
        for chunk in results.chunks(rows):
            consume(chunk)
            del chunk
        finish()
        return
    xyz_min = xyz_max = None
    if target.like is None or target.like.scale is None:
        xyz_min, xyz_max = _bounds(results, style, rows)
    with TableWriter(output, like=target.like, xyz_min=xyz_min, xyz_max=xyz_max) as writer:
        for chunk in results.chunks(rows):
            consume(chunk, writer)
            del chunk
        finish()
