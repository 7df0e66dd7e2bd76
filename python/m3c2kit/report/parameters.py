"""The report's parameter table: every parameter of the run with the value in effect (the
user's, or the default the engine used), and the m3c2kit version, so that a figure can be
reproduced from the table alone."""
from __future__ import annotations

#: Parameters with a name a reader knows, in the table's order (the rest follow, sorted).
ORDER = ("normal_scale", "projection_scale", "max_depth", "core_spacing", "registration_error", "confidence",
         "min_points", "normal_source", "orient", "median", "lod", "t_statistic", "bootstrap", "seed",
         "depth_search", "first_pass_depth", "positive_search_only", "normal_subsample", "variance",
         "scale_selection", "min_points_normal", "compat")


def effective_parameters(params: dict, *, core_spacing=None, crs_label: str | None = None,
                         units: str | None = None) -> list[tuple[str, object]]:
    """(name, value) rows: the run's parameters over the defaults of the parameter table (the
    --compat mode's where it is asked), then the CRS, units and the version."""
    from .. import __version__
    from ..settings import parameters_of

    values = {p.name: p.default_for(params.get("compat")) for p in parameters_of("compare")
              if p.scope in ("engine", "alias")}
    values.update({k: v for k, v in params.items() if v is not None})
    if core_spacing is not None:
        values["core_spacing"] = core_spacing
    values.setdefault("core_spacing", "none (the core points as given)")
    rows = [(k, values.pop(k)) for k in ORDER if k in values]
    rows += sorted(values.items())
    rows += [("CRS", crs_label or "unknown"), ("units", units or "unknown"), ("m3c2kit version", __version__)]
    return rows
