"""2D mode (paper section 6.1.2): M3C2 on a regular grid of core points with vertical normals,
written as GeoTIFF rasters, the M3C2 substitute for a DEM of difference (DoD).

    m3c2 compare REF CMP -o change.laz --grid 1.0 --max-depth 5

builds one core point per non-empty cell of a CELL-sized grid over the reference (z = median z
of the reference points in the cell), imposes vertical normals, uses d = 1.1 x CELL ("a
projection scale slightly larger than the grid spacing, to approximate the averaging over one
square pixel") unless --projection-scale is given, and writes, beside the point table,

    <stem>_distance.tif  float32, NaN = nodata    M3C2 distance (vertical change)
    <stem>_lod.tif       float32, NaN = nodata    level of detection
    <stem>_significant.tif uint8 0/1, 255 = nodata
    <stem>_n1.tif, <stem>_n2.tif int32 point counts, -1 = nodata
    <stem>_status.tif    uint8 status code (0 = ok, see README), 255 = nodata

Nodata marks a cell with no reference point (no core point) or a value that was not computed.
Every output of one run is staged and renamed at the end (m3c2kit.io.atomic.staged_outputs), so a
failed run leaves none of them. See docs/report.md.
"""
from __future__ import annotations

import math
import os
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import engine
from ..base import portable
from ..base.errors import CloudWriteError, M3C2Error, UsageError
from ..io.arrays import bounds
from ..io.quantised import as_float32
from ..io.guard import available_memory, format_bytes
from ..settings.limits import usable_length
from ..io.crs import looks_like_wkt
from ..base.optional import require

__all__ = ["Grid", "RASTERS", "PROJECTION_FACTOR", "grid_core_points", "grid_settings",
           "raster_paths", "rasters", "write_rasters"]

#: d = PROJECTION_FACTOR x cell when --projection-scale is not given (section 6.1.2).
PROJECTION_FACTOR = 1.1

#: Raster name -> (numpy dtype, nodata, description). Distance and LOD are float32: they are
#: differences (not absolute coordinates, which live in the float64 geotransform), so float32's
#: relative precision of 6e-8 is far below any LOD, and it halves the file size.
RASTERS = {
    "distance": ("float32", float("nan"), "M3C2 distance along the vertical normal (compared - reference)"),
    "lod": ("float32", float("nan"), "level of detection (LOD) at the run's confidence"),
    "significant": ("uint8", 255, "1 where |distance| > LOD, 0 where not, 255 where no LOD"),
    "n1": ("int32", -1, "reference points in the cylinder"),
    "n2": ("int32", -1, "compared points in the cylinder"),
    "status": ("uint8", 255, "status code: 0 ok, 1-5 see the README's status table"),
}


@dataclass
class Grid:
    """The engine's grid of core points: cell (row, col) has its centre at
    (x0 + (col + 0.5) cell, y0 + (row + 0.5) cell); row 0 is the LOWEST y."""

    x0: float
    y0: float
    cell: float
    rows: int
    cols: int
    core_points: np.ndarray  # (K, 3), one per non-empty cell
    row: np.ndarray          # (K,) uint64
    col: np.ndarray          # (K,) uint64

    @property
    def transform(self):
        """GeoTIFF geotransform: the top-left corner (x0, max y), rows going DOWN (south)."""
        Affine = require("rasterio.transform", extra="raster", purpose="GeoTIFF rasters (--grid)").Affine
        return Affine(self.cell, 0.0, self.x0, 0.0, -self.cell, self.y0 + self.rows * self.cell)

    def image_rows(self) -> np.ndarray:
        """Row of each core point in the image (row 0 = top = max y): the engine's rows flipped."""
        return (self.rows - 1 - self.row.astype(np.int64)).astype(np.int64)

    def image(self, values: np.ndarray, dtype, nodata) -> np.ndarray:
        """(rows, cols) array with `values` (one per core point) at their cells, nodata elsewhere."""
        out = np.full((self.rows, self.cols), nodata, dtype=dtype)
        out[self.image_rows(), self.col.astype(np.int64)] = values
        return out


#: Bytes per raster cell while the images exist together (rasters(): the six images, 18 bytes a
#: cell, plus the one being written, which GDAL builds in memory, deflated: at most about 4 bytes a
#: cell, write_rasters): the images cover every cell of the grid, empty or not, so a
#: small --grid on a large cloud is sized by its extent, not by its points.
RASTER_BYTES_PER_CELL = sum(np.dtype(t).itemsize for t, _, _ in RASTERS.values()) + 4


def check_raster_memory(xyz: np.ndarray, cell: float, available: int | None = None) -> int:
    """Raster cells of a --grid `cell` over the XY extent of `xyz`; a RasterTooLarge naming --grid
    when the images would not fit the available memory (io.guard.available_memory)."""
    if len(xyz) == 0:
        return 0
    lo, hi = bounds(xyz[:, :2])
    extent = hi - lo
    cols, rows = (np.floor(extent / cell) + 1).tolist()
    cells = cols * rows
    available = available_memory() if available is None else available
    needed = cells * RASTER_BYTES_PER_CELL
    if available is not None and needed > available:
        smallest = cell * math.sqrt(needed / available)
        raise RasterTooLarge(f"--grid {cell:g} makes rasters of {int(cols)} x {int(rows)} cells over the reference's "
                             f"{extent[0]:.6g} x {extent[1]:.6g} extent ({format_bytes(needed)} for the "
                             f"{len(RASTERS)} rasters) but only {format_bytes(available)} is available; use a larger "
                             f"--grid (at least about {smallest:.3g})")
    return int(cells)


class RasterTooLarge(M3C2Error):
    """The rasters of a --grid run would not fit in memory (exit status 1)."""


def grid_core_points(points, cell: float) -> Grid:
    """One core point per non-empty `cell`-sized cell over the XY extent of `points`."""
    xyz = np.ascontiguousarray(getattr(points, "xyz", points), dtype=np.float64)
    check_raster_memory(xyz, float(cell))
    g = engine.grid_core_points(xyz, float(cell), "--grid")
    return Grid(float(g["x0"]), float(g["y0"]), float(g["cell"]), int(g["rows"]), int(g["cols"]),
                np.asarray(g["core_points"]).reshape(-1, 3), np.asarray(g["row"]), np.asarray(g["col"]))


def grid_settings(cell, settings: dict, explicit: dict) -> dict:
    """The compare settings of 2D mode (section 6.1.2) for a --grid `cell`: vertical normals, and
    d = 1.1 x CELL unless a projection scale is set. `explicit` holds what the user gave on the
    command line: there a --normal-scale (which would only choose the normal), a --normal-source
    but vertical, --core-normals and --position reference/compared are usage errors; from a params
    file the normal scale and core point options are dropped (the grid is the core points)."""
    cell = usable_length("--grid", cell)  # finite, > 0, not denormal
    if explicit.get("normal_scale") is not None:
        raise UsageError("--grid imposes vertical normals (section 6.1.2): --normal-scale has no effect; "
                         "leave it out")
    if explicit.get("normal_source") not in (None, "vertical"):
        raise UsageError(f"--grid imposes vertical normals: --normal-source {explicit['normal_source']} is not allowed")
    if explicit.get("core_normals") is not None:
        raise UsageError("--grid imposes vertical normals: --core-normals is not allowed")
    if explicit.get("position") not in (None, "core"):
        raise UsageError("--grid writes values at the cell centres: --position must be core")
    if settings.get("position", "core") != "core":
        raise UsageError("--grid writes values at the cell centres: the position must be core")
    settings = dict(settings)
    settings["normal_source"] = "vertical"
    for name in ("normal_scale", "core_spacing", "normal_subsample"):
        settings.pop(name, None)
    settings.setdefault("projection_scale", PROJECTION_FACTOR * float(cell))
    return settings


def raster_paths(output: str | os.PathLike, names=tuple(RASTERS)) -> dict[str, Path]:
    """`<stem>_<name>.tif` beside `output` for each raster name (stem: the name without its
    extension, e.g. change.copc.laz -> change)."""
    output = Path(output)
    stem = output.name
    for ext in (".copc.laz",):
        if stem.lower().endswith(ext):
            stem = stem[: -len(ext)]
            break
    else:
        stem = output.stem
    return {name: output.with_name(f"{stem}_{name}.tif") for name in names}


def rasters(result, grid: Grid, paths: dict[str, Path] | None = None) -> dict[str, np.ndarray]:
    """The raster images (row 0 = top = max y) of a Result computed at `grid.core_points`;
    `paths` (raster_paths) name the files in the error of a value float32 cannot hold."""
    if len(result) != len(grid.row):
        raise ValueError(f"the result has {len(result)} core points, the grid {len(grid.row)}")
    table = result.columns()
    values = {
        "distance": table["distance"],
        "lod": table["lod"],
        "significant": np.where(np.isnan(table["significant"]), 255, table["significant"]),
        "n1": np.where(np.isnan(table["n1"]), -1, table["n1"]),
        "n2": np.where(np.isnan(table["n2"]), -1, table["n2"]),
        "status": table["status"],
    }
    out = {}
    for name, (dtype, nodata, _) in RASTERS.items():
        column = np.asarray(values[name])
        if dtype == "float32":  # a GeoTIFF's cells are float32 whatever --float64 says
            column = as_float32(column, f"{paths[name]}: its cells" if paths else f"the {name} raster",
                                "--grid rasters are float32")
        out[name] = grid.image(column.astype(dtype), dtype, nodata)
    return out


def rasterio_crs(crs: str | None):
    """A rasterio CRS from Cloud.crs (WKT or "EPSG:n"), or None (with the reason) if there is none
    or GDAL cannot read it."""
    if not crs:
        return None, "the reference cloud has no CRS"
    CRS = require("rasterio.crs", extra="raster", purpose="reading a CRS for the GeoTIFF rasters").CRS
    from rasterio.errors import CRSError
    try:
        return (CRS.from_wkt(crs) if looks_like_wkt(crs) else CRS.from_string(crs)), None
    except CRSError as e:
        return None, f"GDAL cannot read the reference's CRS ({e})"


def write_rasters(paths: dict[str, Path], images: dict[str, np.ndarray], grid: Grid, crs: str | None, *,
                  targets: dict[str, Path] | None = None, warn=None) -> None:
    """Writes each image to paths[name] as a single-band, deflate-compressed, tiled GeoTIFF with
    the grid's geotransform, nodata and band description, and the CRS `crs` (Cloud.crs). Without
    a usable CRS the rasters are written without one and `warn` (default: print to stderr) is
    told, once. `targets` are the final names used in messages (paths may be temporary)."""
    rasterio = require("rasterio", extra="raster", purpose="writing GeoTIFF rasters (--grid)")

    rio_crs, why = rasterio_crs(crs)
    if rio_crs is None:
        (warn or _warn)(f"{why}: the GeoTIFF rasters are written without a CRS")
    for name, image in images.items():
        dtype, nodata, description = RASTERS[name]
        profile = dict(driver="GTiff", width=grid.cols, height=grid.rows, count=1, dtype=dtype, nodata=nodata,
                       transform=grid.transform, compress="deflate", BIGTIFF="IF_SAFER")
        if grid.cols >= 256 and grid.rows >= 256:
            profile.update(tiled=True, blockxsize=256, blockysize=256)
        if rio_crs is not None:
            profile["crs"] = rio_crs
        target = (targets or paths)[name]
        try:
            # GDAL writes into memory: its own writes to disk drop errors raised while it closes
            # a file (a full disk left 0-byte rasters and exit 0); every byte then goes through
            # _copy_out, whose OS errors name the target.
            with rasterio.Env(GDAL_PAM_ENABLED="NO"), rasterio.MemoryFile() as memory:
                with memory.open(**profile) as dst:
                    dst.write(image, 1)
                    dst.set_band_description(1, description)
                    dst.update_tags(1, name=name)
                _copy_out(memory, paths[name], target)
        except rasterio.errors.RasterioError as e:
            raise CloudWriteError(f"{target}: cannot write GeoTIFF: {str(e).replace(str(paths[name]), str(target))}") \
                from None


#: Bytes copied per write from GDAL's in-memory GeoTIFF to the file.
_COPY_CHUNK = 1 << 20


def _copy_out(memory, path, target) -> None:
    """Copies an in-memory GeoTIFF to `path` with os.write (each short write continued); an OS
    error (no space, a file size limit) is a CloudWriteError naming `target`, never `path`,
    which may be a temporary (docs/errors.md, "Output")."""
    memory.seek(0)
    try:
        fd = portable.open_nofollow(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o666)
        try:
            while True:
                chunk = memoryview(memory.read(_COPY_CHUNK))
                if not chunk:
                    break
                while chunk:
                    chunk = chunk[os.write(fd, chunk):]
        finally:
            os.close(fd)
    except OSError as e:
        raise CloudWriteError(f"{target}: {e.strerror or e}") from None


def _warn(message: str) -> None:
    print(f"m3c2: warning: {message}", file=sys.stderr)
