"""Everything `m3c2 compare` writes: the point table, and with --grid the GeoTIFF rasters, with
--report / --report-png the visual report; all staged and renamed together at the end, so that a
failed run leaves none of them (and leaves any older files at those paths untouched)."""
from __future__ import annotations

from pathlib import Path

from .. import raster
from ..result import Result
from ..writing import write


def _inputs(args, reference, grid) -> dict:
    out = {"reference": str(args.reference), "compared": str(args.compared), "output": str(args.output),
           "reference points": len(reference)}
    if grid is not None:
        out["grid cell (2D mode, vertical normals)"] = grid.cell
        out["grid rows x cols"] = f"{grid.rows} x {grid.cols}"
    crs = getattr(reference, "crs", None)
    out["reference CRS"] = (crs[:120] + "...") if crs and len(crs) > 120 else (crs or "none")
    return out


def write_compare_outputs(args, result: Result, reference, *, grid=None, position: str = "core",
                          field_names: str = "m3c2", float64: bool = False, core_spacing=None) -> list[Path]:
    """Writes the point table to args.output and, as asked, the rasters (grid) and the report.
    Returns the paths written besides args.output."""
    html_path = getattr(args, "report", None)
    png_prefix = getattr(args, "report_png", None)
    projected = getattr(args, "projected", False)
    if grid is None and html_path is None and png_prefix is None:
        write(args.output, result, like=reference, projected=projected, position=position,
              field_names=field_names, float64=float64)
        return []
    from . import png_paths, write_report

    rasters = raster.raster_paths(args.output) if grid is not None else {}
    pngs = png_paths(png_prefix) if png_prefix is not None else {}
    extra = list(rasters.values()) + ([Path(html_path)] if html_path is not None else []) + list(pngs.values())
    targets = [Path(args.output)] + extra
    if len(set(targets)) != len(targets):
        raise raster.UsageError("the output, raster, report and PNG paths must all differ")
    with raster.staged_outputs(targets) as staged:
        write(staged[Path(args.output)], result, like=reference, projected=projected, position=position,
              field_names=field_names, float64=float64)
        images = None
        if grid is not None:
            images = raster.rasters(result, grid)
            raster.write_rasters({k: staged[p] for k, p in rasters.items()}, images, grid,
                                 getattr(reference, "crs", None), targets=rasters)
        if html_path is not None or png_prefix is not None:
            write_report(result, html_path, png_prefix, staged=staged, grid=grid, images=images,
                         crs=getattr(reference, "crs", None), units=getattr(reference, "units_hint", None),
                         core_spacing=core_spacing,
                         inputs=_inputs(args, reference, grid))
    return extra
