"""LAS extra-bytes columns stored as scaled integers (LAS 1.4 R15, Table 24: each extra-bytes
dimension may declare a scale, an offset and a ``no_data`` value).

A measured length stored as float32 costs about 3.4 bytes a point in a LAZ file, its low bytes
being noise; rounded to :data:`LENGTH_QUANTUM` (0.1 mm when the unit is the metre) it is an
integer whose compressed size is about 2 bytes. NaN is stored as the type's ``no_data`` value
and read back as NaN (m3c2kit's LAS reader; laspy gives the raw ``no_data`` value, whose
declaration it keeps in the extra-bytes record).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..base.errors import CloudWriteError

__all__ = ["Quantised", "quantised", "as_float32", "LENGTH_QUANTUM", "UNIT_QUANTUM", "KINDS"]

#: Lengths (distance, LOD, spreads, D, roughness) are rounded to this many units of the CRS:
#: at most 0.05 mm off in metres, below the ranging precision of any lidar or photogrammetric
#: survey (millimetres at best) and far below any M3C2 level of detection.
LENGTH_QUANTUM = 1e-4
#: Normal components are rounded to 1e-4: at most 0.005 degrees off the fitted direction.
UNIT_QUANTUM = 1e-4

#: Storage of each kind of column: (integer type, scale or None for an integer stored as it is).
KINDS = {
    "length": (np.dtype(np.int32), LENGTH_QUANTUM),
    "unit": (np.dtype(np.int16), UNIT_QUANTUM),
    "count": (np.dtype(np.uint32), None),
    "flag": (np.dtype(np.uint8), None),
}


@dataclass(frozen=True)
class Quantised:
    """A column written to LAS as ``round(values / scale)`` in `dtype` (values as they are when
    `scale` is None), with `no_data` (the type's extreme, never a value) where `values` is NaN."""

    values: np.ndarray
    dtype: np.dtype
    scale: float | None
    no_data: int

    def __len__(self) -> int:
        return len(self.values)

    def encoded(self) -> np.ndarray:
        v = np.asarray(self.values, dtype=np.float64)
        finite = np.isfinite(v)
        q = v if self.scale is None else v / self.scale
        out = np.full(len(v), self.no_data, dtype=self.dtype)
        out[finite] = np.rint(q[finite]).astype(self.dtype)
        return out

    def sliced(self, rows) -> "Quantised":
        return Quantised(np.asarray(self.values)[rows], self.dtype, self.scale, self.no_data)


def _no_data(dtype: np.dtype) -> int:
    info = np.iinfo(dtype)
    return int(info.min) if dtype.kind == "i" else int(info.max)


def quantised(values, kind: str, what: str = "a column") -> Quantised | np.ndarray:
    """`values` as a :class:`Quantised` column of `kind` (:data:`KINDS`), or as float32 when some
    finite value does not fit the integer type (a length beyond 214 km, a count of 2**32 - 1,
    a non-integer count): never clamped, never wrapped."""
    dtype, scale = KINDS[kind]
    v = np.asarray(values, dtype=np.float64)
    finite = v[np.isfinite(v)]
    no_data = _no_data(dtype)
    info = np.iinfo(dtype)
    lo, hi = (int(info.min) + 1, int(info.max)) if dtype.kind == "i" else (0, int(info.max) - 1)
    q = finite if scale is None else finite / scale
    r = np.rint(q)
    fits = not len(q) or (bool(np.all(r >= lo)) and bool(np.all(r <= hi))
                          and (scale is not None or bool(np.all(q == r))))
    if not fits or np.isinf(v).any():
        return as_float32(v, what)
    return Quantised(v, dtype, scale, no_data)


#: float32's largest finite value and its smallest normal one: a finite value beyond the first
#: would be stored as infinity, a non-zero one below the second as 0 or with fewer digits.
_FLOAT32 = np.finfo(np.float32)


def as_float32(values, what: str, advice: str = "write with --float64") -> np.ndarray:
    """`values` as float32, the default storage of measured values; refused (CloudWriteError
    naming `what`) when a finite value would not survive it (issue 42: a 1e150 alignment
    covariance gave LODs of 1e71, written as inf with only numpy's overflow warning)."""
    v = np.asarray(values, dtype=np.float64)
    magnitude = np.abs(v[np.isfinite(v) & (v != 0)])
    if len(magnitude) and (magnitude.max() > _FLOAT32.max or magnitude.min() < _FLOAT32.smallest_normal):
        worst = magnitude.max() if magnitude.max() > _FLOAT32.max else magnitude.min()
        raise CloudWriteError(f"{what} holds {worst:.6g}, which float32 cannot store (magnitudes "
                              f"{_FLOAT32.smallest_normal:.3g} to {_FLOAT32.max:.3g}); {advice}")
    return v.astype(np.float32)
