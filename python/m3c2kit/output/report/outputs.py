"""Everything `m3c2 compare` writes: the point table, and with --grid the GeoTIFF rasters, with
--report / --report-png the visual report; all staged and renamed together at the end, so that a
failed run leaves none of them (and leaves any older files at those paths untouched). The same
function writes them for every mode (in memory, tiled, on Dask), so their bytes are the same."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from ...engine.result import Result
from ...io.atomic import staged_outputs
from ...io.fields import TableStyle
from ...run import raster
from ..writing import write_table


@dataclass(frozen=True)
class CompareOutputs:
    """What a compare run writes: the point table in `style` (m3c2kit.io.fields.TableStyle), and as
    asked the report and its PNGs (the rasters come with a grid). `inputs` are the run's input
    files, named in the report."""

    table: Path
    report: Path | None = None
    report_png: Path | None = None
    style: TableStyle = TableStyle()
    core_spacing: float | None = None
    inputs: dict = field(default_factory=dict)

    @property
    def extras(self) -> bool:
        """Whether files besides the table are asked (a tiled run then gathers its Result)."""
        return self.report is not None or self.report_png is not None


@dataclass(frozen=True)
class ReferenceInfo:
    """What the outputs take from the reference cloud: `like` (the Cloud whose LAS scale, offset,
    CRS and units the files copy; with its points and fields in memory, from which the core
    points' attributes are matched), its point count, and the core points' attributes already
    matched (a tiled run's, m3c2kit.run.attributes) or None."""

    like: object
    points: int
    attributes: dict | None = None

    @classmethod
    def of(cls, cloud) -> "ReferenceInfo":
        """A reference read whole (the in-memory run)."""
        return cls(cloud, len(cloud))


def _inputs(outputs: CompareOutputs, reference: ReferenceInfo, grid) -> dict:
    out = {**{k: str(v) for k, v in outputs.inputs.items()}, "output": str(outputs.table),
           "reference points": reference.points}
    if grid is not None:
        out["grid cell (2D mode, vertical normals)"] = grid.cell
        out["grid rows x cols"] = f"{grid.rows} x {grid.cols}"
    crs = getattr(reference.like, "crs", None)
    out["reference CRS"] = (crs[:120] + "...") if crs and len(crs) > 120 else (crs or "none")
    return out


def write_compare_outputs(outputs: CompareOutputs, result: Result, reference, *, grid=None) -> list[Path]:
    """Writes the point table and, as asked, the rasters (grid) and the report. `reference`: a
    ReferenceInfo, or the reference Cloud read whole. Returns the paths written besides the table."""
    if not isinstance(reference, ReferenceInfo):
        reference = ReferenceInfo.of(reference)
    like = reference.like
    html_path, png_prefix, table = outputs.report, outputs.report_png, Path(outputs.table)

    def write_points(path) -> None:
        write_table(path, result, outputs.style, like=like, attributes=reference.attributes)

    if grid is None and not outputs.extras:
        write_points(table)
        return []
    from . import png_paths, write_report

    rasters = raster.raster_paths(table) if grid is not None else {}
    pngs = png_paths(png_prefix) if png_prefix is not None else {}
    extra = list(rasters.values()) + ([Path(html_path)] if html_path is not None else []) + list(pngs.values())
    targets = [table] + extra
    if len(set(targets)) != len(targets):
        raise raster.UsageError("the output, raster, report and PNG paths must all differ")
    with staged_outputs(targets) as staged:
        write_points(staged[table])
        images = None
        if grid is not None:
            images = raster.rasters(result, grid, rasters)
            raster.write_rasters({k: staged[p] for k, p in rasters.items()}, images, grid,
                                 getattr(like, "crs", None), targets=rasters)
        if html_path is not None or png_prefix is not None:
            write_report(result, html_path, png_prefix, staged=staged, grid=grid, images=images,
                         crs=getattr(like, "crs", None), units=getattr(like, "units_hint", None),
                         core_spacing=outputs.core_spacing, inputs=_inputs(outputs, reference, grid))
    return extra
