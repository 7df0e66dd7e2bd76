"""`m3c2 compare`: its options, reading, the run in memory or in tiles, the outputs."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .command_index import summary
from .. import api
from ..base.errors import UsageError
from ..classify.vegetation import vegetation_filter
from ..io import crs as crs_mod
from ..io import laz_threads, read_cloud
from ..io.collisions import check_outputs
from ..io.fields import TableStyle
from ..io.files import add_drop_nonfinite_option
from ..output.report.outputs import CompareOutputs, write_compare_outputs
from ..output.summary import summary_lines
from ..run import raster
from ..run.core_normals import given_core_normals
from ..run.checks import check_all_fields, check_core_normals, threads_count
from ..settings import by_name, orientation, parameters_of, resolve
from ..settings.cloudcompare_params import read_cloudcompare_params
from ..settings.resolve import without_inapplicable
from .auto_scales import check_all_but_scales, choose_scales, missing_scales
from .inputs import input_files, orient_spec, print_notes, read_input
from .options import add, add_progress_option, add_table_options, add_verbosity_options, argument_sections
from .parser import phases_for
def compare_parser(sub) -> None:
    p = sub.add_parser("compare", help=summary("compare"),
                       description="M3C2 change between REFERENCE and COMPARED at core points. "
                                   "D and d are diameters; --max-depth is the half-length of the cylinder.")
    p.add_argument("reference", type=Path, help="reference cloud (first epoch)")
    p.add_argument("compared", type=Path, help="compared cloud (second epoch)")
    p.add_argument("-o", "--output", type=Path, required=True, help="output file: .las .laz .ply .csv .txt")
    sections = argument_sections(p)  # CloudCompare's tabs (m3c2kit.settings.groups)
    core = sections["Scales"].add_mutually_exclusive_group()
    add(core, "core", default_text="every reference point")
    core.add_argument("--grid", type=float, metavar="CELL",
                      help="2D mode (section 6.1.2): core points on a CELL grid over the reference, vertical normals, "
                           "d = 1.1 CELL unless --projection-scale; also writes GeoTIFF rasters <stem>_distance.tif, "
                           "_lod, _significant, _n1, _n2, _status beside -o (docs/report.md)")
    add_table_options(p, "compare", groups={"core_spacing": core}, sections=sections)
    add(sections["Normals"], "core_normals")
    p.add_argument("--params", type=Path, help="CloudCompare qM3C2 parameter file; command-line options win")
    sections["Scales"].add_argument("--auto-scales", action="store_true",
                   help="choose D, d and the max depth from the data by m3c2 suggest's rules (also done for any of "
                        "them not given); the run prints what it chose and why")
    sections["Output"].add_argument("--projected", action="store_true", help="also write the projected positions x1..z2")
    add_drop_nonfinite_option(p)
    add(p, "ignore_crs")
    p.add_argument("--allow-angular", action="store_true",
                   help="accept horizontal coordinates in degrees (a geographic CRS such as EPSG:4326; default: "
                        "an error, as distances would mix degrees and heights)")
    p.add_argument("--crs", metavar="CRS",
                   help="CRS of inputs that have none (ASCII, PLY, .npy, LAS without one): EPSG:CODE, a WKT or a "
                        ".prj file; written to LAS outputs and GeoTIFFs (default: none)")
    sections["Output"].add_argument("--report", type=Path, metavar="HTML", help="also write a self-contained HTML report (docs/report.md)")
    sections["Output"].add_argument("--report-png", type=Path, metavar="PREFIX", help="also write the report's figures as PREFIX_<figure>.png")
    sections["Run"].add_argument("--tile-size", type=float, metavar="S",
                   help="out-of-core: process the core points in square XY tiles of side S, each with only the "
                        "points within the halo; same result bit for bit (docs/scaling.md)")
    sections["Run"].add_argument("--memory-limit", metavar="SIZE",
                   help="out-of-core: pick the tile size so a tile's estimated resident memory stays under SIZE "
                        "(e.g. 2GB; docs/scaling.md)")
    add(sections["Run"], "dask_scheduler")
    add_verbosity_options(sections["Run"])
    add_progress_option(sections["Run"])
    p.set_defaults(run=run_compare)


def compare_settings(args) -> dict:
    """Options from --params, overridden by those given on the command line."""
    settings = {}
    if args.params is not None:
        settings.update(read_cloudcompare_params(args.params))
        settings.setdefault("compat", "cloudcompare")
    for param in parameters_of("compare"):
        value = getattr(args, param.name, None)
        if value is not None:
            settings[param.name] = value
    if args.core is not None:
        settings.pop("core_spacing", None)  # as CloudCompare: given core points win over subsampling
    if getattr(args, "grid", None) is not None:
        explicit = {p.name: getattr(args, p.name, None) for p in parameters_of("compare")}
        settings = raster.grid_settings(args.grid, settings, dict(explicit, core_normals=args.core_normals))
        for name, value in explicit.items():  # 2D mode drops what it replaces: given here, it would do nothing
            if value is not None and name not in settings:
                raise UsageError(f"--grid imposes vertical normals on grid cells: {by_name()[name].flag} would change "
                                 f"nothing; leave it out")
    if args.params is not None:  # the file's values that the options make moot are its dialog's state: dropped
        typed = {p.name for p in parameters_of("compare") if getattr(args, p.name, None) is not None}
        settings = without_inapplicable(settings, keep=typed)
    return settings


def run_compare_tiled(args, settings: dict, outputs: CompareOutputs) -> int:
    """`m3c2 compare ... --tile-size S | --memory-limit M [--dask-scheduler ADDRESS]` (m3c2kit.run.tiled):
    every option of the in-memory run, the same bytes in every file and the same warnings."""
    from dataclasses import replace

    from ..run.dask import connect
    from ..run.tiled import TiledOptions, prepare

    if args.tile_size is None and args.memory_limit is None:
        raise UsageError("--dask-scheduler needs --tile-size S or --memory-limit SIZE to cut the work into tiles")
    drop = bool(getattr(args, "drop_nonfinite", False))
    say = (lambda s: None) if args.quiet else (lambda s: print(f"m3c2: {s}", flush=True))
    tiling = TiledOptions(tile_size=args.tile_size, memory_limit=args.memory_limit, drop_nonfinite=drop, log=say)
    # The one plan of the run, checked (tile size, memory limit) before any file is read; --orient
    # sensor is resolved with the files' scanner positions once they are (as in memory).
    sensor = orientation.needs_scan_positions(settings.get("orient"))
    prepared = prepare({k: v for k, v in settings.items() if not (sensor and k == "orient")}, tiling,
                       vegetation=vegetation_filter(settings.get("classifier"), settings.get("keep")),
                       read_points=lambda p: read_cloud(p, drop_nonfinite=drop).xyz)
    client = connect(args.dask_scheduler) if args.dask_scheduler is not None else None  # bounded in time
    try:
        _compare_tiled(args, settings, outputs, prepared, replace(tiling, client=client))
    finally:
        if client is not None:
            client.close()
    if args.verbose:  # as the in-memory run: the parameters the run was given, with D as a list
        for name, value in sorted(prepared.plan.record.items()):
            print(f"parameter {name}: {value}")
    return 0


def _compare_tiled(args, settings: dict, outputs: CompareOutputs, prepared, tiling) -> None:
    """Reads what the run reads whole (the core file), checks the inputs as in memory (--crs, the
    CRSs, --orient sensor), runs the tiles, and writes the outputs: the point table streamed by
    the merge, or with rasters or a report, every file from the gathered Result exactly as in
    memory (m3c2kit.output.report.outputs: O(core points) in memory, docs/scaling.md)."""
    from ..io.streaming import PointSource
    from ..output.report.outputs import ReferenceInfo
    from ..run.tiled import GridCores, run_tiled

    drop = tiling.drop_nonfinite
    ref_src = PointSource(args.reference, drop_nonfinite=drop)
    cmp_src = PointSource(args.compared, drop_nonfinite=drop)
    core_cloud = read_cloud(args.core, drop_nonfinite=drop) if args.core is not None else None
    if getattr(args, "crs", None) is not None:  # '' too: refused as no CRS, not ignored
        assign_crs(args.crs, ref_src.like(), cmp_src.like(), core_cloud)  # the LAS outputs and rasters copy it
    check_same_crs(ref_src.like(), cmp_src.like(), core_cloud, ignore=getattr(args, "ignore_crs", False),
                   allow_angular=getattr(args, "allow_angular", False))
    if orientation.needs_scan_positions(settings.get("orient")):  # the files named when none has a pose
        prepared.orient(orient_spec(args, settings, ref_src.cloud, core_cloud))
    core_normals = _core_normals(args, core_cloud) if settings.get("normal_source") == "core" else None
    whole = args.grid is not None or outputs.extras  # rasters and the report are drawn from the whole Result
    report = run_tiled(ref_src, cmp_src, GridCores(args.grid) if args.grid is not None else core_cloud,
                       core_normals=core_normals, output=None if whole else args.output, style=outputs.style,
                       tiling=tiling, return_result=whole, prepared=prepared)
    extra = []
    if whole:
        reference = ReferenceInfo(ref_src.like(), report.reference_points, report.attributes)
        extra = write_compare_outputs(outputs, report.result, reference, grid=report.grid)
    if not args.quiet:
        for line in report.lines(args.output):
            print(line)
        for path in extra:
            print(f"wrote {path}")
    # What reading changed in the files read whole (text, PLY, E57 and the core file; a streamed
    # LAS or .npy input's dropped points are not counted).
    print_notes((ref_src.cloud, cmp_src.cloud, core_cloud))


def _compare_outputs(args) -> dict:
    """Every file `m3c2 compare` writes, by its option."""
    from ..output.report import png_paths

    outputs = {"-o": args.output}
    if args.grid is not None:
        outputs.update({f"--grid raster {name}": path for name, path in raster.raster_paths(args.output).items()})
    outputs["--report"] = args.report
    if args.report_png is not None:
        outputs.update({f"--report-png {key}": path for key, path in png_paths(args.report_png).items()})
    return outputs


def run_compare(args) -> int:
    cell = args.grid
    settings = compare_settings(args)  # with --grid: 2D mode's settings (raster.grid_settings)
    chosen_later = missing_scales(settings, args)  # D, d, depth not given: from the data, once read
    # Every parameter's checks, options that would change nothing included, before any file is read.
    if chosen_later:
        check_all_but_scales(resolve, settings, chosen_later)
    else:
        resolve(settings, "compare")
    check_core_normals(settings, args.core_normals, "--core-normals")
    check_all_fields(args.output, settings.get("all_fields"))
    laz_threads.set_threads(threads_count(settings.get("threads")))  # LAZ coding: --threads too (checked first)
    check_outputs(_compare_outputs(args), input_files(args, settings))  # before any work (docs/errors.md)
    phases = phases_for(args)  # -q with --progress refused here, in every mode
    # How the table is written: taken out of the run's parameters, the same in every mode.
    style = TableStyle.taken_from(settings, projected=args.projected)
    outputs = CompareOutputs(table=args.output, report=args.report, report_png=args.report_png, style=style,
                             core_spacing=settings.get("core_spacing"),
                             inputs={"reference": args.reference, "compared": args.compared})
    if args.tile_size is not None or args.memory_limit is not None or args.dask_scheduler is not None:
        if chosen_later:  # the rules read both clouds whole: not what a tiled run is for
            raise UsageError(f"a tiled run needs its scales given ({', '.join(by_name()[n].flag for n in chosen_later)} "
                             "missing): 'm3c2 suggest' on the clouds or a crop of them proposes them")
        return run_compare_tiled(args, settings, outputs)  # out-of-core / Dask (docs/scaling.md)
    files = [f for f in (args.reference, args.compared, args.core) if f is not None]
    with phases.phase("reading", total=len(files)) as step:
        reference = read_input(args.reference, args)
        step(1, len(files))
        compared = read_input(args.compared, args)
        step(2, len(files))
        core_cloud = read_input(args.core, args) if args.core is not None else None
        step(len(files), len(files))
    if getattr(args, "crs", None) is not None:  # '' too: refused as no CRS, not ignored
        assign_crs(args.crs, reference, compared, core_cloud)
    check_same_crs(reference, compared, core_cloud, ignore=getattr(args, "ignore_crs", False),
                   allow_angular=getattr(args, "allow_angular", False))  # docs/errors.md
    if chosen_later:
        say = (lambda s: None) if args.quiet else (lambda s: print(f"m3c2: {s}", flush=True))
        choose_scales(settings, chosen_later, reference, compared,
                           threads=threads_count(settings.get("threads")), say=say)
        resolve(settings, "compare")  # the chosen scales checked with the others, their warnings given
    grid = None
    if cell is not None:
        grid = raster.grid_core_points(reference, cell)
        core_cloud = grid.core_points
    if orientation.needs_scan_positions(settings.get("orient")):  # the files named when none has a pose
        settings["orient"] = orient_spec(args, settings, reference, core_cloud)
    threads = settings.pop("threads", 0)
    core_normals = None
    if settings.get("normal_source") == "core":
        core_normals = _core_normals(args, core_cloud)
    # The engine indexes both clouds, fits the normals and measures the distances in one call,
    # reporting core points done: one bar for the three.
    with phases.phase("indexing, normals, distances") as step:
        # The clouds' arrays are the command line's own (read above): ordered in place, not copied.
        result = api.compare(reference, compared, core_cloud, core_normals=core_normals, threads=threads,
                             progress=step, read_points=lambda p: read_input(p, args).xyz, reorder_inputs=True,
                             **settings)
    with phases.phase("writing", total=1) as step:
        extra = write_compare_outputs(outputs, result, reference, grid=grid)
        step(1, 1)
    if not args.quiet:
        for line in summary_lines(result, args.output):
            print(line)
        for path in extra:
            print(f"wrote {path}")
    if args.verbose:
        for name, value in sorted(result.params.items()):
            print(f"parameter {name}: {value}")
        print(phases.timing_line())  # where the time went (issue 45)
    print_notes((reference, compared, core_cloud))  # the warnings: m3c2kit.run.diagnostics, through main()
    return 0


CrsMismatch = crs_mod.CrsMismatch  # the epochs' CRSs or units differ (exit 1); --ignore-crs overrides


def check_same_crs(reference, compared, core=None, *, ignore: bool = False, allow_angular: bool = False) -> None:
    """m3c2kit.io.crs.check_crs: CRSs known to differ, a CRS on one cloud only, different units,
    angular coordinates (docs/errors.md)."""
    crs_mod.check_crs(reference, compared, core, ignore=ignore, allow_angular=allow_angular)


def assign_crs(spec: str, *clouds) -> None:
    """--crs: the CRS of every given cloud that has none; a cloud with another CRS is an error."""
    wkt = crs_mod.assign_crs(spec)
    for cloud in clouds:
        if cloud is None:
            continue
        if not cloud.crs:
            cloud.crs, cloud.units_hint = wkt, crs_mod.crs_units(wkt) or cloud.units_hint
        elif crs_mod.same_crs(cloud.crs, wkt) is False:
            raise CrsMismatch(f"{cloud.path} already has a CRS, {crs_mod.crs_label(cloud.crs)}, not the --crs "
                              f"{crs_mod.crs_label(wkt)}; --crs only assigns a CRS to inputs that have none")


def _core_normals(args, core_cloud) -> np.ndarray:
    """--normal-source core's normals: compare's and series' one rule (run.core_normals)."""
    return given_core_normals(args.core_normals, core_cloud, lambda path: read_input(path, args))

