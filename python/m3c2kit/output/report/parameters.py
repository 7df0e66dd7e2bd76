"""The report's parameter table: every parameter of the run with the value in effect (the
user's, or the default the engine used, from the one parameter table m3c2kit.settings), and the
m3c2kit version, so that a figure can be reproduced from the table alone."""
from __future__ import annotations


def effective_parameters(params: dict, *, core_spacing=None, crs_label: str | None = None,
                         units: str | None = None) -> list[tuple[str, object]]:
    """(name, value) rows in the table's order: the run's value, else the default (under
    --compat cloudcompare where it differs); then the CRS, units and the version."""
    from ... import __version__
    from ...settings import parameters_of

    given = {k: v for k, v in params.items() if v is not None}
    if core_spacing is not None:
        given["core_spacing"] = core_spacing
    compat = given.get("compat")
    rows: list[tuple[str, object]] = []
    for p in parameters_of("compare"):
        if p.name in given:
            value = given.pop(p.name)
        else:
            value = p.default_for(compat)
        if p.name == "core_spacing" and value is None:
            value = "none (the core points as given)"
        rows.append((p.name, "none" if value is None else value))
    rows += sorted((k, v) for k, v in given.items() if k not in ("read_points",))
    rows += [("CRS", crs_label or "unknown"), ("units", units or "unknown"), ("m3c2kit version", __version__)]
    return rows
