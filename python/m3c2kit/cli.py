"""The `m3c2` command line: parse, read, compute, write. Exit 0 on success, 2 for usage errors,
1 for failures (unreadable input, unwritable output, interruption); no partial output file."""
from __future__ import annotations

import argparse
import os
import signal
import warnings
import sys
from pathlib import Path

import numpy as np

from . import api, raster
from .analysis.cli import analysis_parsers
from .classify.cli import classify_parsers
from .errors import M3C2Error, M3C2Warning, UsageError, printable
from .io import read_cloud, write_cloud_table
from .io import crs as crs_mod
from .io.describe import describe, describe_text
from .progress import ProgressBar
from .report.outputs import write_compare_outputs
from .settings import by_name, parameters_of
from .settings.cloudcompare_params import read_cloudcompare_params
from .summary import summary_lines



class Interrupted(M3C2Error):
    """SIGINT or SIGTERM during a run."""


class ArgumentParser(argparse.ArgumentParser):
    def error(self, message):  # argparse's own usage errors: exit 2 with one clear line
        self.print_usage(sys.stderr)
        raise UsageError(message)


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
    p.add_argument("--drop-nonfinite", action="store_true", help="drop points with NaN/Inf coordinates")
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
    p.add_argument("--quiet", action="store_true", help="no progress bar or summary")
    p.set_defaults(run=run_compare)


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
    p.add_argument("input", type=Path)
    p.add_argument("-o", "--output", type=Path, required=True)
    p.add_argument("--core", type=Path, help="core points (default: every point)")
    add_table_options(p, "normals")
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(run=run_normals)


def _subsample_parser(sub) -> None:
    p = sub.add_parser("subsample", help="subsample to a minimum spacing (core points)")
    p.add_argument("input", type=Path)
    p.add_argument("-o", "--output", type=Path, required=True)
    p.add_argument("--spacing", type=float, required=True, help="minimum distance between kept points")
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
    for build in (_compare_parser, _normals_parser, _subsample_parser, _info_parser, analysis_parsers, classify_parsers):
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
    for required, flag in (("projection_scale", "--projection-scale"), ("max_depth", "--max-depth")):
        if required not in settings:
            raise UsageError(f"{flag} is required (or a --params file that sets it)")
    return settings


def _read(path: Path, args):
    return read_cloud(path, drop_nonfinite=getattr(args, "drop_nonfinite", False))


def _orient_spec(args, settings: dict, reference):
    if "orient" in settings:
        return settings["orient"]
    positions = getattr(reference, "scan_positions", None)
    return positions if positions is not None and len(positions) else "+z"


def run_compare(args) -> int:
    cell = raster.grid_mode(args)  # --grid: checks its options, d = 1.1 CELL by default
    settings = compare_settings(args)
    if args.tile_size is not None or args.memory_limit is not None or args.dask_scheduler is not None:
        if getattr(args, "crs", None):
            raise UsageError("--crs is not available with --tile-size, --memory-limit or --dask-scheduler; "
                             "give the inputs a CRS (e.g. convert them to LAS with one) or run in memory")
        from .tiling import run_compare_tiled  # out-of-core / Dask (docs/scaling.md)
        return run_compare_tiled(args, settings, grid=cell)
    reference, compared = _read(args.reference, args), _read(args.compared, args)
    core_cloud = _read(args.core, args) if args.core is not None else None
    if getattr(args, "crs", None):
        assign_crs(args.crs, reference, compared, core_cloud)
    check_same_crs(reference, compared, core_cloud, ignore=getattr(args, "ignore_crs", False),
                   allow_angular=getattr(args, "allow_angular", False))  # docs/errors.md
    grid = None
    if cell is not None:
        settings = raster.grid_settings(settings)
        grid = raster.grid_core_points(reference, cell)
        core_cloud = grid.core_points
    settings["orient"] = _orient_spec(args, settings, reference)
    position = settings.pop("position", "core")
    field_names = settings.pop("field_names", "m3c2")
    float64 = bool(settings.pop("float64", False))
    threads = settings.pop("threads", 0)
    core_normals = None
    if settings.get("normal_source") == "core":
        core_normals = _core_normals(args, core_cloud)
    bar = ProgressBar("M3C2", enabled=not args.quiet)
    result = api.compare(reference, compared, core_cloud, core_normals=core_normals, threads=threads,
                         progress=bar.update, read_points=lambda p: _read(p, args).xyz, **settings)
    bar.close()
    extra = write_compare_outputs(args, result, reference, grid=grid, position=position, field_names=field_names,
                                  float64=float64, core_spacing=settings.get("core_spacing"))
    if not args.quiet:
        for line in summary_lines(result, args.output):
            print(line)
        for path in extra:
            print(f"wrote {path}")
    _print_warnings(args, settings, result, reference, compared, core_cloud)  # docs/errors.md
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


#: Share of computed core points with an empty cylinder in one cloud only above which
#: `compare` warns that --max-depth may be shorter than the change.
EMPTY_ONE_SIDE_WARNING = 0.10


def result_warnings(result, min_points: int, max_depth=None, projection_scale=None) -> list[str]:
    """Warnings for runs that are legitimate but likely mis-parameterised (docs/errors.md):
    the median n1 or n2 below `min_points` (cylinder too thin for the point spacing), and more
    than 10 % of core points with a searched cylinder having it empty in one cloud only (the
    change reaches beyond --max-depth)."""
    searched = np.isin(result.status, (0, 3, 4, 5))  # a normal was found: cylinders were searched
    if not searched.any():
        return []
    lines = []
    n1, n2 = np.asarray(result.n1)[searched], np.asarray(result.n2)[searched]
    m1, m2 = float(np.median(n1)), float(np.median(n2))
    if min(m1, m2) < min_points:
        lines.append(f"warning: the median cylinder holds n1 = {m1:g}, n2 = {m2:g} points, fewer than "
                     f"--min-points {min_points}: the projection scale d = {projection_scale} is small for "
                     f"the point spacing and most LODs are NaN; consider a larger --projection-scale")
    # Empty cylinders in one cloud: m3c2kit.quality tells no overlap from a depth too short.
    return lines


def quality_warnings(settings: dict, result, reference, compared) -> list[str]:
    """m3c2kit.quality's diagnoses: normals that fail (D given as a radius?), and empty cylinders
    split into no overlap (no depth helps) and a depth too short (the depth that reaches)."""
    from . import quality

    lines = []
    failed = quality.normal_failure_message(result, settings.get("normal_scale") or 0.0)
    if failed:
        lines.append(f"warning: {failed}")
    status = np.asarray(result.status)
    with_normal = np.count_nonzero(np.isin(status, (0, 3, 4, 5)))
    empty = np.count_nonzero(np.isin(status, (3, 4)))
    if with_normal and empty / with_normal > quality.EMPTY_SHARE:
        diagnoses = quality.cylinder_diagnosis(reference.xyz, compared.xyz, result,
                                               projection_scale=float(settings["projection_scale"]),
                                               max_depth=float(settings["max_depth"]),
                                               threads=int(settings.get("threads", 0) or 0))
        lines += [f"warning: {m}" for m in quality.cylinder_messages(diagnoses, float(settings["max_depth"]))]
    return lines


def _print_warnings(args, settings: dict, result, *clouds) -> None:
    """Warnings go to stderr (docs/errors.md), with --quiet too: they are about the numbers."""
    min_points = settings.get("min_points")
    lines = [f"note: dropped {c.dropped_nonfinite} points with non-finite coordinates from {c.path}"
             for c in clouds if getattr(c, "dropped_nonfinite", 0)]
    lines += result_warnings(result, by_name()["min_points"].default_for(settings.get("compat")) if min_points is None
                             else int(min_points),
                             settings.get("max_depth"), settings.get("projection_scale"))
    if len(clouds) >= 2 and clouds[0] is not None and clouds[1] is not None:
        lines += quality_warnings(settings, result, clouds[0], clouds[1])
    for line in lines:
        print(f"m3c2: {line}", file=sys.stderr)


def _core_normals(args, core_cloud) -> np.ndarray:
    if args.core_normals is not None:
        return _read(args.core_normals, args).xyz
    if core_cloud is None:
        raise UsageError("--normal-source core needs --core with normal fields (nx, ny, nz) or --core-normals FILE")
    fields = {k.lower(): v for k, v in core_cloud.fields.items()}
    for names in (("nx", "ny", "nz"), ("normalx", "normaly", "normalz"), ("normal_x", "normal_y", "normal_z")):
        if all(n in fields for n in names):
            return np.column_stack([fields[n] for n in names]).astype(float)
    raise UsageError(f"{args.core}: no normal fields (nx, ny, nz) for --normal-source core; use --core-normals FILE")


def run_normals(args) -> int:
    cloud = _read(args.input, args)
    core = _read(args.core, args).xyz if args.core is not None else None
    bar = ProgressBar("normals", enabled=not args.quiet)
    given = {param.name: getattr(args, param.name) for param in parameters_of("normals")}
    out = api.normals(cloud, core, progress=bar.update, read_points=lambda p: _read(p, args).xyz, **given)
    bar.close()
    n = out["normal"]
    fields = {"nx": n[:, 0], "ny": n[:, 1], "nz": n[:, 2], "normal_scale": out["normal_scale"],
              "roughness": out["roughness"], "count": out["count"].astype(np.uint32), "status": out["status"]}
    write_cloud_table(args.output, out["core"], fields, like=cloud)
    if not args.quiet:
        ok = int(np.count_nonzero(np.asarray(out["status"]) == 0))
        print(f"{args.output}: normals at {ok:,} of {len(out['core']):,} points "
              f"({100.0 * ok / max(len(out['core']), 1):.1f} %); median roughness "
              f"{np.nanmedian(out['roughness']) if ok else float('nan'):.4g}")
    return 0


def run_subsample(args) -> int:
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
    previous = signal.signal(signal.SIGTERM, _raise_interrupted)
    try:
        with warnings.catch_warnings():
            warnings.showwarning = _show_warning
            argv = join_dash_values([str(a) for a in (sys.argv[1:] if argv is None else argv)])
            args = make_parser().parse_args(argv)
            return args.run(args)
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
    finally:
        signal.signal(signal.SIGTERM, previous)


if __name__ == "__main__":
    sys.exit(main())
