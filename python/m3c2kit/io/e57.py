"""E57 reading through pye57 (libE57Format).

All scans are read and concatenated in file order, each moved into the file's coordinate
frame by its pose (rotation quaternion, then translation); spherical-only scans are converted
to cartesian by pye57 first. Points flagged invalid (``cartesianInvalidState`` or
``sphericalInvalidState`` != 0) are skipped. ``scan_positions`` holds one row per scan: the
pose translation, i.e. the scanner origin in file coordinates (the origin itself for a scan
without a pose, which E57 defines as the identity). E57 coordinates are metres by definition.
The field ``scan_index`` gives each point its scan's number, counted from 1 (the row of
``scan_positions`` plus one): M3C2-EP's scan-position id (``--scan-position-field scan_index``).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..base.errors import CloudReadError
from ..base.optional import lazy_module
from .cloud import Cloud
from .crs import looks_like_wkt
from .guard import read_errors

pye57 = lazy_module("pye57", extra="e57", purpose="reading .e57 files")

__all__ = ["read"]

_SIGNATURE = b"ASTM-E57"
_CARTESIAN = ("cartesianX", "cartesianY", "cartesianZ")
_SPHERICAL = ("sphericalRange", "sphericalAzimuth", "sphericalElevation")


def read(path: Path) -> Cloud:
    """Reads every scan of an E57 file (see the module docstring)."""
    with open(path, "rb") as f:
        if f.read(len(_SIGNATURE)) != _SIGNATURE:
            raise CloudReadError(f"{path}: not an E57 file (no 'ASTM-E57' signature)")
    with read_errors(path):
        e57 = pye57.E57(str(path))
        try:
            return _read_all(path, e57)
        finally:
            e57.close()


def _read_all(path: Path, e57: pye57.E57) -> Cloud:
    parts: list[np.ndarray] = []
    scan_index: list[np.ndarray] = []
    positions = np.zeros((e57.scan_count, 3))
    for i in range(e57.scan_count):
        header = e57.get_header(i)
        positions[i] = header.translation if header.has_pose() else 0.0
        fields = header.point_fields
        if not (all(f in fields for f in _CARTESIAN) or all(f in fields for f in _SPHERICAL)):
            raise CloudReadError(f"{path}: scan {i} has neither cartesian nor spherical coordinates "
                                 f"(fields: {', '.join(fields)})")
        # libE57Format refuses to open a reader on an empty point section, valid or not.
        if header.point_count == 0:
            continue
        data = e57.read_scan(i, ignore_missing_fields=True, intensity=False, colors=False,
                             row_column=False, transform=True)
        parts.append(np.column_stack([data[c] for c in _CARTESIAN]).astype(np.float64, copy=False))
        scan_index.append(np.full(len(parts[-1]), i + 1, dtype=np.uint32))
    xyz = np.concatenate(parts) if parts else np.empty((0, 3))
    root = e57.root
    metadata = root["coordinateMetadata"].value() if root.isDefined("coordinateMetadata") else ""
    fields = {"scan_index": np.concatenate(scan_index) if scan_index else np.empty(0, np.uint32)}
    return Cloud(xyz, fields, crs=metadata if looks_like_wkt(metadata) else None, scan_positions=positions,
                 path=Path(path), units_hint="metre", format="E57", meta={"scan_count": e57.scan_count})
