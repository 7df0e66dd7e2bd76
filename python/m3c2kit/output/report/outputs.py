"""Everything `m3c2 compare` writes: the point table, and with --grid the GeoTIFF rasters, with
--report / --report-png the visual report; all staged and renamed together at the end, so that a
failed run leaves none of them (and leaves any older files at those paths untouched)."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from ...run import raster
from ...io.atomic import staged_outputs
from ...engine.result import Result
from ..writing import write


@dataclass(frozen=True)
class CompareOutputs:
    """What a compare run writes: the point table, and as asked the report and its PNGs (the
    rasters come with a grid). `inputs` are the run's input files, named in the report."""

    table: Path
    report: Path | None = None
    report_png: Path | None = None
    projected: bool = False
    position: str = "core"
    field_names: str = "m3c2"   # the columns' names: m3c2's or a peer's (writing.write)
    float64: bool = False
    all_fields: bool = False    # LAS/LAZ: every column, not only CloudCompare's default set
    core_spacing: float | None = None
    inputs: dict = field(default_factory=dict)


def _inputs(outputs: CompareOutputs, reference, grid) -> dict:
    out = {**{k: str(v) for k, v in outputs.inputs.items()}, "output": str(outputs.table),
           "reference points": len(reference)}
    if grid is not None:
        out["grid cell (2D mode, vertical normals)"] = grid.cell
        out["grid rows x cols"] = f"{grid.rows} x {grid.cols}"
    crs = getattr(reference, "crs", None)
    out["reference CRS"] = (crs[:120] + "...") if crs and len(crs) > 120 else (crs or "none")
    return out


def write_compare_outputs(outputs: CompareOutputs, result: Result, reference, *, grid=None) -> list[Path]:
    """Writes the point table and, as asked, the rasters (grid) and the report. Returns the paths
    written besides the table."""
    html_path, png_prefix, table = outputs.report, outputs.report_png, Path(outputs.table)
    projected, position = outputs.projected, outputs.position
    columns = {"field_names": outputs.field_names, "float64": outputs.float64, "all_fields": outputs.all_fields}
    if grid is None and html_path is None and png_prefix is None:
        write(table, result, like=reference, projected=projected, position=position, **columns)
        return []
    from . import png_paths, write_report

    rasters = raster.raster_paths(table) if grid is not None else {}
    pngs = png_paths(png_prefix) if png_prefix is not None else {}
    extra = list(rasters.values()) + ([Path(html_path)] if html_path is not None else []) + list(pngs.values())
    targets = [table] + extra
    if len(set(targets)) != len(targets):
        raise raster.UsageError("the output, raster, report and PNG paths must all differ")
    with staged_outputs(targets) as staged:
        write(staged[table], result, like=reference, projected=projected, position=position, **columns)
        images = None
        if grid is not None:
            images = raster.rasters(result, grid)
            raster.write_rasters({k: staged[p] for k, p in rasters.items()}, images, grid,
                                 getattr(reference, "crs", None), targets=rasters)
        if html_path is not None or png_prefix is not None:
            write_report(result, html_path, png_prefix, staged=staged, grid=grid, images=images,
                         crs=getattr(reference, "crs", None), units=getattr(reference, "units_hint", None),
                         core_spacing=outputs.core_spacing, inputs=_inputs(outputs, reference, grid))
    return extra
