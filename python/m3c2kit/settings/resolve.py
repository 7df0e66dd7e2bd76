"""From what a user gave (API keywords, command-line options, a params file) to checked values with
every default filled in, and from those to the engine's Params: the one place parameters are
validated in Python (the engine validates again as the last line, m3c2kit.engine)."""
from __future__ import annotations

import difflib
import warnings
from typing import Callable, Iterable, Mapping

from .. import engine
from ..base.errors import M3C2Warning, UsageError
from . import error_model
from .needs import check_effective, inapplicable
from .table import Parameter, by_name, parameters_of

__all__ = ["check_keywords", "resolve", "engine_params", "build_params", "without_inapplicable"]


def check_keywords(given: Iterable[str], valid: Iterable[str], where: str) -> None:
    """A UsageError naming an unknown keyword, its closest valid one and every valid one."""
    valid = sorted(valid)
    for key in given:
        if key in valid:
            continue
        close = difflib.get_close_matches(key, valid, n=1)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        raise UsageError(f"{where}: unknown parameter {key!r}{hint}; valid parameters: {', '.join(valid)}")


def resolve(given: Mapping, command: str = "compare", api: bool = False, check_needs: bool = True) -> dict:
    """Every parameter of `command`: the checked given value (None counts as not given), or its
    default (CloudCompare's with compat='cloudcompare'); then the rules that tie parameters, and
    (`check_needs`) that each given parameter acts in this run (m3c2kit.settings.needs).
    `api`: the keywords of the Python function, which writes nothing (no "output" parameter)."""
    table = parameters_of(command)
    check_keywords(given, (p.name for p in table if not (api and p.scope == "output")), f"{command}()"
                   if api else command)
    compat = _checked(by_name()["compat"], given.get("compat")) if command == "compare" else None
    values = {}
    for p in table:
        raw = given.get(p.name)
        values[p.name] = p.default_for(compat) if raw is None else _checked(p, raw)
    for rule in RULES.get(command, ()):
        rule(values, given)
    if check_needs:  # last: the values it looks at are final (the depth search and LOD the rules imply)
        check_effective(table, values, given)
    return values


def without_inapplicable(given: Mapping, keep: Iterable[str], command: str = "compare") -> dict:
    """`given` without the parameters that would change nothing in its run, but those in `keep`
    (which resolve then refuses): a CloudCompare params file holds a whole dialog, some of whose
    values the command line's options make moot (NormalScale under --normal-source vertical)."""
    moot = inapplicable(parameters_of(command), resolve(given, command, check_needs=False))
    return {k: v for k, v in given.items() if k not in moot or k in keep}


def _checked(p: Parameter, value):
    return None if value is None else p.kind(p.flag, value)


def engine_params(values: Mapping, command: str = "compare", read_points: Callable | None = None,
                  core_points=None, scan_positions=None) -> engine.Params:
    """The engine's Params for resolved `values`: an orientation FILE is read with read_points,
    ``--orient barycentre`` takes the mean of `core_points` (an array, a callable giving chunks,
    or m3c2kit.settings.orientation.LATER) and ``sensor`` the `scan_positions`."""
    fields = {}
    for p in parameters_of(command):
        if p.engine is not None:
            fields.update(p.engine.to_engine(values[p.name], read_points=read_points, core_points=core_points,
                                             scan_positions=scan_positions))
    return engine.make_params(fields)


def build_params(command: str = "compare", read_points: Callable | None = None, **keywords) -> engine.Params:
    """The engine's Params for a command's keywords (resolve, then engine_params)."""
    return engine_params(resolve(keywords, command, api=True), command, read_points)


def _depth_search(values: dict, given: Mapping) -> None:
    # Asking for a first pass asks for the two-pass search, unless a search was named.
    if given.get("depth_search") is None and values["first_pass_depth"] is not None:
        values["depth_search"] = "two-pass"
    if values["depth_search"] == "two-pass":
        if values["first_pass_depth"] is None:
            raise UsageError("--depth-search two-pass needs --first-pass-depth")
        if values["max_depth"] is not None and values["first_pass_depth"] > values["max_depth"]:
            raise UsageError(f"--first-pass-depth ({given.get('first_pass_depth')}) must not exceed --max-depth "
                             f"({given.get('max_depth')})")


def _lod(values: dict, given: Mapping) -> None:
    # --bootstrap N and --t-statistic name a LOD statistic too; they must agree with --lod.
    implied, switch = (("bootstrap", "--bootstrap") if values["bootstrap"]
                       else ("auto", "--t-statistic") if values["t_statistic"] else (None, None))
    if given.get("lod") is None:
        values["lod"] = implied or values["lod"]
    elif implied is not None and values["lod"] != implied:
        raise UsageError(f"--lod {values['lod']} contradicts {switch} (which means --lod {implied})")
    if values["lod"] == "bootstrap" and values["bootstrap"] < 2:
        raise UsageError("--lod bootstrap needs --bootstrap N (N >= 2 resamples)")


def _normal_scale_needed(values: dict, given: Mapping) -> None:
    if values["normal_scale"] is None and values.get("normal_source", "reference") not in ("vertical", "core"):
        raise UsageError("--normal-scale (D, a diameter) is required unless --normal-source is vertical or core")


def _required(*names: str, hint: str = ""):
    def rule(values: dict, given: Mapping) -> None:
        for name in names:
            if values[name] is None:
                raise UsageError(f"{by_name()[name].flag} is required{hint}")
    return rule


def _error_model(values: dict, given: Mapping) -> None:
    # The model's sills are the correlated variance of cylinder means at ITS d: another d would
    # average the field over another footprint (docs/algorithm.md, "Spatially correlated errors").
    if values["error_model"] is None:
        return
    model = error_model.for_compare(values["error_model"])
    d, fitted, name = values["projection_scale"], model.projection_scale, error_model.label(values["error_model"])
    if fitted is None:
        warnings.warn(f"{name}: the error model does not record the projection scale it was "
                      f"fitted at; its correlated variance is used as that of d = {d:g}", M3C2Warning, stacklevel=2)
    error_model.check_projection_scale(model, name, d)


#: Rules that tie several parameters, checked after each value is (in the table's order).
RULES = {
    "compare": (_normal_scale_needed, _required("projection_scale", "max_depth",
                                                hint=" (or a --params file that sets it)"), _depth_search, _lod,
                _error_model),
    "normals": (_required("normal_scale"),),
}
