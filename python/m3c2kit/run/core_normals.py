"""The normals ``--normal-source core`` uses (section 3.1.2: normals given with the core points,
not fitted to a cloud), one rule for every command that takes them (m3c2 compare, m3c2 series):
``--core-normals FILE``, else the core file's normal fields (nx, ny, nz), else a UsageError
naming what is missing."""
from __future__ import annotations

from pathlib import Path
from typing import Callable

import numpy as np

from ..base.errors import UsageError

__all__ = ["given_core_normals", "require_one_per_core_point"]


def given_core_normals(normals_file: Path | None, core_cloud, read: Callable) -> np.ndarray:
    """The (N, 3) normals of ``--normal-source core``: those of `normals_file` (its coordinates
    read as nx, ny, nz by `read`, which reads a cloud as the command reads its inputs), else the
    normal fields of `core_cloud` (the m3c2kit.io.Cloud of --core, or None when none was given)."""
    if normals_file is not None:
        return read(normals_file).xyz
    if core_cloud is None:
        raise UsageError("--normal-source core needs --core with normal fields (nx, ny, nz) or --core-normals FILE")
    normals = core_cloud.normals()
    if normals is None:
        raise UsageError(f"{core_cloud.path}: no normal fields (nx, ny, nz) for --normal-source core; "
                         f"use --core-normals FILE")
    return normals


def require_one_per_core_point(normals: np.ndarray, core_count: int) -> None:
    """A UsageError unless there is one given normal per core point (as m3c2kit.compare says)."""
    if len(normals) != core_count:
        raise UsageError(f"core_normals has {len(normals)} rows for {core_count} core points")
