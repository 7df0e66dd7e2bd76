"""Writing a Result to any supported output format (atomically: no partial file on failure)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .. import engine
from ..io import Cloud, write_cloud_table
from ..io.fields import core_attributes, typed_columns
from ..io.input_file import path_argument
from ..io.registry import format_for
from ..engine.result import Result


def write(path, result: Result, *, like: Cloud | None = None, projected: bool = False,
          position: str = "core", field_names: str = "m3c2", float64: bool = False,
          attributes: bool = True, all_fields: bool = False) -> None:
    """Writes the output columns of `result` to `path` (.las/.laz/.ply/.csv/.txt), keeping `like`'s
    CRS, scale and offset for LAS. `position` places rows at the core points, or at their
    projections on the reference or compared cloud. `field_names` ("m3c2", "cloudcompare",
    "pdal") names the columns (m3c2kit.io.fields.FIELDS); measured values are stored as float32
    (LAS/LAZ: as integers at 0.1 mm, m3c2kit.io.quantised) unless `float64`; a LAS/LAZ file
    carries CloudCompare's default columns and ``status`` unless `all_fields`. The attributes of `like`'s points that are the core points (intensity,
    classification, GPS time, RGB, ...) are carried beside them (LAS standard fields filled)
    unless not `attributes` (tiled runs stream the reference and carry none)."""
    path = path_argument("path", path)
    if not isinstance(result, Result):  # a str or an array has no .columns: say what write() takes
        raise TypeError(f"result must be an m3c2kit.Result (what m3c2kit.compare returns), got {type(result).__name__}")
    table = result.columns(projected=projected, position=position)
    xyz = np.column_stack([table.pop("x"), table.pop("y"), table.pop("z")])
    fmt = format_for(Path(path), writing=True)
    spaces = fmt is not None and fmt.name == "LAS/LAZ"  # text and PLY names cannot hold spaces
    fields = typed_columns(table, field_names=field_names, float64=float64, spaces=spaces, las=spaces,
                           all_fields=all_fields)
    if attributes and getattr(like, "fields", None) and len(result.core):
        # The reference point each core point is, matched in the engine (src/core_points/match_rows.cpp).
        fields.update(core_attributes(like, engine.match_rows(like.xyz, result.core), set(fields)))
    write_cloud_table(Path(path), xyz, fields, like=like)
