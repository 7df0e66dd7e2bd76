"""m3c2kit.io.polygons: GeoJSON and WKT region files, and which region each point is in.

Membership is checked against matplotlib's Path.contains_points (an independent C
implementation) on random points, and against hand-worked cases on edges, holes and parts."""
from __future__ import annotations

import json

import numpy as np
import pytest

from m3c2kit.base.errors import UsageError
from m3c2kit.io.polygons import Polygon, contains, read_polygons, region_index

SQUARE = [[0, 0], [10, 0], [10, 10], [0, 10], [0, 0]]
HOLE = [[4, 4], [6, 4], [6, 6], [4, 6], [4, 4]]
FAR = [[20, 0], [30, 0], [30, 10], [20, 10], [20, 0]]


def _write(tmp_path, name, doc):
    p = tmp_path / name
    p.write_text(doc if isinstance(doc, str) else json.dumps(doc))
    return p


def _feature(geom, **props):
    return {"type": "Feature", "properties": props, "geometry": geom}


def test_geojson_feature_collection_names_holes_and_parts(tmp_path):
    doc = {"type": "FeatureCollection", "features": [
        _feature({"type": "Polygon", "coordinates": [SQUARE, HOLE]}, name="slope"),
        _feature({"type": "MultiPolygon", "coordinates": [[SQUARE], [FAR]]}, id=7),
        {"type": "Feature", "id": "top", "properties": None, "geometry": {"type": "Polygon", "coordinates": [FAR]}},
        _feature({"type": "Polygon", "coordinates": [[[0, 0, 5], [1, 0, 5], [1, 1, 5]]]}),
    ]}
    polys = read_polygons(_write(tmp_path, "r.geojson", doc))
    assert [p.name for p in polys] == ["slope", "7", "top", "3"]
    assert len(polys[0].rings) == 2 and polys[0].rings[0].shape == (4, 2)  # closing vertex dropped
    assert polys[0].rings[0].dtype == np.float64
    assert len(polys[1].rings) == 2
    assert polys[3].rings[0].shape == (3, 2)  # z dropped, an unclosed ring accepted
    assert polys[0].area() == pytest.approx(100 - 4)
    assert polys[1].area() == pytest.approx(200)
    assert polys[3].area() == pytest.approx(0.5)


def test_geojson_single_feature_and_bare_geometry(tmp_path):
    f = read_polygons(_write(tmp_path, "f.json", _feature({"type": "Polygon", "coordinates": [SQUARE]}, name="a")))
    g = read_polygons(_write(tmp_path, "g.json", {"type": "MultiPolygon", "coordinates": [[SQUARE, HOLE], [FAR]]}))
    assert [p.name for p in f] == ["a"] and [p.name for p in g] == ["0"]
    assert len(g[0].rings) == 3


def test_wkt_lines(tmp_path):
    text = ("# regions\n"
            "POLYGON ((0 0, 10 0, 10 10, 0 10, 0 0), (4 4, 6 4, 6 6, 4 6, 4 4))\n"
            "\n"
            "multipolygon Z (((20 0 1, 30 0 1, 30 10 1, 20 10 1, 20 0 1)), ((40 0 1, 41 0 1, 41 1 1, 40 0 1)))\n"
            "POLYGON((1e1 -2.5,1.5e1 -2.5,1.5e1 0,1e1 -2.5))\n")
    polys = read_polygons(_write(tmp_path, "r.wkt", text))
    assert [p.name for p in polys] == ["0", "1", "2"]
    assert polys[0].area() == pytest.approx(96)
    assert polys[1].area() == pytest.approx(100.5)
    np.testing.assert_array_equal(polys[2].rings[0], [[10, -2.5], [15, -2.5], [15, 0]])


@pytest.mark.parametrize("doc, needle", [
    ({"type": "FeatureCollection", "features": []}, "no features"),
    ({"type": "Point", "coordinates": [0, 0]}, "GeoJSON type 'Point'"),
    ([1, 2], "a JSON list"),
    (_feature({"type": "LineString", "coordinates": SQUARE}), "feature 0: a LineString geometry"),
    (_feature(None), "feature 0: no geometry"),
    (_feature({"type": "Polygon", "coordinates": [[[0, 0], [1, 1], [0, 0]]]}), "fewer than 3 distinct"),
    (_feature({"type": "Polygon", "coordinates": [[["a", 0], [1, 1], [0, 1]]]}), "malformed coordinates"),
    (_feature({"type": "Polygon", "coordinates": [[[0, 0], [1e400, 1], [0, 1]]]}), "non-finite"),
    (_feature({"type": "Polygon", "coordinates": []}), "non-empty list of rings"),
    ("POLYGON ((0 0, 1 0, 1 1, 0 0)\n", "unbalanced '('"),
    ("POLYGON ((0 0, 1 0, 1 1, 0 0)))\n", "unbalanced ')'"),
    ("POLYGON ((0 0, 1 x, 1 1, 0 0))\n", "malformed WKT"),
    ("POLYGON ((0 0, 1 0, 1 1, 0 0))\nLINESTRING (0 0, 1 1)\n", "line 2: found 'LINESTRING"),
    ("x,y\n1,2\n", "not a polygon file: found 'x,y"),
    ("", "an empty file"),
    ("{not json", "not valid JSON"),
])
def test_bad_files_name_the_file_and_what_was_found(tmp_path, doc, needle):
    p = _write(tmp_path, "bad.geojson", doc)
    with pytest.raises(UsageError) as e:
        read_polygons(p)
    assert str(e.value).startswith(f"{p}: ") and needle in str(e.value)


def test_missing_and_special_files_refused(tmp_path):
    with pytest.raises(UsageError, match="no such file"):
        read_polygons(tmp_path / "none.geojson")
    with pytest.raises(UsageError, match="is a directory"):
        read_polygons(tmp_path)


def test_region_index_matches_matplotlib_on_random_points():
    mpath = pytest.importorskip("matplotlib.path")
    rng = np.random.default_rng(34)
    # a star with a hole, a concave L, and an overlapping square: the first one wins
    t = np.linspace(0, 2 * np.pi, 23, endpoint=False)
    r = np.where(np.arange(23) % 2 == 0, 9.0, 3.5)
    star = np.c_[10 + r * np.cos(t), 10 + r * np.sin(t)]
    hole = np.c_[10 + 1.5 * np.cos(t[::-1]), 10 + 1.5 * np.sin(t[::-1])]
    ell = np.array([[20, 0], [30, 0], [30, 4], [24, 4], [24, 15], [20, 15]], float)
    over = np.array([[17, 8], [27, 8], [27, 12], [17, 12]], float)
    polys = [Polygon("star", [star, hole]), Polygon("ell", [ell]), Polygon("over", [over])]
    xy = rng.uniform(-2, 32, (20000, 2))
    got = region_index(xy, polys)

    def inside(rings):
        m = np.zeros(len(xy), bool)
        for ring in rings:
            m ^= mpath.Path(ring).contains_points(xy)
        return m
    want = np.full(len(xy), -1)
    for k in reversed(range(len(polys))):
        want[inside(polys[k].rings)] = k
    np.testing.assert_array_equal(got, want)
    assert got.dtype == np.int64
    assert {-1, 0, 1, 2} <= set(got.tolist())  # every case occurs


def test_edges_are_half_open_so_neighbours_share_no_point():
    left = Polygon("L", [np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)])
    right = Polygon("R", [np.array([[1, 0], [2, 0], [2, 1], [1, 1]], float)])
    # points on the shared edge x = 1, on the outer edges, and a corner
    xy = np.array([[1, 0.5], [0, 0.5], [2, 0.5], [0.5, 0], [0.5, 1], [1, 0]], float)
    both = region_index(xy, [left, right])
    only_right = region_index(xy, [right, left])
    swapped = np.select([only_right == 0, only_right == 1], [1, 0], -1)
    np.testing.assert_array_equal(both, swapped)  # disjoint regions: the same membership in either order
    assert both[0] == 1 and both[1] == 0 and both[2] == -1  # shared edge in exactly one: the right one
    assert both[3] == 0 and both[4] == -1  # bottom edge inside, top edge outside
    assert contains(xy, left.rings).sum() + contains(xy, right.rings).sum() == (both >= 0).sum()


def test_region_index_empty_and_nan():
    sq = Polygon("s", [np.array(SQUARE[:-1], float)])
    assert region_index(np.zeros((0, 2)), [sq]).shape == (0,)
    np.testing.assert_array_equal(region_index(np.array([[np.nan, 5.0], [5.0, 5.0]]), [sq]), [-1, 0])
    np.testing.assert_array_equal(region_index(np.array([[5.0, 5.0, 99.0]]), [sq]), [0])  # z ignored
