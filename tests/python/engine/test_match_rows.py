"""m3c2kit.engine.match_rows (m3c2::match_rows) against a brute-force oracle: the first identical
row in input order, None when a query is no row, -0.0 equal to 0.0, rows one ulp apart and NaN
told apart."""
from __future__ import annotations

import numpy as np

from m3c2kit import engine


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
    np.testing.assert_array_equal(engine.match_rows(pts, queries), expected)
    assert len(np.unique(pts, axis=0)) < len(pts)  # the fixture has duplicates to choose among


def test_none_when_a_query_is_no_row():
    pts = _cloud(3)
    queries = np.vstack([pts[:5], [[9.9, 9.9, 9.9]]])
    assert engine.match_rows(pts, queries) is None
    shifted = pts[:5].copy()
    shifted[2, 1] = np.nextafter(shifted[2, 1], 10.0)  # one ulp off on one axis
    assert engine.match_rows(pts, shifted) is None


def test_negative_zero_matches_zero():
    pts = np.array([[1.0, 0.0, 2.0], [0.0, 0.0, 0.0]])
    queries = np.array([[0.0, -0.0, -0.0], [1.0, -0.0, 2.0]])
    np.testing.assert_array_equal(engine.match_rows(pts, queries), [1, 0])


def test_identical_arrays_are_the_identity():
    pts = _cloud(4)
    np.testing.assert_array_equal(engine.match_rows(pts, pts.copy()), np.arange(len(pts)))


def test_rows_one_ulp_apart_and_nan_rows_are_told_apart():
    # Each query has neighbours one ulp off on each axis (before it in input order) and rows
    # holding NaN: only the identical row is its match; a NaN query equals no row.
    pts = _cloud(5, n=300)
    off = []
    for a in range(3):
        for direction in (-np.inf, np.inf):
            near = pts.copy()
            near[:, a] = np.nextafter(near[:, a], direction)
            off.append(near)
    nan_rows = pts[:50].copy()
    nan_rows[:, 1] = np.nan
    everything = np.vstack(off + [nan_rows, pts])
    queries = pts[::-7]
    np.testing.assert_array_equal(engine.match_rows(everything, queries), _oracle(everything, queries))
    assert engine.match_rows(everything, np.vstack([queries, nan_rows[:1]])) is None


def test_many_points_few_queries_against_the_oracle():
    # Far more points than queries (the table of distinct queries is small and most points probe
    # slots held by other rows), duplicates among the queries, queries late in the points.
    rng = np.random.default_rng(6)
    pts = np.round(rng.normal(0, 50, (20000, 3)), 2)
    queries = np.vstack([pts[-3:], pts[rng.integers(0, len(pts), 40)], pts[-3:]])
    np.testing.assert_array_equal(engine.match_rows(pts, queries), _oracle(pts, queries))


def test_no_queries_and_no_points():
    assert len(engine.match_rows(_cloud(7), np.empty((0, 3)))) == 0
    assert engine.match_rows(np.empty((0, 3)), _cloud(7)[:2]) is None
