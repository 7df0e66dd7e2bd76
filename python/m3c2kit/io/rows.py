"""Finding, for each query row, an identical row of a point array (exact float64 equality).

The core points' own attributes are carried into the output by matching each core point to the
reference point it is (m3c2kit.io.fields.core_attributes). Sorting the rows as (x, y, z) records
takes seconds on a million points (numpy compares structured records field by field in Python-level
generic code); sorting one 64-bit hash per row takes milliseconds. A hash is not a proof: every
match is checked coordinate by coordinate, and the few queries whose hash meets a different row
first (a collision) are settled by the exact record sort, on those rows only.
"""
from __future__ import annotations

import numpy as np

__all__ = ["match_rows"]

# Odd 64-bit multipliers (the golden ratio's and two other well-mixed constants): each axis's bits
# spread over the whole word before they are combined, so rows differing in any bit hash apart.
_MIX = np.array([0x9E3779B97F4A7C15, 0xC2B2AE3D27D4EB4F, 0x165667B19E3779F9], dtype=np.uint64)


def _hash(rows: np.ndarray) -> np.ndarray:
    # + 0.0 makes -0.0 into +0.0 (equal as numbers, different bits); NaN never matches anyway.
    bits = np.ascontiguousarray(rows + 0.0).view(np.uint64)
    with np.errstate(over="ignore"):
        h = bits * _MIX
        out = h[:, 0] ^ (h[:, 1] >> np.uint64(1)) ^ (h[:, 2] >> np.uint64(2))
        out ^= out >> np.uint64(29)
    return out


def _match_exact(points: np.ndarray, queries: np.ndarray) -> np.ndarray:
    """Index of the first identical row of `points` per query (any index where there is none)."""
    row = np.dtype([("x", "<f8"), ("y", "<f8"), ("z", "<f8")])
    p = np.ascontiguousarray(points + 0.0).view(row).ravel()
    q = np.ascontiguousarray(queries + 0.0).view(row).ravel()
    order = np.argsort(p, kind="stable")
    pos = np.minimum(np.searchsorted(p[order], q), len(p) - 1)
    return order[pos]


def match_rows(points: np.ndarray, queries: np.ndarray) -> np.ndarray | None:
    """For each row of `queries` ((m, 3) float64), the index of the first row of `points`
    ((n, 3) float64, n >= 1) equal to it in input order, or None when some query has none."""
    if len(points) == len(queries) and np.array_equal(points, queries):
        return np.arange(len(points))
    keys = _hash(points)
    order = np.argsort(keys, kind="stable")  # stable: equal rows (equal hashes) keep input order
    sorted_keys = keys[order]
    wanted = _hash(queries)
    pos = np.minimum(np.searchsorted(sorted_keys, wanted), len(points) - 1)
    if not np.array_equal(sorted_keys[pos], wanted):
        return None  # some query's hash is no row's: that query is no row
    found = order[pos]
    missed = np.flatnonzero(~(points[found] == queries).all(axis=1))
    if len(missed):
        # A hash collision put another row first (or the query is no row after all).
        found[missed] = _match_exact(points, queries[missed])
        if not (points[found[missed]] == queries[missed]).all():
            return None
    return found
