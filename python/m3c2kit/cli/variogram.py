"""`m3c2 variogram RESULT [--stable POLYGONS | --stable-field NAME=VALUE] -o MODEL.json`: the
spatially correlated error model of a compare output (docs/analysis.md, "m3c2 variogram"),
which `m3c2 compare --error-model MODEL.json` applies. Registered by m3c2kit.cli.main."""
from __future__ import annotations

import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np

from .command_index import summary
from ..analysis import variogram as vg
from ..analysis.common import figure_format, repeated_positions
from ..analysis.error_model import LAG_DISTANCES, model_bytes
from ..base.errors import M3C2Warning, UsageError
from ..io import read_cloud
from ..io.atomic import staged_outputs
from ..io.collisions import check_outputs, require_suffix
from ..settings.parsers import positive
from .integers import COUNT_MAX, integer
from .options import add, add_table_option


def variogram_parser(sub) -> None:
    p = sub.add_parser("variogram", help=summary("variogram"),
                       description="The empirical variogram of the M3C2 distance over the stable core points of a "
                                   "compare output (sampled pairs, seeded), fitted by nugget + spherical + exponential "
                                   "(Rolstad et al. 2009; Hugonnet et al. 2022). Writes MODEL.json for "
                                   "'m3c2 compare --error-model' and, with --plot, the figure.")
    p.add_argument("result", type=Path, help="a compare output (any format m3c2 writes: x, y, z, distance, ...)")
    stable = p.add_mutually_exclusive_group()
    stable.add_argument("--stable", type=Path, metavar="POLYGONS",
                        help="stable areas: GeoJSON or WKT polygons (default: every core point)")
    stable.add_argument("--stable-field", metavar="NAME=VALUE",
                        help="stable core points: where the result's field NAME equals VALUE (classification=2)")
    # recorded in MODEL.json, which compare --error-model then applies only at that d (docs/analysis.md)
    add_table_option(p, "projection_scale")
    p.add_argument("--lag-distance", choices=LAG_DISTANCES, default="3d",
                   help="lags as 3D distances (cliffs, overhangs) or in plan view (default 3d)")
    p.add_argument("--bins", type=integer(4, 200), default=20, help="lag bins, log-spaced (default 20)")
    p.add_argument("--max-lag", type=float, help="largest lag (default half the core points' largest extent)")
    p.add_argument("--pairs", type=integer(1, COUNT_MAX), default=10_000_000,
                   help="random pairs for the long lags (default 10000000; the short lags come from neighbourhoods)")
    add(p, "sample_seed", default=0)
    p.add_argument("-o", "--output", type=Path, required=True, help="the error model (JSON)")
    add(p, "plot")
    add_table_option(p, "threads", filled=True)
    add(p, "quiet")
    p.set_defaults(run=run_variogram)


def run_variogram(args) -> int:
    plot = args.plot  # a figure only with its own option: it replaced m.png beside -o m.json
    check_outputs({"-o": args.output, "--plot": plot}, {"result": args.result, "--stable": args.stable})
    require_suffix("-o", args.output, (".json",), "the error model")
    if plot is not None:
        figure_format(plot)
    if args.max_lag is not None:
        positive("--max-lag", args.max_lag)
    cloud = read_cloud(args.result)
    distance = vg.result_column(cloud, "distance")
    if distance is None:
        raise UsageError(f"{args.result}: no 'distance' field: not a compare output "
                         f"(its fields: {', '.join(sorted(cloud.fields)) or 'none'})")
    u2 = vg.eq1_variance(cloud)
    if (message := repeated_positions(cloud.xyz)) is not None:
        warnings.warn(f"{args.result}: {message}", M3C2Warning, stacklevel=2)
    mask = vg.stable_mask(cloud, polygons=args.stable, field=args.stable_field)
    if args.stable is None and args.stable_field is None and (message := vg.change_taken_for_error(cloud)):
        warnings.warn(f"{args.result}: {message}", M3C2Warning, stacklevel=2)
    try:
        fitted = vg.fit_error_model(cloud.xyz[mask], distance[mask], u2[mask], seed=args.seed, bins=args.bins,
                                    max_lag=args.max_lag, lag_distance=args.lag_distance, far_pairs=args.pairs,
                                    threads=args.threads)
    except UsageError as e:
        raise UsageError(f"{args.result}: {e}") from None
    model = replace(fitted.model, projection_scale=args.projection_scale,
                    notes=f"{fitted.kept}; {fitted.used} stable core points of {args.result.name}, seed {args.seed}")
    for message in fitted.warnings:
        warnings.warn(f"{args.result}: {message}", M3C2Warning, stacklevel=2)
    fig = None if plot is None else vg.plot_variogram(fitted.empirical, model,
                                                      title=f"{args.result.name}: variogram of the distance")
    with staged_outputs([p for p in (args.output, plot) if p is not None]) as staged:
        staged[args.output].write_bytes(model_bytes(model))
        if fig is not None:
            fig.savefig(staged[plot], dpi=120, format=figure_format(plot))
    if not args.quiet:
        emp = fitted.empirical
        print(f"{args.result}: {fitted.used} stable core points with a distance and a LOD, {int(emp.pairs.sum())} "
              f"pairs in {len(emp.lag)} lag bins ({args.lag_distance} lags)")
        print(f"fit: {fitted.kept}")
        print(f"nugget {model.nugget:.6g}")
        for c in model.components:
            print(f"{c.kind}: partial sill {c.sill:.6g}, range {c.range:.6g}")
        at = "" if args.projection_scale is None else f" at d = {args.projection_scale:g}"
        print(f"total sill {model.total_variance():.6g} - mean s1^2/n1 + s2^2/n2 {model.mean_u2:.6g} = "
              f"correlated variance sigma_c^2 {model.excess_variance():.6g} (sigma_c "
              f"{np.sqrt(model.excess_variance()):.6g}){at}: compare --error-model's LOD term")
        print(f"wrote {args.output}" + (f" and {plot}" if plot is not None else ""))
    return 0
