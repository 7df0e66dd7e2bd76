"""`m3c2 normals`, `m3c2 subsample`, `m3c2 info` and `m3c2 convert`."""
from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from .command_index import summary
from ..base.errors import M3C2Warning, printable
from ..io import write_cloud_table
from ..io.collisions import check_outputs
from ..io.crs import crs_label
from ..io.registry import keeps_crs
from ..io.describe import describe, describe_text
from ..io.files import add_drop_nonfinite_option, writable_format
from ..run import in_memory
from ..settings import orientation, parameters_of, resolve
from .inputs import input_files, orient_spec, read_input
from .options import add, add_progress_option, add_table_options, add_verbosity_options
from .parser import phases_for


def normals_parser(sub) -> None:
    p = sub.add_parser("normals", help=summary("normals"))
    p.add_argument("input", type=Path, help="the point cloud")
    p.add_argument("-o", "--output", type=Path, required=True,
                   help="output: .csv .txt .ply .las .laz (nx, ny, nz, normal_scale, roughness, count, status)")
    add(p, "core", default_text="every point")
    add_table_options(p, "normals")
    add_drop_nonfinite_option(p)
    add_verbosity_options(p)
    add_progress_option(p)
    p.set_defaults(run=run_normals)


def subsample_parser(sub) -> None:
    p = sub.add_parser("subsample", help=summary("subsample"))
    p.add_argument("input", type=Path, help="the point cloud")
    p.add_argument("-o", "--output", type=Path, required=True,
                   help="the kept points with their attributes: .csv .txt .ply .las .laz")
    p.add_argument("--spacing", type=float, required=True, help="minimum distance between kept points")
    add_drop_nonfinite_option(p)
    add(p, "quiet")
    p.set_defaults(run=run_subsample)


def info_parser(sub) -> None:
    p = sub.add_parser("info", help=summary("info"))
    p.add_argument("file", type=Path, help="a point-cloud file")
    p.add_argument("--json", action="store_true",
                   help="machine-readable output: one JSON object, the CRS as name, EPSG code and WKT (default: text)")
    p.set_defaults(run=run_info)


def convert_parser(sub) -> None:
    # The QGIS provider's route from any output to a table QGIS reads (its Python has no m3c2kit).
    p = sub.add_parser("convert", help=summary("convert"))
    p.add_argument("input", type=Path, help="a point-cloud file")
    p.add_argument("-o", "--output", type=Path, required=True,
                   help="the copy, format by extension: .csv .txt .ply .las .laz (the CRS kept where the format holds one)")
    add_drop_nonfinite_option(p)
    add(p, "quiet")
    p.set_defaults(run=run_convert)


def run_normals(args) -> int:
    resolve({p.name: getattr(args, p.name) for p in parameters_of("normals")}, "normals")  # before any file is read
    check_outputs({"-o": args.output}, input_files(args))
    phases = phases_for(args)
    files = [f for f in (args.input, args.core) if f is not None]
    with phases.phase("reading", total=len(files)) as step:
        cloud = read_input(args.input, args)
        step(1, len(files))
        core_cloud = read_input(args.core, args) if args.core is not None else None
        step(len(files), len(files))
    given = {param.name: getattr(args, param.name) for param in parameters_of("normals")}
    if orientation.needs_scan_positions(given.get("orient")):
        given["orient"] = orient_spec(args, given, cloud, core_cloud)
    with phases.phase("indexing, normals") as step:
        out = in_memory.normals(cloud, core_cloud.xyz if core_cloud is not None else None, progress=step,
                          read_points=lambda p: read_input(p, args).xyz, **given)
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
        print(phases.timing_line())
    if not args.quiet:
        ok = int(np.count_nonzero(np.asarray(out["status"]) == 0))
        print(f"wrote {args.output}: normals at {ok:,} of {len(out['core']):,} points "
              f"({100.0 * ok / max(len(out['core']), 1):.1f} %); median roughness "
              f"{np.nanmedian(out['roughness']) if ok else float('nan'):.4g}; columns {', '.join(fields)}")
    return 0


def run_subsample(args) -> int:
    check_outputs({"-o": args.output}, input_files(args))
    cloud = read_input(args.input, args)
    kept = in_memory.subsample(cloud.xyz, args.spacing)
    fields = {name: np.asarray(values)[kept] for name, values in cloud.fields.items()}
    write_cloud_table(args.output, cloud.xyz[kept], fields, like=cloud)
    if not args.quiet:
        print(f"{args.output}: kept {len(kept)} of {len(cloud.xyz)} points (min spacing {args.spacing})")
    return 0


def run_convert(args) -> int:
    check_outputs({"-o": args.output}, input_files(args))
    writable_format(args.output)  # before the input is read
    cloud = read_input(args.input, args)
    if cloud.crs and not keeps_crs(args.output):
        warnings.warn(f"{args.output}: {args.output.suffix or 'this format'} stores no CRS: the CRS of {args.input} "
                      f"({crs_label(cloud.crs)}) is not in the copy; write .las or .laz to keep it", M3C2Warning,
                      stacklevel=2)
    write_cloud_table(args.output, cloud.xyz, dict(cloud.fields), like=cloud)
    if not args.quiet:
        print(f"wrote {args.output}: {len(cloud.xyz):,} points, columns x, y, z{''.join(', ' + n for n in cloud.fields)}")
    return 0


def run_info(args) -> int:
    d = describe(args.file)
    if args.json:
        import json
        print(printable(json.dumps(d, indent=2)))
    else:
        print(printable(describe_text(d)))  # a WKT or a file name may hold terminal escapes
    return 0

