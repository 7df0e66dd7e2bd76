"""Writing a Result to any supported output format (atomically: no partial file on failure)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .io import Cloud, write_cloud_table
from .result import Result


def write(path, result: Result, *, like: Cloud | None = None, projected: bool = False,
          position: str = "core") -> None:
    """Writes the output columns of `result` to `path` (.las/.laz/.ply/.csv/.txt), keeping `like`'s
    CRS, scale and offset for LAS. `position` places rows at the core points, or at their
    projections on the reference or compared cloud."""
    table = result.columns(projected=projected, position=position)
    xyz = np.column_stack([table.pop("x"), table.pop("y"), table.pop("z")])
    write_cloud_table(Path(path), xyz, table, like=like)
