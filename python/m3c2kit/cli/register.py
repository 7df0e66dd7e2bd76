"""`m3c2 register REFERENCE COMPARED -o TRANSFORM.json [--stable POLYGONS | --auto-stable]`: the rigid
motion that maps COMPARED onto REFERENCE by point-to-plane ICP on stable areas, its covariance and
the registration error `reg` of eq. (1) (m3c2kit.analysis.registration; docs/registration.md), for
`m3c2 compare --transform`, `--registration-error` and `--alignment-covariance`. Registered by
m3c2kit.cli.main."""
from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np

from .command_index import summary
from ..analysis.registration import register
from ..base.errors import M3C2Warning, UsageError
from ..io import crs as crs_mod
from ..io.atomic import staged_outputs
from ..io.collisions import check_outputs, require_suffix
from ..io.polygons import read_regions_for
from ..io.registration_file import registration_bytes
from ..settings.needs import check_effective
from ..settings.registration_rows import REGISTER
from ..settings.table import parameters_of
from .inputs import read_input
from .options import add, add_table_option, single_normal_scale, step_options


def register_parser(sub) -> None:
    p = sub.add_parser(REGISTER, help=summary(REGISTER),
                       description="Point-to-plane ICP (Chen & Medioni 1992) of COMPARED onto REFERENCE on stable "
                                   "areas: given as polygons (plan view), or found by excluding what M3C2 finds "
                                   "significant, round after round (--auto-stable). Writes TRANSFORM.json: matrix "
                                   "(4x4, COMPARED onto REFERENCE), covariance (6x6: rx, ry, rz in radians, tx, ty, "
                                   "tz), registration_error (reg of eq. 1), for m3c2 compare --transform, "
                                   "--registration-error and --alignment-covariance (docs/registration.md).")
    p.add_argument("reference", type=Path, help="reference cloud (first epoch): the one that does not move")
    p.add_argument("compared", type=Path, help="compared cloud (second epoch): the one moved onto the reference")
    p.add_argument("-o", "--output", type=Path, required=True, help="the registration (.json)")
    stable = p.add_mutually_exclusive_group()
    stable.add_argument("--stable", type=Path, metavar="POLYGONS",
                        help="stable areas: GeoJSON or WKT polygons (default: every point, or --auto-stable)")
    stable.add_argument("--auto-stable", action="store_true",
                        help="find the stable areas: register on every point, compare with M3C2 at the data's "
                             "scales, drop the points within d of a significant core point, register again, until "
                             "the stable set settles or --rounds")
    add(p, "derived_normal_scale", default_text="m3c2 suggest's D, from the data")
    # --max-distance, --reject, --max-iterations, --max-points, --rounds: the parameter table's rows
    # (settings/registration_rows.py)
    step_options(p, REGISTER)
    add(p, "ignore_crs")
    add_table_option(p, "threads", filled=True)
    add(p, "quiet")
    p.set_defaults(run=run_register)


def run_register(args) -> int:
    check_outputs({"-o": args.output}, {"reference cloud": args.reference, "compared cloud": args.compared,
                                        "--stable": args.stable})
    require_suffix("-o", args.output, (".json",), "the registration")
    # The rows' values; a row that acts only with another option (--rounds) is None when not given, and
    # m3c2kit.register refuses it given where it would change nothing (the rows' needs), as this check
    # does before two clouds are read.
    options = {row.name: getattr(args, row.name) for row in parameters_of(REGISTER)
               if getattr(args, row.name) is not None}
    check_effective(parameters_of(REGISTER), {**options, "auto_stable": args.auto_stable}, options)
    scale = single_normal_scale(args.normal_scale, "register (the targets' normals)")
    reference, compared = read_input(args.reference, args), read_input(args.compared, args)
    crs_mod.check_crs(reference, compared, ignore=args.ignore_crs)
    polygons = read_regions_for(args.stable, reference, "--stable") if args.stable is not None else None
    for name, cloud in (("reference", reference), ("compared", compared)):
        if len(cloud.xyz) == 0:
            raise UsageError(f"{cloud.path}: the {name} cloud is empty")
    try:
        found = register(reference, compared, stable=polygons, auto_stable=args.auto_stable, normal_scale=scale,
                         threads=args.threads, **options)
    except UsageError as e:
        raise UsageError(f"{args.compared} onto {args.reference}: {e}") from None
    found.details.update(reference=str(args.reference), compared=str(args.compared))
    if not found.details["converged"]:
        warnings.warn(f"{args.compared}: ICP did not converge in {args.max_iterations} steps: the estimate is the "
                      f"last step's (raise --max-iterations)", M3C2Warning, stacklevel=2)
    with staged_outputs([args.output]) as staged:
        staged[args.output].write_bytes(registration_bytes(found))
    if not args.quiet:
        d = found.details
        angle = math.degrees(math.acos(max(-1.0, min(1.0, (np.trace(found.matrix[:3, :3]) - 1) / 2))))
        sd = np.sqrt(np.diag(found.covariance))
        print(f"{args.compared} onto {args.reference}: {d['pairs']} pairs of {d['candidates']} compared points "
              f"({100 * d['stable_fraction']:.1f} % of them stable, {d['stable']}), {d['iterations']} ICP steps"
              + (f", {d['rounds']} rounds" if "rounds" in d else ""))
        print(f"rotation {angle:.6g} deg, translation {' '.join(f'{v:.6g}' for v in found.matrix[:3, 3])}")
        print(f"sd: rotations {' '.join(f'{math.degrees(v):.3g}' for v in sd[:3])} deg, translations "
              f"{' '.join(f'{v:.3g}' for v in sd[3:])} (independent residuals assumed)")
        print(f"registration error (reg of eq. 1) {found.registration_error:.6g}, rms {d['rms']:.6g}")
        print(f"wrote {args.output}")
    return 0
