"""Writing a Result to any supported output format (atomically: no partial file on failure)."""
from __future__ import annotations

from pathlib import Path

from .. import engine
from ..engine.result import Result
from ..io import Cloud, write_cloud_table
from ..io.fields import TableStyle, carried_columns, core_attributes
from ..io.input_file import path_argument
from ..io.registry import quantises

_DEFAULT = TableStyle()


def write(path, result: Result, *, like: Cloud | None = None, projected: bool = _DEFAULT.projected,
          position: str = _DEFAULT.position, field_names: str = _DEFAULT.field_names,
          float64: bool = _DEFAULT.float64, attributes: bool | dict = _DEFAULT.attributes,
          all_fields: bool = _DEFAULT.all_fields) -> None:
    """Writes the output columns of `result` to `path` (.las/.laz/.ply/.csv/.txt), keeping `like`'s
    CRS, scale and offset for LAS. `position` places rows at the core points, or at their
    projections on the reference or compared cloud. `field_names` ("m3c2", "cloudcompare",
    "pdal") names the columns (m3c2kit.io.fields.FIELDS); measured values are stored as float32
    (LAS/LAZ: as integers at 0.1 mm, m3c2kit.io.quantised) unless `float64`; a LAS/LAZ file
    carries CloudCompare's default columns and ``status`` unless `all_fields` (the defaults:
    m3c2kit.io.fields.TableStyle). The attributes of `like`'s points that are the core points
    (intensity, classification, GPS time, RGB, ...) are carried beside them (LAS standard fields
    filled) unless not `attributes`; `attributes` may also be those columns already matched, in
    core-point order (a tiled run's, m3c2kit.run.attributes, which streams the reference)."""
    style = TableStyle(projected=projected, position=position, field_names=field_names, float64=float64,
                       all_fields=all_fields, attributes=bool(attributes))
    write_table(path, result, style, like=like, attributes=attributes if isinstance(attributes, dict) else None)


def write_table(path, result: Result, style: TableStyle, *, like: Cloud | None = None,
                attributes: dict | None = None) -> None:
    """:func:`write` with its options as a :class:`~m3c2kit.io.fields.TableStyle`; `attributes`:
    the core points' attributes already matched (else, as the style asks, those of `like`)."""
    path = path_argument("path", path)
    if not isinstance(result, Result):  # a str or an array has no .columns: say what write() takes
        raise TypeError(f"result must be an m3c2kit.Result (what m3c2kit.compare returns), got {type(result).__name__}")
    xyz, table = style.rows(result)
    fields = style.stored(table, quantises(path), path)
    if attributes is not None:
        fields.update(carried_columns(attributes, set(fields)))
    elif style.attributes and getattr(like, "fields", None) and len(result.core):
        # The reference point each core point is, matched in the engine (src/match_rows.cpp).
        fields.update(core_attributes(like, engine.match_rows(like.xyz, result.core), set(fields)))
    write_cloud_table(Path(path), xyz, fields, like=like)
