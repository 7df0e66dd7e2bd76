"""Training labels: one label for a whole file (FILE=LABEL), a per-point field of the file (LAS
classification, or any field), or polygons (GeoJSON, tested in XY).

Polygon files (docs/classify.md): a GeoJSON FeatureCollection whose features are Polygon or
MultiPolygon geometries in the clouds' own coordinates (XY), each with a label property
(``"label"`` unless told otherwise). Holes are honoured (even-odd rule); a point inside the
polygons of two different labels is refused as ambiguous; points in no polygon are not used.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..base.errors import UsageError
from ..io.input_file import read_small_json


def parse_sample(text: str) -> tuple[Path, str | None]:
    """'FILE=LABEL' -> (FILE, LABEL); 'FILE' -> (FILE, None). The last '=' splits, so a path may
    hold '=' when a label is given."""
    if "=" in text:
        path, label = text.rsplit("=", 1)
        if not label.strip() or not path:
            raise UsageError(f"sample {text!r}: expected FILE=LABEL with a non-empty label")
        return Path(path), label.strip()
    return Path(text), None


def parse_mapping(spec: str | None, option: str) -> dict[str, str]:
    """'a=b,c=d' -> {'a': 'b', 'c': 'd'}; None (the option not given) -> {}."""
    out: dict[str, str] = {}
    if spec is None:
        return out
    for item in spec.split(","):
        if not item.strip():
            continue
        if "=" not in item:
            raise UsageError(f"{option}: expected KEY=VALUE items separated by commas, got {item!r}")
        k, v = (s.strip() for s in item.split("=", 1))
        if not k or not v:
            raise UsageError(f"{option}: empty key or value in {item!r}")
        if k in out:  # the last one silently won before
            raise UsageError(f"{option}: {k} is given twice ({k}={out[k]} and {k}={v}); give each once")
        out[k] = v
    if not out:  # '' or ',' was the same as no option, silently
        raise UsageError(f"{option} is empty: give KEY=VALUE items separated by commas")
    return out


def field_value_name(v) -> str:
    """A field value as a label: integers without '.0'."""
    f = float(v)
    return str(int(f)) if f.is_integer() else repr(f)


def labels_from_field(cloud, field: str, path, value_names: dict[str, str]) -> np.ndarray:
    """Per-point labels from `field` of `cloud`; with `value_names`, only the values listed are
    labelled (as their names), the others unused ("")."""
    if field not in cloud.fields:
        have = ", ".join(sorted(cloud.fields)) or "none"
        raise UsageError(f"{path}: has no field {field!r} for --label-field (its fields: {have})")
    values = np.asarray(cloud.fields[field])
    out = np.full(len(values), "", dtype=object)
    for v in np.unique(values):
        name = field_value_name(v)
        if value_names:
            name = value_names.get(name, "")
        out[values == v] = name
    return out


def _ring_inside(x, y, ring: np.ndarray) -> np.ndarray:
    """Even-odd test of points (x, y) against a closed ring (K, 2): a horizontal ray to +x crosses
    the edge (a, b) when y lies in [min, max) of the edge's y and the crossing is right of x."""
    inside = np.zeros(len(x), dtype=bool)
    a = ring
    b = np.roll(ring, -1, axis=0)
    for (ax, ay), (bx, by) in zip(a, b):
        if ay == by:
            continue
        straddles = (ay <= y) != (by <= y)
        with np.errstate(divide="ignore", invalid="ignore"):
            xc = ax + (y - ay) * (bx - ax) / (by - ay)
        inside ^= straddles & (x < xc)
    return inside


def read_polygons(path: Path, prop: str) -> list[tuple[str, list[list[np.ndarray]]]]:
    """[(label, [polygon = [outer ring, hole, ...], ...]), ...] from a GeoJSON file."""
    doc = read_small_json(path, "polygon file")  # a FIFO, device or huge file refused there
    feats = doc.get("features") if isinstance(doc, dict) else None
    if doc.get("type") == "Feature" if isinstance(doc, dict) else False:
        feats = [doc]
    if not isinstance(feats, list) or not feats:
        raise UsageError(f"{path}: expected a GeoJSON FeatureCollection with Polygon features")
    out = []
    for k, f in enumerate(feats):
        f = f if isinstance(f, dict) else {}  # a forged file's feature may be any JSON value
        geom = f.get("geometry") if isinstance(f.get("geometry"), dict) else {}
        props = f.get("properties") if isinstance(f.get("properties"), dict) else {}
        if prop not in props:
            raise UsageError(f"{path}: feature {k} has no {prop!r} property (the label; see --polygon-property)")
        kind, coords = geom.get("type"), geom.get("coordinates")
        if kind == "Polygon":
            polys = [coords]
        elif kind == "MultiPolygon":
            polys = coords
        else:
            raise UsageError(f"{path}: feature {k} is a {kind}, not a Polygon or MultiPolygon")
        try:
            rings = [[np.asarray(r, dtype=float)[:, :2] for r in poly] for poly in polys]
        except (TypeError, ValueError, IndexError, OverflowError):
            raise UsageError(f"{path}: feature {k} has malformed coordinates") from None
        if any(len(r) < 3 for poly in rings for r in poly):
            raise UsageError(f"{path}: feature {k} has a ring of fewer than 3 points")
        label = props[prop]
        out.append((field_value_name(label) if isinstance(label, (int, float)) else str(label), rings))
    return out


def labels_from_polygons(xyz: np.ndarray, polygons, source) -> np.ndarray:
    """Per-point labels from polygons (XY); "" outside every polygon."""
    x, y = xyz[:, 0], xyz[:, 1]
    out = np.full(len(xyz), "", dtype=object)
    for label, polys in polygons:
        inside = np.zeros(len(xyz), dtype=bool)
        for rings in polys:
            inner = np.zeros(len(xyz), dtype=bool)
            for ring in rings:
                inner ^= _ring_inside(x, y, ring)
            inside |= inner
        clash = inside & (out != "") & (out != label)
        if clash.any():
            raise UsageError(f"{source}: {int(clash.sum())} points lie in polygons of two labels "
                             f"({out[clash][0]!r} and {label!r})")
        out[inside] = label
    return out
