"""What every subcommand does with the files it is given: read them, name them (for the rule
that no output is an input), resolve --orient with their scanner poses, and report what reading
changed."""
from __future__ import annotations

import os
import sys
from pathlib import Path

from ..base.errors import printable
from ..io import read_cloud
from ..settings import orientation
from ..settings.cloudcompare_params import ORIENT_KEY_VALUES
def read_input(path: Path, args):
    return read_cloud(path, drop_nonfinite=getattr(args, "drop_nonfinite", False))


def input_files(args, settings: dict | None = None) -> dict:
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


def orient_spec(args, settings: dict, reference, core=None):
    """--orient with the files' scanner positions (settings.orientation.for_clouds), the message
    naming the option or the params file's key it came from."""
    spec = settings.get("orient")
    origin = f"--orient {spec}"
    if getattr(args, "orient", None) is None and getattr(args, "params", None) is not None and spec is not None:
        origin = f"{args.params}: NormalPreferedOri={ORIENT_KEY_VALUES[spec]}"
    main_file = getattr(args, "reference", None) or getattr(args, "input", None)  # compare / normals
    return orientation.for_clouds(spec, reference, core, reference_name=str(main_file),
                                  core_name=None if args.core is None else str(args.core), origin=origin)


def print_notes(clouds) -> None:
    """What reading changed in the inputs (docs/errors.md), on stderr beside the warnings."""
    for c in clouds:
        if getattr(c, "dropped_nonfinite", 0):
            print(f"m3c2: note: dropped {c.dropped_nonfinite} points with non-finite coordinates from "
                  f"{printable(str(c.path))}", file=sys.stderr)

