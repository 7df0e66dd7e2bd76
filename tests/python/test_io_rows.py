"""m3c2kit.io.rows.match_rows against a brute-force oracle: first identical row in input order,
None when a query is no row, -0.0 equal to 0.0, and hash collisions settled exactly."""
from __future__ import annotations

import numpy as np

from m3c2kit.io import rows


def _oracle(points, queries):
    out = []
    for q in queries:
        hit = np.flatnonzero((points == q).all(axis=1))
        if len(hit) == 0:
            return None
        out.append(hit[0])
    return np.array(out)


def _cloud(seed, n=400):
    rng = np.random.default_rng(seed)
    pts = np.round(rng.uniform(0, 3, (n, 3)), 1)  # coarse values: many duplicate rows and shared axes
    return pts


def test_matches_the_first_identical_row():
    pts = _cloud(1)
    queries = pts[np.random.default_rng(2).integers(0, len(pts), 150)]
    expected = _oracle(pts, queries)
    np.testing.assert_array_equal(rows.match_rows(pts, queries), expected)
    assert len(np.unique(pts, axis=0)) < len(pts)  # the fixture has duplicates to choose among


def test_none_when_a_query_is_no_row():
    pts = _cloud(3)
    queries = np.vstack([pts[:5], [[9.9, 9.9, 9.9]]])
    assert rows.match_rows(pts, queries) is None
    shifted = pts[:5].copy()
    shifted[2, 1] = np.nextafter(shifted[2, 1], 10.0)  # one ulp off on one axis
    assert rows.match_rows(pts, shifted) is None


def test_negative_zero_matches_zero():
    pts = np.array([[1.0, 0.0, 2.0], [0.0, 0.0, 0.0]])
    queries = np.array([[0.0, -0.0, -0.0], [1.0, -0.0, 2.0]])
    np.testing.assert_array_equal(rows.match_rows(pts, queries), [1, 0])


def test_identical_arrays_are_the_identity():
    pts = _cloud(4)
    np.testing.assert_array_equal(rows.match_rows(pts, pts.copy()), np.arange(len(pts)))


def test_collisions_are_settled_exactly(monkeypatch):
    # Every row hashes alike: the exact record sort must still find each query's first row.
    monkeypatch.setattr(rows, "_hash", lambda a: np.zeros(len(a), dtype=np.uint64))
    pts = _cloud(5)
    queries = pts[::-7]
    np.testing.assert_array_equal(rows.match_rows(pts, queries), _oracle(pts, queries))
    assert rows.match_rows(pts, np.array([[7.0, 7.0, 7.0]])) is None
