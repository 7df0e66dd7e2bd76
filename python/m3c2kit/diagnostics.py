"""Data-quality warnings of a run (docs/errors.md, "Legitimate runs that need a warning"): runs that
are legitimate but likely mis-parameterised. Every executor (in memory, tiled, Dask) calls
:func:`warn` once with the whole run's result, so the API sees the warnings as Python warnings
(:class:`~m3c2kit.errors.M3C2Warning`) and the command line prints them on stderr.

The interface is one function, :func:`run_warnings` (result, resolved parameters) -> messages;
a result is anything with the arrays ``status``, ``n1``, ``n2``, ``normal_scale`` and
``roughness`` (a :class:`~m3c2kit.result.Result`, or the columns a tiled merge gathered).
"""
from __future__ import annotations

import warnings
from typing import Mapping

import numpy as np

from .engine import STATUS_NAMES
from .errors import M3C2Warning

__all__ = ["EMPTY_ONE_SIDE_WARNING", "run_warnings", "cylinder_warnings", "normal_accuracy",
           "normal_accuracy_warnings", "warn"]

#: Share of computed core points with an empty cylinder in one cloud only above which a run
#: warns that --max-depth may be shorter than the change.
EMPTY_ONE_SIDE_WARNING = 0.10
#: Statuses of core points whose cylinders were searched (a normal was found).
_SEARCHED = tuple(STATUS_NAMES.index(name) for name in ("ok", "empty_cylinder_reference", "empty_cylinder_compared",
                                                        "too_few_points_for_lod"))


def run_warnings(result, values: Mapping) -> list[str]:
    """Every warning for `result` of a run with the resolved parameters `values`."""
    return (cylinder_warnings(result, values["min_points"], values.get("max_depth"), values.get("projection_scale"))
            + normal_accuracy_warnings(result))


def cylinder_warnings(result, min_points: int, max_depth=None, projection_scale=None) -> list[str]:
    """The median n1 or n2 below `min_points` (a cylinder too thin for the point spacing), and more
    than 10 % of the core points with a searched cylinder having it empty in one cloud only (the
    change reaches beyond --max-depth)."""
    searched = np.isin(result.status, _SEARCHED)
    if not searched.any():
        return []
    lines = []
    n1, n2 = np.asarray(result.n1)[searched], np.asarray(result.n2)[searched]
    m1, m2 = float(np.median(n1)), float(np.median(n2))
    if min(m1, m2) < min_points:
        lines.append(f"the median cylinder holds n1 = {m1:g}, n2 = {m2:g} points, fewer than --min-points "
                     f"{min_points}: the projection scale d = {projection_scale} is small for the point spacing "
                     f"and most LODs are NaN; consider a larger --projection-scale")
    one_side = np.count_nonzero((n1 == 0) != (n2 == 0)) / len(n1)
    if one_side > EMPTY_ONE_SIDE_WARNING:
        lines.append(f"{100 * one_side:.1f}% of the core points with a normal have an empty cylinder in one cloud "
                     f"only: the change may reach beyond --max-depth {max_depth}; consider a larger --max-depth")
    return lines


def normal_accuracy(result) -> dict:
    """Shares of core points with xi = D / sigma(D) > 20 and > 25, and the median predicted
    E_norm = 1.3e5 xi^-3.5 (%), eq. (5) of section 5.1; empty where no roughness was computed."""
    with np.errstate(divide="ignore", invalid="ignore"):
        xi = np.asarray(result.normal_scale) / np.asarray(result.roughness)
    xi = xi[np.isfinite(xi)]
    if xi.size == 0:
        return {}
    return {"xi_over_20": float(np.mean(xi > 20)), "xi_over_25": float(np.mean(xi > 25)),
            "median_e_norm_percent": float(np.median(1.3e5 * xi ** -3.5))}


def normal_accuracy_warnings(result) -> list[str]:
    acc = normal_accuracy(result)
    if acc and acc["xi_over_20"] < 0.5:
        return ["most core points have xi = D / sigma(D) < 20: the normals are affected by roughness "
                "(section 5.1); consider a larger --normal-scale"]
    return []


def warn(result, values: Mapping) -> list[str]:
    """Emits each of run_warnings(result, values) as an M3C2Warning; returns them."""
    messages = run_warnings(result, values)
    for message in messages:
        warnings.warn(message, M3C2Warning, stacklevel=3)
    return messages
