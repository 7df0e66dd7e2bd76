"""The `m3c2` command line: parse, read, compute, write. Exit 0 on success, 2 for usage errors,
1 for failures (unreadable input, unwritable output, interruption); no partial output file."""
from __future__ import annotations

import argparse
import os
import signal
import sys
import warnings
from pathlib import Path

import numpy as np

from . import api, raster
from .analysis.cli import analysis_parsers
from .classify.cli import classify_parsers
from .cli_parser import ArgumentParser, add_progress_option, phases_for
from .errors import M3C2Error, M3C2Warning, UsageError, printable
from .io import read_cloud, write_cloud_table
from .io import crs as crs_mod
from .io import laspy_local, laz_threads
from .io.collisions import check_outputs
from .io.describe import describe, describe_text
from .io.files import add_drop_nonfinite_option
from .io.input_file import os_error_message
from .report.outputs import CompareOutputs, write_compare_outputs
from .run.checks import check_all_fields, check_core_normals
from .settings import by_name, parameters_of, resolve
from .settings.resolve import without_inapplicable
from .settings import orientation
from .settings.cloudcompare_params import ORIENT_KEY_VALUES, read_cloudcompare_params
from .summary import summary_lines



class Interrupted(M3C2Error):
    """SIGINT or SIGTERM during a run."""


def _compare_parser(sub) -> None:
    p = sub.add_parser("compare", help="M3C2 distances between two clouds",
                       description="M3C2 change between REFERENCE and COMPARED at core points. "
                                   "D and d are diameters; --max-depth is the half-length of the cylinder.")
    p.add_argument("reference", type=Path, help="reference cloud (first epoch)")
    p.add_argument("compared", type=Path, help="compared cloud (second epoch)")
    p.add_argument("-o", "--output", type=Path, required=True, help="output file: .las .laz .ply .csv .txt")
    core = p.add_mutually_exclusive_group()
    core.add_argument("--core", type=Path, help="core points file (default: every reference point)")
    core.add_argument("--grid", type=float, metavar="CELL",
                      help="2D mode (section 6.1.2): core points on a CELL grid over the reference, vertical normals, "
                           "d = 1.1 CELL unless --projection-scale; also writes GeoTIFF rasters <stem>_distance.tif, "
                           "_lod, _significant, _n1, _n2, _status beside -o (docs/report.md)")
    add_table_options(p, "compare", groups={"core_spacing": core})
    p.add_argument("--core-normals", type=Path, help="with --normal-source core: file of nx,ny,nz per core point "
                                                     "(default: the core file's normal fields)")
    p.add_argument("--params", type=Path, help="CloudCompare qM3C2 parameter file; command-line options win")
    p.add_argument("--projected", action="store_true", help="also write the projected positions x1..z2")
    add_drop_nonfinite_option(p)
    p.add_argument("--ignore-crs", action="store_true",
                   help="compare clouds whose CRS or units differ, or of which only one has a CRS, or in degrees "
                        "(default: an error naming them)")
    p.add_argument("--allow-angular", action="store_true",
                   help="accept horizontal coordinates in degrees (a geographic CRS such as EPSG:4326; default: "
                        "an error, as distances would mix degrees and heights)")
    p.add_argument("--crs", metavar="CRS",
                   help="CRS of inputs that have none (ASCII, PLY, .npy, LAS without one): EPSG:CODE, a WKT or a "
                        ".prj file; written to LAS outputs and GeoTIFFs (default: none)")
    p.add_argument("--report", type=Path, metavar="HTML", help="also write a self-contained HTML report (docs/report.md)")
    p.add_argument("--report-png", type=Path, metavar="PREFIX", help="also write the report's figures as PREFIX_<figure>.png")
    p.add_argument("--tile-size", type=float, metavar="S",
                   help="out-of-core: process the core points in square XY tiles of side S, each with only the "
                        "points within the halo; same result bit for bit (docs/scaling.md)")
    p.add_argument("--memory-limit", metavar="SIZE",
                   help="out-of-core: pick the tile size so a tile's estimated resident memory stays under SIZE "
                        "(e.g. 2GB; docs/scaling.md)")
    p.add_argument("--dask-scheduler", metavar="ADDRESS",
                   help="run the tiles as tasks on this Dask distributed scheduler; every worker must be able to "
                        "read the inputs and the work folder beside the output (docs/scaling.md)")
    _verbosity_options(p)
    add_progress_option(p)
    p.set_defaults(run=run_compare)


def _verbosity_options(parser) -> None:
    talk = parser.add_mutually_exclusive_group()
    talk.add_argument("-q", "--quiet", action="store_true",
                      help="no progress bar or summary (warnings and errors still go to stderr)")
    talk.add_argument("--verbose", action="store_true", help="also print the parameters the run used")


def add_table_options(parser, command: str, groups: dict | None = None) -> None:
    """One option per parameter of `command` in the parameter table (m3c2kit.settings.table).
    Every default is None (not given): the table fills it in, so --params values and
    --compat defaults can tell what the user said."""
    for param in parameters_of(command):
        target = (groups or {}).get(param.name, parser)
        if param.cli_type is None:
            target.add_argument(param.flag, dest=param.name, action="store_true", default=None,
                                help=param.help_text())
        else:
            target.add_argument(param.flag, dest=param.name, type=param.cli_type, choices=param.choices,
                                metavar=param.metavar, help=param.help_text())


def _normals_parser(sub) -> None:
    p = sub.add_parser("normals", help="normals at the most planar scale, with roughness (section 6.3)")
    p.add_argument("input", type=Path, help="the point cloud")
    p.add_argument("-o", "--output", type=Path, required=True,
                   help="output: .csv .txt .ply .las .laz (nx, ny, nz, normal_scale, roughness, count, status)")
    p.add_argument("--core", type=Path, help="core points (default: every point)")
    add_table_options(p, "normals")
    add_drop_nonfinite_option(p)
    _verbosity_options(p)
    add_progress_option(p)
    p.set_defaults(run=run_normals)


def _subsample_parser(sub) -> None:
    p = sub.add_parser("subsample", help="subsample to a minimum spacing (core points)")
    p.add_argument("input", type=Path, help="the point cloud")
    p.add_argument("-o", "--output", type=Path, required=True,
                   help="the kept points with their attributes: .csv .txt .ply .las .laz")
    p.add_argument("--spacing", type=float, required=True, help="minimum distance between kept points")
    add_drop_nonfinite_option(p)
    p.set_defaults(run=run_subsample)


def _info_parser(sub) -> None:
    p = sub.add_parser("info", help="point count, bounds, CRS and fields of a file")
    p.add_argument("file", type=Path, help="a point-cloud file")
    p.add_argument("--json", action="store_true",
                   help="machine-readable output: one JSON object, the CRS as name, EPSG code and WKT (default: text)")
    p.set_defaults(run=run_info)


def make_parser() -> argparse.ArgumentParser:
    parser = ArgumentParser(prog="m3c2", description="M3C2 point-cloud change detection (Lague et al. 2013)")
    from . import __version__
    parser.add_argument("--version", action="version", version=f"m3c2 (m3c2kit) {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=ArgumentParser)
    from .series.cli import series_parsers  # noqa: PLC0415 - m3c2 series (docs/series.md)
    for build in (_compare_parser, _normals_parser, _subsample_parser, _info_parser, analysis_parsers, classify_parsers,
                  series_parsers):
        build(sub)
    return parser


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


def _read(path: Path, args):
    return read_cloud(path, drop_nonfinite=getattr(args, "drop_nonfinite", False))


def _orient_spec(args, settings: dict, reference, core=None):
    """--orient as the engine takes it: the reference's E57 scan positions when not given, and
    ``sensor`` read from the file the core points come from (the --core file, as CloudCompare;
    the reference when that file has no scanner pose, or when there is no --core file)."""
    if "orient" not in settings:
        positions = getattr(reference, "scan_positions", None)
        return positions if positions is not None and len(positions) else "+z"
    spec = settings["orient"]
    if not orientation.needs_scan_positions(spec):
        return spec
    main_file = getattr(args, "reference", None) or getattr(args, "input", None)  # compare / normals
    positions, path, also = getattr(reference, "scan_positions", None), str(main_file), None
    if args.core is not None:  # the core points' own scanner first (CloudCompare's), else the reference's
        own = getattr(core, "scan_positions", None)
        if own is not None and len(own):
            positions = own
        elif positions is None or not len(positions):
            path, also = str(args.core), str(main_file)
    origin = f"--orient {spec}"
    if getattr(args, "orient", None) is None and getattr(args, "params", None) is not None:
        origin = f"{args.params}: NormalPreferedOri={ORIENT_KEY_VALUES[spec]}"
    return orientation.sensor_points(spec, positions, path, origin, also)


def run_compare_tiled(args, settings: dict, grid=None) -> int:
    """`m3c2 compare ... --tile-size S | --memory-limit M [--dask-scheduler ADDRESS]` (m3c2kit.run.tiled)."""
    from .run.dask import connect
    from .run.tiled import preflight

    for flag, value in (("--grid", grid), ("--report", getattr(args, "report", None)),
                        ("--report-png", getattr(args, "report_png", None))):
        if value is not None:
            raise UsageError(f"{flag} cannot be combined with tiling (--tile-size, --memory-limit, --dask-scheduler)")
    if args.tile_size is None and args.memory_limit is None:
        raise UsageError("--dask-scheduler needs --tile-size S or --memory-limit SIZE to cut the work into tiles")

    settings = dict(settings)
    field_names = settings.pop("field_names", "m3c2") or "m3c2"
    float64 = bool(settings.pop("float64", False))
    all_fields = bool(settings.pop("all_fields", False))
    position = settings.pop("position", "core")
    threads = settings.pop("threads", 0)
    core_spacing = settings.pop("core_spacing", None)
    drop = bool(getattr(args, "drop_nonfinite", False))
    # The executor's checks and the Dask connection (bounded in time) before any file is read.
    checked = dict(settings, threads=threads, core_spacing=core_spacing)
    if orientation.needs_scan_positions(checked.get("orient")):
        checked.pop("orient")  # read with the files; it does not change the halo
    plan = preflight(checked, args.tile_size, args.memory_limit,
                     read_points=lambda p: read_cloud(p, drop_nonfinite=drop).xyz)[0]
    client = connect(args.dask_scheduler) if args.dask_scheduler is not None else None
    try:
        code = _compare_tiled(args, settings, client, position, threads, core_spacing, drop,
                              dict(field_names=field_names, float64=float64, all_fields=all_fields))
    finally:
        if client is not None:
            client.close()
    if args.verbose:  # as the in-memory run: the parameters the run was given, with D as a list
        for name, value in sorted(plan.record.items()):
            print(f"parameter {name}: {value}")
    return code


def _compare_tiled(args, settings, client, position, threads, core_spacing, drop, storage: dict) -> int:
    from .io.streaming import PointSource
    from .run import run_tiled

    ref_src = PointSource(args.reference, drop_nonfinite=drop)
    cmp_src = PointSource(args.compared, drop_nonfinite=drop)
    core_cloud = read_cloud(args.core, drop_nonfinite=drop) if args.core is not None else None
    if settings.get("normal_source") != "core":  # given normals are used as they are
        settings["orient"] = _orient_spec(args, settings, ref_src.cloud, core_cloud)
    check_same_crs(ref_src.like(), cmp_src.like(), core_cloud, ignore=getattr(args, "ignore_crs", False),
                   allow_angular=getattr(args, "allow_angular", False))
    core_normals = _core_normals(args, core_cloud) if settings.get("normal_source") == "core" else None
    say = (lambda s: None) if args.quiet else (lambda s: print(f"m3c2: {s}", flush=True))
    report = run_tiled(ref_src, cmp_src, output=args.output,
                       core=core_cloud.xyz if core_cloud is not None else None, core_spacing=core_spacing,
                       core_normals=core_normals, tile_size=args.tile_size, memory_limit=args.memory_limit,
                       client=client, threads=threads or 0, projected=args.projected,
                       position=position, **storage, drop_nonfinite=drop, log=say,
                       read_points=lambda p: read_cloud(p, drop_nonfinite=drop).xyz, **settings)
    if not args.quiet:
        for line in report.lines(args.output):
            print(line)
    return 0


def _inputs(args, settings: dict | None = None) -> dict:
    """Every file a command reads, by the name its messages use."""
    files = {"reference cloud": getattr(args, "reference", None), "compared cloud": getattr(args, "compared", None),
             "input cloud": getattr(args, "input", None), "core points file": getattr(args, "core", None),
             "core normals file": getattr(args, "core_normals", None), "params file": getattr(args, "params", None)}
    orient = (settings or {}).get("orient", getattr(args, "orient", None))
    if isinstance(orient, str) and orient.strip().lower().startswith(orientation.AWAY):
        orient = orient.strip()[len(orientation.AWAY):].strip()
    if isinstance(orient, (str, Path)) and str(orient) and os.path.exists(orient):  # False, not OSError, for a name too long
        files["orientation file"] = orient
    return files


def _compare_outputs(args) -> dict:
    """Every file `m3c2 compare` writes, by its option."""
    from .report import png_paths

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
    # Every parameter's checks, options that would change nothing included, before any file is read.
    resolve(settings, "compare")
    check_core_normals(settings, args.core_normals, "--core-normals")
    check_all_fields(args.output, settings.get("all_fields"))
    laz_threads.set_threads(api.threads_count(settings.get("threads")))  # LAZ coding: --threads too (checked first)
    check_outputs(_compare_outputs(args), _inputs(args, settings))  # before any work (docs/errors.md)
    phases = phases_for(args)  # -q with --progress refused here, in every mode
    if args.tile_size is not None or args.memory_limit is not None or args.dask_scheduler is not None:
        if getattr(args, "crs", None) is not None:  # an empty --crs '' was dropped silently
            raise UsageError("--crs is not available with --tile-size, --memory-limit or --dask-scheduler; "
                             "give the inputs a CRS (e.g. convert them to LAS with one) or run in memory")
        return run_compare_tiled(args, settings, grid=cell)  # out-of-core / Dask (docs/scaling.md)
    files = [f for f in (args.reference, args.compared, args.core) if f is not None]
    with phases.phase("reading", total=len(files)) as step:
        reference = _read(args.reference, args)
        step(1, len(files))
        compared = _read(args.compared, args)
        step(2, len(files))
        core_cloud = _read(args.core, args) if args.core is not None else None
        step(len(files), len(files))
    if getattr(args, "crs", None) is not None:  # '' too: refused as no CRS, not ignored
        assign_crs(args.crs, reference, compared, core_cloud)
    check_same_crs(reference, compared, core_cloud, ignore=getattr(args, "ignore_crs", False),
                   allow_angular=getattr(args, "allow_angular", False))  # docs/errors.md
    grid = None
    if cell is not None:
        grid = raster.grid_core_points(reference, cell)
        core_cloud = grid.core_points
    if settings.get("normal_source") != "core":  # given normals are used as they are
        settings["orient"] = _orient_spec(args, settings, reference, core_cloud)
    position = settings.pop("position", "core")
    field_names = settings.pop("field_names", "m3c2")
    float64 = bool(settings.pop("float64", False))
    all_fields = bool(settings.pop("all_fields", False))
    threads = settings.pop("threads", 0)
    core_normals = None
    if settings.get("normal_source") == "core":
        core_normals = _core_normals(args, core_cloud)
    # The engine indexes both clouds, fits the normals and measures the distances in one call,
    # reporting core points done: one bar for the three.
    with phases.phase("indexing, normals, distances") as step:
        # The clouds' arrays are the command line's own (read above): ordered in place, not copied.
        result = api.compare(reference, compared, core_cloud, core_normals=core_normals, threads=threads,
                             progress=step, read_points=lambda p: _read(p, args).xyz, reorder_inputs=True,
                             **settings)
    outputs = CompareOutputs(table=args.output, report=args.report, report_png=args.report_png,
                             projected=args.projected, position=position, field_names=field_names,
                             float64=float64, all_fields=all_fields, core_spacing=settings.get("core_spacing"),
                             inputs={"reference": args.reference, "compared": args.compared})
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
    _print_notes((reference, compared, core_cloud))  # the warnings: m3c2kit.diagnostics, through main()
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


def _print_notes(clouds) -> None:
    """What reading changed in the inputs (docs/errors.md), on stderr beside the warnings."""
    for c in clouds:
        if getattr(c, "dropped_nonfinite", 0):
            print(f"m3c2: note: dropped {c.dropped_nonfinite} points with non-finite coordinates from "
                  f"{printable(str(c.path))}", file=sys.stderr)


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """The run's warnings (m3c2kit.diagnostics' M3C2Warning and any other) as one line on stderr."""
    print(f"m3c2: warning: {message}", file=sys.stderr)


def _core_normals(args, core_cloud) -> np.ndarray:
    if args.core_normals is not None:
        return _read(args.core_normals, args).xyz
    if core_cloud is None:
        raise UsageError("--normal-source core needs --core with normal fields (nx, ny, nz) or --core-normals FILE")
    normals = core_cloud.normals()
    if normals is not None:
        return normals
    raise UsageError(f"{args.core}: no normal fields (nx, ny, nz) for --normal-source core; use --core-normals FILE")


def run_normals(args) -> int:
    resolve({p.name: getattr(args, p.name) for p in parameters_of("normals")}, "normals")  # before any file is read
    check_outputs({"-o": args.output}, _inputs(args))
    phases = phases_for(args)
    files = [f for f in (args.input, args.core) if f is not None]
    with phases.phase("reading", total=len(files)) as step:
        cloud = _read(args.input, args)
        step(1, len(files))
        core_cloud = _read(args.core, args) if args.core is not None else None
        step(len(files), len(files))
    given = {param.name: getattr(args, param.name) for param in parameters_of("normals")}
    if orientation.needs_scan_positions(given.get("orient")):
        given["orient"] = _orient_spec(args, given, cloud, core_cloud)
    with phases.phase("indexing, normals") as step:
        out = api.normals(cloud, core_cloud.xyz if core_cloud is not None else None, progress=step,
                          read_points=lambda p: _read(p, args).xyz, **given)
    n = out["normal"]
    fields = {"nx": n[:, 0], "ny": n[:, 1], "nz": n[:, 2], "normal_scale": out["normal_scale"],
              "roughness": out["roughness"], "count": out["count"].astype(np.uint32), "status": out["status"]}
    with phases.phase("writing", total=1) as step:
        write_cloud_table(args.output, out["core"], fields, like=cloud)
        step(1, 1)
    if args.verbose:
        for name, value in sorted(given.items()):
            if value is not None:
                print(f"parameter {name}: {value}")
    if not args.quiet:
        ok = int(np.count_nonzero(np.asarray(out["status"]) == 0))
        print(f"wrote {args.output}: normals at {ok:,} of {len(out['core']):,} points "
              f"({100.0 * ok / max(len(out['core']), 1):.1f} %); median roughness "
              f"{np.nanmedian(out['roughness']) if ok else float('nan'):.4g}; columns {', '.join(fields)}")
    return 0


def run_subsample(args) -> int:
    check_outputs({"-o": args.output}, _inputs(args))
    cloud = _read(args.input, args)
    kept = api.subsample(cloud.xyz, args.spacing)
    fields = {name: np.asarray(values)[kept] for name, values in cloud.fields.items()}
    write_cloud_table(args.output, cloud.xyz[kept], fields, like=cloud)
    print(f"{args.output}: kept {len(kept)} of {len(cloud.xyz)} points (min spacing {args.spacing})")
    return 0


def run_info(args) -> int:
    d = describe(args.file)
    if args.json:
        import json
        print(printable(json.dumps(d, indent=2)))
    else:
        print(printable(describe_text(d)))  # a WKT or a file name may hold terminal escapes
    return 0


_CLEAN_EXIT_SIGNALS = tuple(getattr(signal, name) for name in ("SIGHUP", "SIGQUIT", "SIGTERM") if hasattr(signal, name))


def _raise_interrupted(signum, frame):
    raise Interrupted(f"interrupted by {signal.Signals(signum).name}; no output written")


def _show_warning(message, category, filename, lineno, file=None, line=None):
    """M3C2Warning (e.g. QuantisationWarning) as `m3c2: warning: ...`; others as Python shows them."""
    if issubclass(category, M3C2Warning):
        print(f"m3c2: warning: {printable(message)}", file=sys.stderr)
    else:
        _python_showwarning(message, category, filename, lineno, file, line)


_python_showwarning = warnings.showwarning


#: Option values that start with "-" and that argparse would take for options: "--orient -z".
_DASH_VALUES = {"--orient": ("-x", "-y", "-z")}


def join_dash_values(argv: list[str]) -> list[str]:
    """["--orient", "-z"] -> ["--orient=-z"], as --help writes it (argparse reads "-z" as an option)."""
    out: list[str] = []
    i = 0
    while i < len(argv):
        a = argv[i]
        if a in _DASH_VALUES and i + 1 < len(argv) and str(argv[i + 1]).lower() in _DASH_VALUES[a]:
            out.append(f"{a}={argv[i + 1]}")
            i += 2
            continue
        out.append(a)
        i += 1
    return out


def main(argv=None) -> int:
    """The `m3c2` command. Without `argv` (the `m3c2` script, ``python -m m3c2kit``) the process
    is the command line's own: laspy is imported without the modules a local file never uses
    (m3c2kit.io.laspy_local) when the arguments name a LAS/LAZ file."""
    if argv is None and laspy_local.names_las_file(sys.argv[1:]):
        laspy_local.import_laspy_for_local_files()
    # SIGHUP, SIGQUIT and SIGTERM end the run as SIGINT does: an exception that unwinds through
    # the atomic writer, which removes its private folders (no partial output, no leftover).
    previous = {s: signal.signal(s, _raise_interrupted) for s in _CLEAN_EXIT_SIGNALS}
    with warnings.catch_warnings():
        warnings.simplefilter("always", M3C2Warning)
        warnings.showwarning = _show_warning
        try:
            return _main(argv)
        finally:
            for number, handler in previous.items():
                signal.signal(number, handler)


def _main(argv) -> int:
    try:
        with warnings.catch_warnings():
            warnings.showwarning = _show_warning
            argv = join_dash_values([str(a) for a in (sys.argv[1:] if argv is None else argv)])
            args = make_parser().parse_args(argv)
            code = args.run(args)
            sys.stdout.flush()  # a closed stdout raises here, not in the interpreter's final flush
            return code
    except UsageError as e:
        print(f"m3c2: error: {printable(e)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("m3c2: error: interrupted by SIGINT; no output written", file=sys.stderr)
        return 1
    except M3C2Error as e:
        print(f"m3c2: error: {printable(e)}", file=sys.stderr)
        return 1
    except MemoryError:
        print("m3c2: error: out of memory; use fewer or subsampled core points", file=sys.stderr)
        return 1
    except BrokenPipeError:
        # stdout closed by the reader (`m3c2 info x.las | head -1`): stop quietly, as Unix tools
        # do, and point stdout at /dev/null so that the interpreter's final flush stays quiet.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 1
    except OSError as e:
        # An OS error no reader or writer turned into a message: e.g. a name over 255 bytes, which
        # pathlib's checks (exists, is_file) raise instead of answering. Writers remove their
        # temporaries on any exception (io.atomic), so nothing half-written is left.
        print(f"m3c2: error: {printable(os_error_message(e))}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
