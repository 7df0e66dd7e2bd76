"""Region polygons in the clouds' own XY coordinates: the regions ``m3c2 aggregate`` sums over
and the stable areas ``m3c2 variogram`` fits on.

Two formats, told apart by their content (not their extension):

* GeoJSON (RFC 7946): a FeatureCollection, a Feature, or a bare Polygon or MultiPolygon
  geometry. A feature's name is its property ``"name"``, else its property ``"id"``, else the
  feature's own ``"id"`` member, else its index in the file (``"0"``, ``"1"``, ...). A bare
  geometry is named ``"0"``.
* WKT: a text file of one ``POLYGON ((...), (...))`` or ``MULTIPOLYGON (((...)), ((...)))`` per
  line (blank lines and lines starting with ``#`` skipped), named by their index among the
  polygons (``"0"``, ``"1"``, ...). ``Z``/``M`` coordinates are accepted and only X, Y kept.

A :class:`Polygon` keeps every ring of its parts: for each part its exterior ring, then that
part's holes. Inside is the even-odd rule over all rings (a point inside an odd number of rings),
which for valid (OGC simple-feature) polygons is exactly "inside a part's exterior and in none of
its holes", and needs no ring orientation. A point exactly on an edge follows the half-open
crossing rule (inside on left/bottom edges, outside on right/top ones), so a point on the edge
shared by two adjacent polygons lies in exactly one of them.

Anything else (another geometry type, malformed coordinates, a ring of fewer than 3 distinct
vertices, non-finite coordinates, a region of zero area or with crossing edges, a file that is
neither format) is a :class:`UsageError` naming the file and what was found. A GeoJSON `crs`
member is read (read_polygons_and_crs) so that a command can check it against its data's CRS.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..base.errors import UsageError, printable
from .input_file import parse_json, read_small_text
from .polygon_checks import check_region

__all__ = ["Polygon", "read_polygons", "read_polygons_and_crs", "region_index", "contains"]

_KIND = "polygon file"


@dataclass(frozen=True)
class Polygon:
    """A named region: its rings ((k, 2) float64 XY), each part's exterior then its holes."""
    name: str
    rings: list[np.ndarray]

    def area(self) -> float:
        """The area inside (even-odd: a ring nested in an odd number of others is a hole and
        subtracts), by the shoelace formula."""
        total = 0.0
        for k, ring in enumerate(self.rings):
            depth = sum(bool(contains(ring[:1], [r])[0]) for j, r in enumerate(self.rings) if j != k)
            total += _ring_area(ring) * (-1.0 if depth % 2 else 1.0)
        return total


def _ring_area(ring: np.ndarray) -> float:
    x, y = ring[:, 0], ring[:, 1]
    with np.errstate(over="ignore", invalid="ignore"):  # vertices near 1e300: inf or NaN, refused by check_region
        return abs(0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))


def _ring(coords, path: Path, where: str) -> np.ndarray:
    """One ring as (k, 2) float64, the closing vertex dropped; errors name `where`."""
    try:
        arr = np.array(coords, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        raise UsageError(f"{path}: {where}: malformed coordinates (expected a list of [x, y] positions)") from None
    if arr.ndim != 2 or arr.shape[1] < 2:
        raise UsageError(f"{path}: {where}: malformed coordinates (expected a list of [x, y] positions, "
                         f"got an array of shape {arr.shape})")
    arr = np.ascontiguousarray(arr[:, :2])
    if not np.isfinite(arr).all():
        raise UsageError(f"{path}: {where}: non-finite coordinates")
    if len(arr) > 1 and (arr[0] == arr[-1]).all():
        arr = arr[:-1]
    if len(np.unique(arr, axis=0)) < 3:
        raise UsageError(f"{path}: {where}: a ring of fewer than 3 distinct vertices")
    return arr


def _polygon_rings(coords, path: Path, where: str) -> list[np.ndarray]:
    if not isinstance(coords, list) or not coords:
        raise UsageError(f"{path}: {where}: a Polygon needs a non-empty list of rings")
    return [_ring(r, path, f"{where}, ring {k}") for k, r in enumerate(coords)]


def _geometry_rings(geom, path: Path, where: str) -> list[np.ndarray]:
    if not isinstance(geom, dict):
        raise UsageError(f"{path}: {where}: no geometry (found {type(geom).__name__})")
    kind, coords = geom.get("type"), geom.get("coordinates")
    if kind == "Polygon":
        return _polygon_rings(coords, path, where)
    if kind == "MultiPolygon":
        if not isinstance(coords, list) or not coords:
            raise UsageError(f"{path}: {where}: a MultiPolygon needs a non-empty list of polygons")
        return [r for k, part in enumerate(coords) for r in _polygon_rings(part, path, f"{where}, part {k}")]
    raise UsageError(f"{path}: {where}: a {printable(kind)} geometry, not a Polygon or MultiPolygon")


def _feature_name(feature: dict, index: int) -> str:
    props = feature.get("properties") if isinstance(feature.get("properties"), dict) else {}
    for value in (props.get("name"), props.get("id"), feature.get("id")):
        if isinstance(value, bool) or value is None:
            continue
        if isinstance(value, (str, int, float)):
            return str(value)
    return str(index)


def _from_geojson(doc, path: Path) -> list[Polygon]:
    kind = doc.get("type") if isinstance(doc, dict) else None
    if kind == "FeatureCollection":
        features = doc.get("features")
        if not isinstance(features, list):
            raise UsageError(f"{path}: a FeatureCollection without a list of features")
    elif kind == "Feature":
        features = [doc]
    elif kind in ("Polygon", "MultiPolygon"):
        return [Polygon("0", _geometry_rings(doc, path, "the geometry"))]
    else:
        found = f"a JSON {type(doc).__name__}" if kind is None else f"GeoJSON type {printable(kind)!r}"
        raise UsageError(f"{path}: found {found}; expected a GeoJSON FeatureCollection, Feature, Polygon or "
                         "MultiPolygon")
    out = []
    for k, f in enumerate(features):
        if not isinstance(f, dict) or f.get("type") != "Feature":
            raise UsageError(f"{path}: feature {k} is not a GeoJSON Feature")
        out.append(Polygon(_feature_name(f, k), _geometry_rings(f.get("geometry"), path, f"feature {k}")))
    if not out:
        raise UsageError(f"{path}: a FeatureCollection with no features")
    return out


_WKT_HEAD = re.compile(r"\s*(MULTIPOLYGON|POLYGON)\s*(ZM|Z|M)?\s*(?=\()", re.IGNORECASE)
_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_POSITION = re.compile(rf"\s*({_NUMBER})\s+({_NUMBER})(?:\s+{_NUMBER}){{0,2}}\s*")


def _wkt_nested(text: str, where: str, path: Path):
    """The bracketed lists of `text` (after the keyword) as nested Python lists of positions."""
    stack: list[list] = []
    root = None
    pos = 0
    n = len(text)
    while pos < n:
        c = text[pos]
        if c.isspace() or c == ",":
            pos += 1
        elif c == "(":
            new: list = []
            if stack:
                stack[-1].append(new)
            elif root is not None:
                raise UsageError(f"{path}: {where}: text after the polygon's closing bracket")
            else:
                root = new
            stack.append(new)
            pos += 1
        elif c == ")":
            if not stack:
                raise UsageError(f"{path}: {where}: unbalanced ')'")
            stack.pop()
            pos += 1
        else:
            m = _POSITION.match(text, pos)
            if not m or not stack:
                raise UsageError(f"{path}: {where}: malformed WKT near {printable(text[pos:pos + 20])!r}")
            stack[-1].append([float(m.group(1)), float(m.group(2))])
            pos = m.end()
    if stack or root is None:
        raise UsageError(f"{path}: {where}: unbalanced '('")
    return root


def _from_wkt(text: str, path: Path) -> list[Polygon]:
    out = []
    for lineno, line in enumerate(text.splitlines(), start=1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        where = f"line {lineno}"
        m = _WKT_HEAD.match(line)
        if not m:
            raise UsageError(f"{path}: {where}: found {printable(line.strip()[:40])!r}; expected a WKT POLYGON or "
                             "MULTIPOLYGON (one per line)")
        nested = _wkt_nested(line[m.end():], where, path)
        if m.group(1).upper() == "POLYGON":
            rings = _polygon_rings(nested, path, where)
        else:
            rings = [r for k, part in enumerate(nested) for r in _polygon_rings(part, path, f"{where}, part {k}")]
        out.append(Polygon(str(len(out)), rings))
    if not out:
        raise UsageError(f"{path}: no polygons (an empty WKT file)")
    return out


def read_polygons(path) -> list[Polygon]:
    """The polygons of a GeoJSON or WKT file (module docstring), in file order; each checked to
    have an area and no crossing edges (io/polygon_checks.py)."""
    polygons, _ = read_polygons_and_crs(path)
    return polygons


def read_polygons_and_crs(path) -> tuple[list[Polygon], str | None]:
    """read_polygons() and the CRS the file names (a GeoJSON `crs` member, as GeoJSON 2008 and
    GDAL write it; RFC 7946 files name none), None when it names none."""
    path = Path(path)
    text = read_small_text(path, _KIND, encoding="utf-8-sig")
    head = text.lstrip()[:1]
    if head in ("{", "["):
        doc = parse_json(text, _KIND, label=str(path))
        return _checked(_from_geojson(doc, path), path), _geojson_crs(doc, path)
    if _WKT_HEAD.match(text.lstrip().split("\n", 1)[0]) or head == "#":
        return _checked(_from_wkt(text, path), path), None
    found = printable(text.strip()[:40]) if text.strip() else "an empty file"
    raise UsageError(f"{path}: not a polygon file: found {found!r}; expected GeoJSON or WKT POLYGON/MULTIPOLYGON "
                     "lines")


def _checked(polygons: list[Polygon], path: Path) -> list[Polygon]:
    for polygon in polygons:
        check_region(polygon.rings, polygon.area(), path, f"region {printable(polygon.name)!r}")
    return polygons


def _geojson_crs(doc, path: Path) -> str | None:
    """The CRS a GeoJSON document names in its `crs` member ({"type": "name", "properties":
    {"name": "EPSG:32633" or "urn:ogc:def:crs:EPSG::32633"}}), None without one."""
    crs = doc.get("crs") if isinstance(doc, dict) else None
    if crs is None:
        return None
    name = crs.get("properties", {}).get("name") if isinstance(crs, dict) and isinstance(crs.get("properties"), dict) \
        else None
    if not isinstance(name, str) or not name.strip():
        raise UsageError(f"{path}: its crs member names no CRS (expected {{\"type\": \"name\", \"properties\": "
                         f"{{\"name\": \"EPSG:...\"}}}})")
    m = re.fullmatch(r"urn:ogc:def:crs:EPSG:[0-9.]*:(\d+)", name.strip())
    if m:
        return f"EPSG:{m.group(1)}"
    if name.strip() == "urn:ogc:def:crs:OGC:1.3:CRS84":
        return "OGC:CRS84"
    return name.strip()


def contains(xy: np.ndarray, rings) -> np.ndarray:
    """Even-odd membership of the points `xy` ((n, 2)) in `rings` (half-open crossing rule).

    The points are sorted by y once; each edge then tests only the points whose y lies in its
    half-open span [min y, max y) (two binary searches), so the work is about n times the number
    of edges a horizontal line crosses, not n times the number of edges."""
    xy = np.asarray(xy, dtype=np.float64)
    inside = np.zeros(len(xy), dtype=bool)
    if len(xy) == 0:
        return inside
    x, y = xy[:, 0], xy[:, 1]
    order = np.argsort(y, kind="stable")
    ys = y[order]
    for ring in rings:
        a = ring
        b = np.roll(ring, -1, axis=0)
        for (ax, ay), (bx, by) in zip(a, b):
            if ay == by:
                continue  # a horizontal edge is crossed by no half-open span
            lo = np.searchsorted(ys, min(ay, by), side="left")
            hi = np.searchsorted(ys, max(ay, by), side="left")
            if hi <= lo:
                continue
            idx = order[lo:hi]
            xc = ax + (y[idx] - ay) * (bx - ax) / (by - ay)
            inside[idx] ^= x[idx] < xc
    return inside


def region_index(xy: np.ndarray, polygons) -> np.ndarray:
    """The index of the first polygon containing each point of `xy` ((n, 2)), -1 if none."""
    xy = np.asarray(xy, dtype=np.float64)
    if xy.ndim != 2 or xy.shape[1] < 2:
        raise ValueError(f"xy must be (n, 2), got {xy.shape}")
    xy = xy[:, :2]
    out = np.full(len(xy), -1, dtype=np.int64)
    for k, poly in enumerate(polygons):
        free = np.flatnonzero(out < 0)
        if len(free) == 0:
            break
        rings = poly.rings
        lo = np.min([r.min(axis=0) for r in rings], axis=0)
        hi = np.max([r.max(axis=0) for r in rings], axis=0)
        box = free[((xy[free] >= lo) & (xy[free] <= hi)).all(axis=1)]
        if len(box):
            out[box[contains(xy[box], rings)]] = k
    return out


def read_regions_for(path, cloud, option: str = "--regions") -> list[Polygon]:
    """The polygons of `path` for the points of `cloud` (a read point cloud): the CRS the file names,
    if any, must be the cloud's (issue 42: EPSG:4326 regions over a UTM result summed 0 points and
    wrote NaN with exit 0). A file naming none is taken to be in the cloud's coordinates."""
    import warnings

    from ..base.errors import M3C2Warning
    from .crs import _has_pyproj, crs_label, parse_crs, same_horizontal_crs
    polygons, crs = read_polygons_and_crs(path)
    if crs is None:
        return polygons
    if _has_pyproj() and parse_crs(crs) is None:
        raise UsageError(f"{option} {path}: its CRS {crs_label(crs)} cannot be read: name one PROJ knows "
                         f"(as EPSG:32633 or urn:ogc:def:crs:EPSG::32633) or none (the data's coordinates)")
    if not cloud.crs:
        warnings.warn(f"{option} {path}: the regions are in {crs_label(crs)}, {cloud.path or 'the data'} names no CRS: "
                      f"the regions are taken to be in its coordinates", M3C2Warning, stacklevel=2)
        return polygons
    if same_horizontal_crs(crs, cloud.crs) is False:  # plan-view regions: the horizontal part
        raise UsageError(f"{option} {path}: the regions are in {crs_label(crs)}, {cloud.path or 'the data'} in "
                         f"{crs_label(cloud.crs)}: reproject the regions into the data's CRS")
    return polygons


def require_points_inside(inside: np.ndarray, xy: np.ndarray, polygons: list[Polygon], path, data) -> list[str]:
    """`inside`: each polygon's count of points of `data` (its xy, (n, 2)). A UsageError when no
    polygon holds any, with both extents (another CRS, another site); else the names of those
    that hold none, for a warning each (a NaN row that nobody explains)."""
    if len(polygons) and not np.any(inside):
        rings = np.concatenate([r for p in polygons for r in p.rings])
        lo, hi = rings.min(axis=0), rings.max(axis=0)
        have = (f"x {xy[:, 0].min():.6g}..{xy[:, 0].max():.6g}, y {xy[:, 1].min():.6g}..{xy[:, 1].max():.6g}"
                if len(xy) else "no points")
        raise UsageError(f"{path}: no region holds a point of {data} (regions x {lo[0]:.6g}..{hi[0]:.6g}, "
                         f"y {lo[1]:.6g}..{hi[1]:.6g}; {data}: {have}): another CRS, or another site?")
    return [p.name for p, count in zip(polygons, inside) if count == 0]
