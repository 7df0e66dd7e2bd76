"""The report's parameter table: every parameter of the run with the value in effect (the
user's, or the default the engine used), and the m3c2kit version, so that a figure can be
reproduced from the table alone."""
from __future__ import annotations

import inspect

#: Parameters with a name a reader knows, in the table's order (the rest follow, sorted).
ORDER = ("normal_scale", "projection_scale", "max_depth", "core_spacing", "registration_error", "confidence",
         "min_points", "normal_source", "orient", "median", "lod", "t_statistic", "bootstrap", "seed",
         "depth_search", "first_pass_depth", "positive_search_only", "normal_subsample", "variance",
         "scale_selection", "min_points_normal", "compat")


def effective_parameters(params: dict, *, core_spacing=None, crs_label: str | None = None,
                         units: str | None = None) -> list[tuple[str, object]]:
    """(name, value) rows: the run's parameters over the engine's defaults (api.build_params and
    the --compat mode's), then the CRS, units and the version."""
    from .. import __version__, api

    signature = inspect.signature(api.build_params)
    values = {k: p.default for k, p in signature.parameters.items()
              if p.default is not inspect.Parameter.empty and k != "read_points"}
    mode = api.CLOUDCOMPARE_DEFAULTS if params.get("compat") == "cloudcompare" else api.DEFAULTS
    for k, v in mode.items():
        if values.get(k) is None:
            values[k] = v
    values.update({k: v for k, v in params.items() if v is not None})
    if core_spacing is not None:
        values["core_spacing"] = core_spacing
    values.setdefault("core_spacing", "none (the core points as given)")
    rows = [(k, values.pop(k)) for k in ORDER if k in values]
    rows += sorted(values.items())
    rows += [("CRS", crs_label or "unknown"), ("units", units or "unknown"), ("m3c2kit version", __version__)]
    return rows
