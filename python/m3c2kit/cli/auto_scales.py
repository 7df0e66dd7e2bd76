"""`m3c2 compare REFERENCE COMPARED -o OUTPUT` with no scale: D, d and the maximum depth not given
are chosen from the data by `m3c2 suggest`'s rules (m3c2kit.analysis.suggest, sections 5.1, 5.2.2
and 5.3 of the paper), rounded as its proposal, and the run says what it chose and why (issue 44).
`--auto-scales` asks for it explicitly: every scale is chosen, a --params file's included. With
--error-model, d is the model's (it applies at no other d)."""
from __future__ import annotations

import math
import warnings
from typing import Callable

from ..base.errors import M3C2Error, UsageError
from ..settings import by_name

#: The scales the rules choose, in the order they are chosen and printed.
SCALES = ("normal_scale", "projection_scale", "max_depth")
#: A scale's stand-in while the other parameters are checked before any file is read.
_STAND_IN = {"normal_scale": "1", "projection_scale": 1.0, "max_depth": 1.0}


def missing_scales(settings: dict, args) -> list[str]:
    """The scales `settings` lacks (D only where the normals are fitted); with --auto-scales every
    scale, those of a --params file dropped, and one given on the command line refused."""
    if getattr(args, "auto_scales", False):
        given = [by_name()[n].flag for n in SCALES if getattr(args, n, None) is not None]
        if given:
            raise UsageError(f"--auto-scales chooses {', '.join(given)} from the data: give one or the other")
        for name in SCALES:
            settings.pop(name, None)
    if settings.get("projection_scale") is None and settings.get("error_model") is not None:
        # --error-model applies only at the d it was fitted at (settings.resolve): that d, not the rules'
        from ..settings.error_model import for_compare
        settings["projection_scale"] = for_compare(settings["error_model"]).projection_scale
    fitted = settings.get("normal_source", "reference") not in ("vertical", "core")
    return [n for n in SCALES if settings.get(n) is None and (n != "normal_scale" or fitted)]


def with_stand_ins(settings: dict, names: list[str]) -> dict:
    """`settings` with the missing scales stood in for, to check every other parameter first."""
    return {**settings, **{n: _STAND_IN[n] for n in names}}


def check_all_but_scales(resolve: Callable[[dict, str], object], settings: dict, names: list[str]) -> None:
    """resolve()'s checks of every parameter but the scales still to choose, before any file is
    read (their warnings come once, with the chosen scales)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        resolve(with_stand_ins(settings, names), "compare")


def choose_scales(settings: dict, names: list[str], reference, compared, *, threads: int, say: Callable[[str], None]) -> None:
    """Fills `names` in `settings` from suggest's rules on the two clouds and says what was chosen."""
    from importlib import import_module
    rules = import_module("m3c2kit.analysis.suggest")  # the module: the package names its function suggest
    try:
        with warnings.catch_warnings():  # the rules' trial runs warn about their own trial scales
            warnings.simplefilter("ignore")
            found = rules.suggest(reference, compared, threads=threads)
    except M3C2Error as e:
        raise (UsageError if isinstance(e, UsageError) else M3C2Error)(f"{e}; the scales cannot be chosen from the data: give "
                      f"{', '.join(by_name()[n].flag for n in names)}") from None
    rounded = rules.proposal(found)
    why = {
        "normal_scale": found["normal_rule"],
        "projection_scale": (f"smallest d with median n1, n2 >= {rules.N_TARGET}" if math.isfinite(
            found["projection_scale"]) else f"no d has median n1, n2 >= {rules.N_TARGET}: the largest candidate"),
        "max_depth": "3 x the 99th percentile of |distance| in a first pass, at least d0 / 2",
    }
    for name in names:
        settings[name] = rounded[name] if name == "normal_scale" else float(rounded[name])
    shown = {n: settings[n] if n == "normal_scale" else f"{settings[n]:g}" for n in names}
    say(f"scales chosen from the data by m3c2 suggest's rules ({found['core_points']} sampled core points, point "
        f"spacing {found['spacing']:.4g}): {' '.join(f'{by_name()[n].flag} {shown[n]}' for n in names)}")
    for name in names:
        say(f"  {by_name()[name].flag} {shown[name]}: {why[name]}")
