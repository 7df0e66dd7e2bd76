"""Command-line subcommands of the analysis toolkit: roughness, calibrate, c2c, simplify, suggest
(docs/analysis.md). Registered by m3c2kit.cli.main.make_parser through `analysis_parsers`."""
from __future__ import annotations

import os
import shlex
from importlib import import_module
from pathlib import Path

import numpy as np

from .command_index import summary
from ..io import read_cloud, write_cloud_table
from ..io.collisions import check_outputs
from ..io.files import add_drop_nonfinite_option
from ..run.cores import core_points_for
from ..settings import by_name
from ..settings.parsers import positive
from .integers import COUNT_MAX, integer
from .options import add, add_table_option, table_type
from .parser import phases_for

# m3c2kit.analysis exports functions named like these modules (`from ..analysis import calibrate`
# and even `import m3c2kit.analysis.calibrate as m` give the function): the modules by name.
roughness_mod, calibrate_mod, simplify_mod, suggest_mod = (
    import_module(f"m3c2kit.analysis.{name}") for name in ("roughness", "calibrate", "simplify", "suggest"))
from ..analysis.baselines import MODEL_NEIGHBOURS, RULE, RULES, c2c, model_options
from ..analysis.common import figure_format, scales, value_range, write_csv

D_HELP = "D, the normal scale: a DIAMETER"
d_HELP = "d, the projection scale: the cylinder's DIAMETER"


def _read(path: Path, args):
    return read_cloud(path, drop_nonfinite=args.drop_nonfinite)


def _run_options(p, *, quiet: bool = True) -> None:
    """How an analysis command runs: --threads, -q (but suggest, whose printed text is its result),
    --drop-nonfinite."""
    add_table_option(p, "threads", filled=True)
    if quiet:
        add(p, "quiet")
    add_drop_nonfinite_option(p)


def _core_options(p, default: str) -> None:
    """--core FILE or --core-spacing S; `default`: the command's core points without either."""
    core = p.add_mutually_exclusive_group()
    add(core, "core", default_text=default)
    add(core, "cloud_core_spacing")


def _check_outputs(args) -> None:
    """No output of the command (-o, --plot) may be one of its inputs (m3c2kit.io.collisions),
    checked before any work, as for every command (docs/errors.md, "Output")."""
    orient = getattr(args, "orient", None)
    inputs = {"input cloud": getattr(args, "cloud", None), "reference cloud": getattr(args, "reference", None),
              "compared cloud": getattr(args, "compared", None), "core points file": getattr(args, "core", None),
              "orientation file": orient if orient and os.path.isfile(orient) else None}
    check_outputs({"-o": getattr(args, "output", None), "--plot": getattr(args, "plot", None)}, inputs)
    if getattr(args, "plot", None) is not None:
        figure_format(args.plot)


def _core_points(args, cloud_xyz, default_all=True):
    from .. import api
    if args.core is not None:
        return _read(args.core, args).xyz
    if args.core_spacing is not None:
        return core_points_for(cloud_xyz, None, args.core_spacing)
    return cloud_xyz if default_all else None


def analysis_parsers(sub) -> None:
    """Adds the roughness, calibrate, c2c, simplify and suggest subcommands."""
    p = sub.add_parser("roughness", help=summary("roughness"),
                       description="Mean and standard deviation of sigma(D) over core points per scale D, and the "
                                   "fit of eq. (3) <sigma(D)> = sigma(l0) (D/l0)^beta in log-log.")
    p.add_argument("cloud", type=Path, help="the point cloud")
    p.add_argument("--normal-scale", required=True, type=table_type(by_name()["normal_scale"]),  # D's range
                   help=D_HELP + " for each scale: 'MIN:MAX:STEP' or a list 'a,b,c'")
    _core_options(p, "every point")
    add(p, "fit_range", default_text="all")
    p.add_argument("--l0", type=float, default=roughness_mod.L0, help="reference scale l0 of eq. (3) (default 0.5)")
    p.add_argument("--min-points", type=integer(1, COUNT_MAX), default=10, help="fewest neighbours for sigma(D) (default 10)")
    add_table_option(p, "variance", filled=True)
    p.add_argument("-o", "--output", type=Path, required=True, help="CSV table")
    add(p, "plot")
    _run_options(p)
    p.set_defaults(run=run_roughness)

    p = sub.add_parser("calibrate", help=summary("calibrate"),
                       description="Compares a cloud with differently subsampled versions of itself: per d, the "
                                   "percentage of core points correctly NOT significant with eq. (1) z, Welch t "
                                   "(eq. 2) and the bootstrap, the mean LOD95 and its scaling d^alpha vs beta - 0.95.")
    p.add_argument("cloud", type=Path, help="the point cloud, compared with subsampled copies of itself")
    p.add_argument("--projection-scales", required=True, help=d_HELP + " for each scale: 'MIN:MAX:STEP' or 'a,b,c'")
    p.add_argument("--spacings", default="raw,3x",
                   help="minimum spacings of cloud 1 and cloud 2: 'raw', a length, or 'Nx' = N times the median "
                        "point spacing (default raw,3x; the paper: raw,0.1 and 0.045,0.05)")
    add(p, "derived_normal_scale", default_text="vertical normals, as the paper: 'We impose a fixed normal direction'")
    _core_options(p, "the cloud subsampled to the larger of --spacings and 4 times the median point spacing")
    p.add_argument("--max-core", type=integer(1, COUNT_MAX), default=2000,
                   help="at most this many core points, drawn with --seed (default 2000)")
    add(p, "derived_max_depth", default_text="the largest d")
    p.add_argument("--bootstrap", type=integer(0, COUNT_MAX), default=100,
                   help="resamples of the bootstrap LOD of Appendix B, with --seed (0: skip; default 100)")
    add(p, "sample_seed", default=0)
    add_table_option(p, "min_points", filled=True)
    add(p, "fit_range", default_text="all")
    add(p, "fixed_orient", default="+z")
    p.add_argument("-o", "--output", type=Path, required=True, help="CSV table")
    add(p, "plot")
    _run_options(p)
    p.set_defaults(run=run_calibrate)

    p = sub.add_parser("c2c", help=summary("c2c"),
                       description="Distance from each compared point (or core point) to the closest reference point "
                                   "(C2C) and, with --model plane, to the least-squares plane of that point's "
                                   "reference neighbours (C2C_HF). Unsigned, as in CloudCompare.")
    p.add_argument("reference", type=Path, help="the reference cloud")
    p.add_argument("compared", type=Path, help="the compared cloud (its points are the query points by default)")
    p.add_argument("-o", "--output", type=Path, required=True, help="output: .csv .txt .ply .las .laz")
    _core_options(p, "every compared point")
    p.add_argument("--model", choices=["none", "plane"], default="none",
                   help="local model: none (C2C) or plane (also C2C_HF)")
    p.add_argument("--model-radius", type=float, help="model neighbours within this radius of the closest point")
    p.add_argument("--model-knn", type=integer(1, COUNT_MAX),
                   help=f"else its k nearest reference points (default {MODEL_NEIGHBOURS})")
    p.add_argument("--rule", choices=RULES,
                   help=f"with --model plane: closer: min(C2C, plane) as CloudCompare >= 2.5; model: the plane "
                        f"distance as CloudCompare 2.3 (default {RULE})")
    _run_options(p)
    p.set_defaults(run=run_c2c)

    p = sub.add_parser("simplify", help=summary("simplify"),
                       description="Compares the cloud with itself at core points and writes the projected "
                                   "positions core + i n (mean: local averaging; --median: outlier removal) with "
                                   "roughness, density and normals; d is the averaging scale.")
    p.add_argument("cloud", type=Path, help="the point cloud")
    _core_options(p, "every point")
    add_table_option(p, "projection_scale", required=True)
    add(p, "derived_normal_scale", default_text="2 d")
    p.add_argument("--vertical", action="store_true", help="impose vertical normals instead")
    add_table_option(p, "median", filled=True)
    add(p, "derived_max_depth", default_text="d")
    add(p, "fixed_orient", default="+z")
    p.add_argument("-o", "--output", type=Path, required=True,
                   help="the projected points: .csv .txt .ply .las .laz")
    _run_options(p)
    p.set_defaults(run=run_simplify)

    p = sub.add_parser("suggest", help=summary("suggest"),
                       description="Proposes D (smallest scale with xi >= 25 at 95% of sampled core points), d "
                                   "(smallest with median n >= 30 in both clouds) and a max depth (3 x the 99th "
                                   "percentile of |distance| of a first pass), printing the numbers behind each.")
    p.add_argument("reference", type=Path, help="the reference cloud")
    p.add_argument("compared", type=Path, help="the compared cloud")
    p.add_argument("--sample", type=integer(1, COUNT_MAX), default=2000, help="sampled core points (default 2000)")
    add(p, "sample_seed", default=0)
    _run_options(p, quiet=False)
    p.set_defaults(run=run_suggest)


def run_roughness(args) -> int:
    _check_outputs(args)
    positive("--l0", args.l0)  # checked again by fit_scaling; here before the scales are computed
    cloud = _read(args.cloud, args)
    diameters = scales("--normal-scale", args.normal_scale)
    core = _core_points(args, cloud.xyz)
    with phases_for(args).phase("roughness") as step:
        sigma = roughness_mod.roughness_by_scale(cloud.xyz, core, diameters, variance=args.variance,
                                                 min_points=args.min_points, threads=args.threads, progress=step)
    table = roughness_mod.roughness_table(sigma, diameters)
    fit = roughness_mod.fit_scaling(diameters, table["mean_sigma"], value_range("--fit-range", args.fit_range), args.l0)
    write_csv(args.output, dict(table, in_fit=fit["in_fit"].astype(int)))
    if args.plot is not None:
        roughness_mod.plot(args.plot, table, fit, title=f"{args.cloud.name}: roughness scaling")
    print(f"{args.cloud}: {len(core)} core points, {len(diameters)} scales")
    for line in roughness_mod.report_lines(table, fit):
        print(line)
    return 0


def run_calibrate(args) -> int:
    _check_outputs(args)
    cloud = _read(args.cloud, args)
    ds = scales("--projection-scales", args.projection_scales)
    spacings = [s for s in args.spacings.split(",") if s.strip()]
    core = _read(args.core, args).xyz if args.core is not None else None
    comparison = calibrate_mod.ComparisonSettings(normal_scale=args.normal_scale, max_depth=args.max_depth,
                                                  min_points=args.min_points, orient=args.orient)
    res = calibrate_mod.calibrate(cloud.xyz, ds, spacings=spacings, comparison=comparison,
                                  cores=calibrate_mod.CorePoints(core, args.core_spacing, args.max_core),
                                  bootstrap=args.bootstrap, seed=args.seed,
                                  fit=calibrate_mod.FitSettings(value_range("--fit-range", args.fit_range)),
                                  threads=args.threads)
    write_csv(args.output, res["table"])
    if args.plot is not None:
        calibrate_mod.plot(args.plot, res, title=f"{args.cloud.name}: LOD95 calibration")
    if not args.quiet:
        for line in calibrate_mod.report_lines(res):
            print(line)
    return 0


def run_c2c(args) -> int:
    _check_outputs(args)
    model_options(args.model, args.model_radius, args.model_knn, args.rule)  # refused before reading
    reference, compared = _read(args.reference, args), _read(args.compared, args)
    queries = _core_points(args, compared.xyz)
    with phases_for(args).phase("C2C") as step:
        r = c2c(reference.xyz, queries, model=args.model, model_radius=args.model_radius,
                model_neighbours=args.model_knn, rule=args.rule, threads=args.threads, progress=step)
    fields = {"c2c": r["distance"]}
    if args.model != "none":
        fields["c2c_hf"] = r["hf_distance"]
        fields["model_points"] = r["model_count"].astype(np.uint32)
    write_cloud_table(args.output, queries, fields, like=compared)
    if not args.quiet:
        line = f"wrote {args.output}: {len(queries)} points; C2C mean {np.mean(r['distance']):.6g}, median {np.median(r['distance']):.6g}"
        if args.model != "none":
            line += f"; C2C_HF mean {np.mean(r['hf_distance']):.6g}, median {np.median(r['hf_distance']):.6g}"
        print(line)
    return 0


def run_simplify(args) -> int:
    _check_outputs(args)
    cloud = _read(args.cloud, args)
    core = _read(args.core, args).xyz if args.core is not None else None
    with phases_for(args).phase("simplify") as step:
        points, fields = simplify_mod.simplify(cloud.xyz, core, projection_scale=args.projection_scale,
                                               normal_scale=args.normal_scale, core_spacing=args.core_spacing,
                                               median=args.median, max_depth=args.max_depth,
                                               vertical=args.vertical, orient=args.orient, threads=args.threads,
                                               progress=step)
    write_cloud_table(args.output, points, fields, like=cloud)
    if not args.quiet:
        # No projected point (every core point without a normal): no median, and no numpy warning for it.
        density = f"{np.median(fields['density']):.4g} points per cylinder" if len(points) else "none"
        print(f"wrote {args.output}: {len(points)} projected points ({'median' if args.median else 'mean'}, "
              f"d = {args.projection_scale:g}); median density {density}")
    return 0


def run_suggest(args) -> int:
    reference, compared = _read(args.reference, args), _read(args.compared, args)
    res = suggest_mod.suggest(reference, compared, sample=args.sample, seed=args.seed, threads=args.threads)
    for line in suggest_mod.report_lines(res) + suggest_mod.proposal_lines(res, shlex.quote(str(args.reference)),
                                                                          shlex.quote(str(args.compared))):
        print(line)
    return 0
