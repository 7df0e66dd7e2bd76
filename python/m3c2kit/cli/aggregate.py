"""`m3c2 aggregate RESULT --regions POLYGONS -o TABLE`: per region of a compare output, the mean
change, the volume (grid runs) and the area of significant change with their intervals
(m3c2kit.analysis.aggregate; docs/analysis.md, "m3c2 aggregate"). Registered by m3c2kit.cli.main."""
from __future__ import annotations

import math
import warnings
from pathlib import Path

from .command_index import summary
from ..analysis.aggregate import aggregate, survey_from_fields
from ..analysis.aggregate_table import table_format, write_table
from ..analysis.common import repeated_positions
from ..analysis.error_model import load as load_error_model
from ..base.errors import M3C2Warning, UsageError, printable
from ..io import read_cloud
from ..io.collisions import check_outputs
from ..io.polygons import read_regions_for, require_points_inside
from ..settings.error_model import check_projection_scale
from ..settings.table import by_name
from .integers import integer, positive_real
from .options import add, add_table_option, table_type

#: simulated surveys for the significant area's interval (each draws a field over every region)
SIMULATIONS = 200


def aggregate_parser(sub) -> None:
    p = sub.add_parser("aggregate", help=summary("aggregate"),
                       description="Per region (GeoJSON or WKT polygons, plan view) of a compare output, and over all "
                                   "of them: the core points with a distance, the mean change, the volume (grid runs: "
                                   "--cell-size) and the area of significant change, each with its interval at "
                                   "--confidence. With --error-model (m3c2 variogram's MODEL.json) the intervals "
                                   "include the spatial correlation of the errors (Rolstad et al. 2009); without, they "
                                   "are the uncorrelated ones and the table says so.")
    p.add_argument("result", type=Path, help="a compare output (any format m3c2 writes, with distance, lod, sigma1, "
                                             "sigma2, n1, n2: LAS/LAZ need compare --all-fields)")
    p.add_argument("--regions", type=Path, required=True, metavar="POLYGONS",
                   help="the regions: GeoJSON (FeatureCollection, Feature, Polygon, MultiPolygon; named by the "
                        "property 'name' or 'id') or WKT (a POLYGON or MULTIPOLYGON per line)")
    p.add_argument("-o", "--output", type=Path, required=True, help="the table: .csv or .json")
    p.add_argument("--error-model", type=Path, metavar="MODEL.json",
                   help="the spatially correlated error model (m3c2 variogram) the intervals account for "
                        "(default: none, uncorrelated intervals)")
    add_table_option(p, "projection_scale")
    confidence = by_name()["confidence"]  # its range and default are the table's (compare's LOD level)
    p.add_argument("--confidence", type=table_type(confidence), default=confidence.default_for(),
                   help=f"confidence level of the intervals (default {confidence.default_for():g})")
    p.add_argument("--cell-size", type=positive_real("--cell-size"), metavar="CELL",
                   help="the --grid CELL of the compare run (its core points are checked to be on that grid): "
                        "volumes and areas (default: none, no volume)")
    p.add_argument("--simulations", type=integer(0, 100_000), default=SIMULATIONS,
                   help=f"simulated surveys for the significant area's interval, 0 for none (default {SIMULATIONS})")
    add(p, "sample_seed", default=0)
    add_table_option(p, "threads", filled=True)
    add(p, "quiet")
    p.set_defaults(run=run_aggregate)


def run_aggregate(args) -> int:
    check_outputs({"-o": args.output}, {"result": args.result, "--regions": args.regions,
                                        "--error-model": args.error_model})
    table_format(args.output)
    model = load_error_model(args.error_model) if args.error_model is not None else None
    if model is not None:  # issue 42: the model's d was never checked
        check_projection_scale(model, str(args.error_model), args.projection_scale, of=f"{args.result}'s")
        if args.projection_scale is None and model.projection_scale is not None:
            warnings.warn(f"{args.result}: a compare output does not record its projection scale: taken as the error "
                          f"model's, d = {model.projection_scale:g}; give --projection-scale to have it checked",
                          M3C2Warning, stacklevel=2)
    elif args.projection_scale is not None:
        raise UsageError("--projection-scale is checked against --error-model's d: without a model it would change "
                         "nothing")
    cloud = read_cloud(args.result)
    polygons = read_regions_for(args.regions, cloud)
    if (message := repeated_positions(cloud.xyz)) is not None:
        warnings.warn(f"{args.result}: {message}", M3C2Warning, stacklevel=2)
    survey = survey_from_fields(cloud.xyz, cloud.fields, args.result)
    table = aggregate(survey, polygons, model=model, confidence=float(args.confidence), cell=args.cell_size,
                      simulations=args.simulations, seed=args.seed, threads=args.threads, source=args.result)
    counts = [row.core_points for row in table.rows[:len(polygons)]]
    for name in require_points_inside(counts, cloud.xyz[:, :2], polygons, args.regions, args.result):
        warnings.warn(f"--regions {args.regions}: region {printable(name)!r} holds no core point of {args.result}: "
                      f"its row has no mean", M3C2Warning, stacklevel=2)
    meta = {"result": str(args.result), "regions_file": str(args.regions),
            "error_model": None if args.error_model is None else str(args.error_model)}
    write_table(args.output, table, meta=meta)
    if not args.quiet:
        pct = f"{100 * float(args.confidence):g} %"
        for row in table.rows:
            line = f"{row.region}: {row.with_distance} core points with a distance"
            if row.with_distance:
                line += f", mean {row.mean:.6g} [{row.mean_low:.6g}, {row.mean_high:.6g}]"
            if row.volume is not None:
                line += f", volume {row.volume:.6g} [{row.volume_low:.6g}, {row.volume_high:.6g}]"
            if row.significant_area is not None:
                line += f", significant area {row.significant_area:.6g}"
            elif not math.isnan(row.mean):
                line += f", {row.significant} significant"
            print(line)
        print(f"intervals at {pct}; " + "; ".join(table.notes))
        print(f"wrote {args.output}")
    return 0
