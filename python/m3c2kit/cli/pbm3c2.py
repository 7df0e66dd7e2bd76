"""`m3c2 pbm3c2 REFERENCE COMPARED -o OUT [--per-point FILE]`: correspondence-driven plane-based
M3C2 (Zahs et al. 2022; m3c2kit.analysis.pbm3c2, docs/pbm3c2.md): one row per reference segment
(x, y, z its centroid, nx, ny, nz, distance, lod, significant, n1, n2, then the segments' ids,
roughnesses, the planes' angle and status), in any format m3c2 writes. Registered by
m3c2kit.cli.main."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .command_index import summary
from ..analysis.pbm3c2 import STATUS, pbm3c2
from ..analysis.pbm3c2_forest import read_training
from ..base.errors import UsageError
from ..io import crs as crs_mod
from ..io import write_cloud_table
from ..io.atomic import staged_outputs
from ..io.collisions import check_outputs
from ..settings.table import by_name, parameters_of
from .inputs import read_input
from .options import add, add_table_option, single_normal_scale, step_options

COMMAND = "pbm3c2"
#: The rows the command reads itself (files), not PBM3C2Options.
_FILES = ("segments", "training", "per_point")


def pbm3c2_parser(sub) -> None:
    p = sub.add_parser(COMMAND, help=summary(COMMAND),
                       description="Correspondence-driven plane-based M3C2 (Zahs et al. 2022): both clouds cut into "
                                   "planar segments (region growing on normals, or --segments FIELD), each reference "
                                   "segment paired with the compared segment of the same surface (the nearest "
                                   "centroid within --search-radius and --max-angle, or a random forest trained on "
                                   "--training), and the change: the distance between the two planes along the "
                                   "reference normal, with eq. (1)'s LOD from the planes' fits and reg. One row per "
                                   "reference segment; a segment without a pair has NaN and its status "
                                   "(docs/pbm3c2.md).")
    p.add_argument("reference", type=Path, help="reference cloud (first epoch)")
    p.add_argument("compared", type=Path, help="compared cloud (second epoch)")
    p.add_argument("-o", "--output", type=Path, required=True,
                   help="the segment pairs (.las/.laz/.ply/.csv/.txt/.npy...): one row per reference segment")
    add(p, "derived_normal_scale", default_text="m3c2 suggest's D, from the data; not with --segments")
    step_options(p, COMMAND)
    add_table_option(p, "registration_error", filled=True)
    add_table_option(p, "confidence", filled=True)
    add(p, "ignore_crs")
    add_table_option(p, "threads", filled=True)
    add(p, "quiet")
    p.set_defaults(run=run_pbm3c2)


def _segment_ids(cloud, field: str) -> np.ndarray:
    fields = getattr(cloud, "fields", None) or {}
    if field not in fields:
        raise UsageError(f"{cloud.path}: no field {field!r} (--segments); its fields: "
                         f"{', '.join(fields) or 'none'}")
    return fields[field]


def run_pbm3c2(args) -> int:
    for name in _FILES[1:]:  # Text rows: kept as given
        if getattr(args, name) is not None:
            setattr(args, name, Path(getattr(args, name)))
    check_outputs({"-o": args.output, "--per-point": args.per_point},
                  {"reference cloud": args.reference, "compared cloud": args.compared, "--training": args.training})
    # Given options only: m3c2kit.pbm3c2 refuses one that would change nothing (the rows' needs).
    options = {row.name: getattr(args, row.name) for row in parameters_of(COMMAND)
               if row.name not in _FILES and getattr(args, row.name) is not None}
    # m3c2kit.pbm3c2 checks these too; here they fail before two clouds are read.
    if args.correspondence == "forest" and args.training is None:
        raise UsageError("--correspondence forest learns from labelled pairs: give --training CSV")
    if args.training is not None and args.correspondence != "forest":
        raise UsageError("--training would change nothing in this run: it applies only with --correspondence forest")
    if args.normal_scale is not None and args.segments is not None:
        raise UsageError("--normal-scale would change nothing in this run: it applies only without --segments "
                         "(the segmentation's D)")
    scale = single_normal_scale(args.normal_scale, "pbm3c2 (the segmentation's normals)")
    training = read_training(args.training) if args.training is not None else None
    registration_error = by_name()["registration_error"].kind("--registration-error", args.registration_error)
    reference, compared = read_input(args.reference, args), read_input(args.compared, args)
    crs_mod.check_crs(reference, compared, ignore=args.ignore_crs)
    for name, cloud in (("reference", reference), ("compared", compared)):
        if len(cloud.xyz) == 0:
            raise UsageError(f"{cloud.path}: the {name} cloud is empty")
    segments = {}
    if args.segments is not None:
        segments = {"reference_segments": _segment_ids(reference, args.segments),
                    "compared_segments": _segment_ids(compared, args.segments)}
    try:
        found = pbm3c2(reference, compared, training=training, registration_error=registration_error,
                       confidence=args.confidence, threads=args.threads, normal_scale=scale, **segments, **options)
    except UsageError as e:
        raise UsageError(f"{args.compared} against {args.reference}: {e}") from None
    pairs = dict(found.pairs)
    xyz = np.column_stack([pairs.pop("x"), pairs.pop("y"), pairs.pop("z")])
    with staged_outputs([p for p in (args.output, args.per_point) if p is not None]) as staged:
        write_cloud_table(staged[args.output], xyz, pairs, like=reference)
        if args.per_point is not None:
            write_cloud_table(staged[args.per_point], reference.xyz, found.per_point(), like=reference)
    if not args.quiet:
        _say(args, found)
    return 0


def _say(args, found) -> None:
    d, status = found.details, found.pairs["status"]
    print(f"{args.reference}: {d['reference_segments']} segments, {args.compared}: {d['compared_segments']} "
          f"({d['segmented_by']}{', D ' + format(d['normal_scale'], '.6g') if d['segmented_by'] != 'given' else ''})")
    significant = int(np.count_nonzero(found.pairs["significant"]))
    print(f"{d['paired']} of {len(status)} reference segments paired ({d['correspondence']}, search radius "
          f"{d['search_radius']:.6g}), {significant} with a significant change")
    for code in np.unique(status[status != 0]):
        print(f"  {int(np.count_nonzero(status == code))} unpaired: {STATUS[int(code)]}")
    print(f"wrote {args.output}" + (f" and {args.per_point}" if args.per_point is not None else ""))
