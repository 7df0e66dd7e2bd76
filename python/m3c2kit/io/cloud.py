"""The in-memory point cloud every reader returns."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = ["Cloud"]


@dataclass
class Cloud:
    """A point cloud as read from one file.

    Contract (checked on construction):

    * ``xyz``: (N, 3) float64, C-contiguous, in the file's own units and CRS (LAS: scaled
      coordinates; E57: metres, scan poses applied). N may be 0 only for clouds built by
      :func:`m3c2kit.io.info`; :func:`m3c2kit.io.read_cloud` never returns an empty cloud.
    * ``fields``: other per-point attributes, name -> 1-D array of length N (any numeric dtype);
      may be empty.
    * ``crs``: WKT text when the file carries one; for a LAS file with GeoTIFF keys only, an
      ``"EPSG:<code>"`` string; else None.
    * ``scale`` / ``offset``: the LAS header's (x, y, z) quantisation, None for other formats.
    * ``scan_positions``: (K, 3) scanner origins in file coordinates (E57: each scan's pose
      translation), or None when the format has none.
    * ``units_hint``: a human-readable linear unit (e.g. ``"metre"``, ``"US survey foot"``, or
      ``"metre (horizontal), US survey foot (vertical)"``) when the file or its CRS says so,
      else None. A hint only: nothing converts units.
    * ``format``: short format name (``"LAS"``, ``"LAZ"``, ``"COPC"``, ``"E57"``, ``"PLY"``,
      ``"ASCII"``, ``"NPY"``); ``meta``: format-specific details (LAS version, PLY encoding, ...).
    * ``dropped_nonfinite``: how many points with NaN/inf coordinates were dropped on request.
    """

    xyz: np.ndarray
    fields: dict[str, np.ndarray] = field(default_factory=dict)
    crs: str | None = None
    scale: tuple[float, float, float] | None = None
    offset: tuple[float, float, float] | None = None
    scan_positions: np.ndarray | None = None
    path: Path | None = None
    units_hint: str | None = None
    format: str = ""
    meta: dict = field(default_factory=dict)
    dropped_nonfinite: int = 0
    # Raw CRS records of a source LAS file, (user_id, record_id, description, data) tuples, so that
    # a LAS writer given like=this cloud can copy GeoTIFF keys verbatim when there is no WKT.
    _crs_vlrs: tuple = field(default=(), repr=False, compare=False)

    def __post_init__(self) -> None:
        xyz = np.ascontiguousarray(self.xyz, dtype=np.float64)
        if xyz.ndim != 2 or xyz.shape[1] != 3:
            raise ValueError(f"Cloud.xyz must have shape (N, 3), got {xyz.shape}")
        self.xyz = xyz
        n = len(xyz)
        for name, values in self.fields.items():
            if np.shape(values)[:1] != (n,) or np.ndim(values) != 1:
                raise ValueError(f"Cloud field {name!r} must have shape ({n},), got {np.shape(values)}")
        if self.scan_positions is not None:
            self.scan_positions = np.ascontiguousarray(self.scan_positions, dtype=np.float64).reshape(-1, 3)
        if self.path is not None:
            self.path = Path(self.path)

    def __len__(self) -> int:
        return len(self.xyz)

    #: Spellings of per-point normal fields (ours, CloudCompare's, PDAL's), first match wins.
    NORMAL_FIELDS = (("nx", "ny", "nz"), ("normalx", "normaly", "normalz"), ("normal_x", "normal_y", "normal_z"))

    def normals(self) -> np.ndarray | None:
        """(N, 3) float64 normals from the cloud's normal fields, or None when it has none."""
        fields = {k.lower(): v for k, v in self.fields.items()}
        for names in self.NORMAL_FIELDS:
            if all(n in fields for n in names):
                return np.column_stack([fields[n] for n in names]).astype(float)
        return None

    def select(self, mask: np.ndarray) -> "Cloud":
        """A copy holding only the points where `mask` (bool, length N) is True."""
        kept = {name: np.asarray(v)[mask] for name, v in self.fields.items()}
        return Cloud(self.xyz[mask], kept, self.crs, self.scale, self.offset, self.scan_positions,
                     self.path, self.units_hint, self.format, dict(self.meta), self.dropped_nonfinite,
                     self._crs_vlrs)
