"""Finding, for each query row, an identical row of a point array (exact float64 equality).

The core points' own attributes are carried into the output by matching each core point to the
reference point it is (m3c2kit.io.fields.core_attributes). The engine does it
(m3c2::match_rows, src/match_rows.cpp): a hash table of the distinct queries and one pass over
the points, where numpy's hash-and-argsort of every point took a tenth of a whole run (issue 19).
"""
from __future__ import annotations

import numpy as np

__all__ = ["match_rows"]


def match_rows(points: np.ndarray, queries: np.ndarray) -> np.ndarray | None:
    """For each row of `queries` ((m, 3)), the index of the first row of `points` ((n, 3)) equal
    to it as numbers (-0.0 equals 0.0, NaN equals nothing), or None when some query has none."""
    from .. import engine

    as_rows = lambda a: np.ascontiguousarray(a, dtype=np.float64).reshape(-1, 3)  # noqa: E731
    return engine.match_rows(as_rows(points), as_rows(queries))
