"""The reference's own attributes of the core points (intensity, classification, GPS time, RGB, ...)
in a tiled run, the very columns m3c2kit.write carries in memory, where the engine matches each
core point to the reference row it is (src/match_rows.cpp): every row when the core points are the
reference itself, else the first reference point equal to each core point, and none at all when
some core point is no reference point. Here the reference is streamed (m3c2kit.io.streaming:
PointSource.attribute_records, the fields as m3c2kit.io.read_cloud reads them):

- core points streamed from the reference (every point, or those --classifier keeps): their
  attributes stream beside them, chunk by chunk (:class:`StreamedAttributes`: bounded memory);
- core points held in memory (a --core file, --core-spacing, --grid): one pass over the reference
  matches them as the engine does and keeps their attributes (:class:`HeldAttributes`: as large as
  the core points' table, which these runs hold anyway).

One difference remains, documented in docs/scaling.md: with --classifier and every kept reference
point as a core point, a kept point that repeats the coordinates of an earlier point of the
reference carries its own attributes here, the earlier point's in memory (the engine's first match)."""
from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Iterator

import numpy as np

from ..base.errors import M3C2Error
from ..io.streaming import DEFAULT_CHUNK

__all__ = ["AttributeRows", "HeldAttributes", "StreamedAttributes", "core_attributes"]


class AttributeRows(ABC):
    """The core points' attributes handed over in core order: take(n) gives the next n rows."""

    @abstractmethod
    def take(self, n: int) -> dict[str, np.ndarray]:
        """The next `n` rows of every attribute."""

    def gather(self, n: int) -> dict[str, np.ndarray]:
        """All of the (remaining) `n` rows at once."""
        return self.take(n)


class HeldAttributes(AttributeRows):
    """Columns held in memory, handed over in slices."""

    def __init__(self, values: dict[str, np.ndarray]):
        self.values, self.at = values, 0

    def take(self, n: int) -> dict[str, np.ndarray]:
        out = {k: v[self.at:self.at + n] for k, v in self.values.items()}
        self.at += n
        return out


class StreamedAttributes(AttributeRows):
    """Columns read from a stream of field chunks ({name: values}) beside the core points, in their order."""

    def __init__(self, records: Iterator[dict]):
        self.records = records
        self.parts: list[dict] = []  # read and not yet handed over
        self.held = 0

    def take(self, n: int) -> dict[str, np.ndarray]:
        while self.held < n:
            values = next(self.records, None)
            if values is None:
                raise M3C2Error("core-point bookkeeping failed: the reference ended before the core points' attributes")
            if not values:
                return {}
            self.parts.append(values)
            self.held += len(next(iter(values.values())))
        joined = self.parts[0] if len(self.parts) == 1 else {
            k: np.concatenate([p[k] for p in self.parts]) for k in self.parts[0]}
        self.parts = [{k: v[n:] for k, v in joined.items()}]
        self.held -= n
        return {k: v[:n] for k, v in joined.items()}


def has_attributes(source) -> bool:
    """Whether the reference has per-point fields (LAS always does: intensity, return number, ...)."""
    if source.kind in ("las", "copc"):
        return True
    if source.cloud is not None:
        return bool(source.cloud.fields)
    return bool(source._npy_fields())


def core_attributes(reference, cores, rows: int = DEFAULT_CHUNK) -> AttributeRows | None:
    """The attributes of the core points `cores` among the points of `reference` (the PointSource as
    given, before any --classifier filter): `cores` is an (N, 3) array, or the source the core points
    stream from (`reference` itself, or it read through a keep mask: run.vegetation.MaskedSource).
    None when the reference has no fields or some core point is no reference point."""
    if not has_attributes(reference):
        return None
    if not isinstance(cores, np.ndarray):
        if cores is reference:
            return StreamedAttributes(_values(reference.attribute_records(rows)))
        return StreamedAttributes(_masked(reference, cores, rows))
    return _matched(reference, cores, rows)


def _values(records):
    for _, values in records:
        yield values


def _masked(reference, masked, rows: int):
    """The attributes of the points a keep mask keeps (run.vegetation.MaskedSource), in file order."""
    mask, at = masked._masks(), 0
    for xyz, values in reference.attribute_records(rows):
        keep = np.asarray(mask[at:at + len(xyz)], dtype=bool)
        at += len(xyz)
        if keep.any():
            yield {k: v[keep] for k, v in values.items()}


def _row_keys(xyz: np.ndarray) -> np.ndarray:
    """One 24-byte key per row: its coordinates' bits with -0.0 as +0.0 (rows equal as numbers
    have equal keys), as the engine's match_rows hashes them."""
    return np.ascontiguousarray(np.asarray(xyz, dtype=np.float64) + 0.0).view(np.uint64).view("V24").reshape(-1)


def _matched(reference, core: np.ndarray, rows: int) -> HeldAttributes | None:
    """engine.match_rows(reference, core) applied to the reference's fields, in one streaming pass:
    every row when the core points are the reference itself (same count, equal rows), else the
    first reference point equal to each core point; None when one is no reference point."""
    m = len(core)
    distinct, inverse = np.unique(_row_keys(core), return_inverse=True)
    first = np.full(len(distinct), -1, dtype=np.int64)
    matched: dict[str, np.ndarray] = {}
    itself = reference.drop_nonfinite or reference.point_count() == m  # the core points may be the reference
    own: list[dict] = []
    n = 0
    for xyz, values in reference.attribute_records(rows):
        if itself:
            itself = n + len(xyz) <= m and np.array_equal(xyz, core[n:n + len(xyz)])
            if itself:
                own.append(values)
            else:
                own = []
        keys = _row_keys(xyz)
        at = np.minimum(np.searchsorted(distinct, keys), len(distinct) - 1)
        hit = np.flatnonzero((distinct[at] == keys) & (first[at] < 0))
        if hit.size:
            new, where = np.unique(at[hit], return_index=True)  # the first point of this chunk per core row
            rows_here = hit[where]
            first[new] = n + rows_here
            for name, v in values.items():
                if name not in matched:
                    matched[name] = np.zeros(len(distinct), dtype=v.dtype)
                matched[name][new] = v[rows_here]
        n += len(xyz)
    if itself and n == m:
        return HeldAttributes({k: np.concatenate([p[k] for p in own]) for k in own[0]} if own else {})
    if (first < 0).any():
        return None
    return HeldAttributes({name: v[inverse.reshape(-1)] for name, v in matched.items()})
