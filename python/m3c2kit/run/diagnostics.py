"""Data-quality warnings of a run (docs/errors.md, "Legitimate runs that need a warning"): runs that
are legitimate but likely mis-parameterised. Every executor (in memory, tiled, Dask) calls
:func:`warn` once with the whole run's result, so the API sees the warnings as Python warnings
(:class:`~m3c2kit.base.errors.M3C2Warning`) and the command line prints them on stderr.

The interface is one function, :func:`run_warnings` (result, resolved parameters) -> messages;
a result is anything with the arrays ``status``, ``n1``, ``n2``, ``normal_scale`` and
``roughness`` (a :class:`~m3c2kit.engine.result.Result`, or the columns a tiled merge gathered,
m3c2kit.run.merge.Evidence, whose ``rows_at`` reads back the diagnosed rows' core points and normals).
"""
from __future__ import annotations

import warnings
from typing import Mapping

import numpy as np

from . import quality
from ..engine.result import EMPTY_CYLINDER, SEARCHED, status_in
from ..base.errors import M3C2Warning

__all__ = ["run_warnings", "cylinder_warnings", "normal_accuracy",
           "normal_accuracy_warnings", "warn"]

#: Statuses of core points whose cylinders were searched (a normal was found).


def run_warnings(result, values: Mapping, reference=None, compared=None) -> list[str]:
    """Every warning for `result` of a run with the resolved parameters `values`; the clouds let
    m3c2kit.run.quality tell why cylinders are empty: xyz arrays where the run holds them, or a
    tiled run's streamed clouds (m3c2kit.run.cylinder_points.StreamedCloud), the same diagnosis."""
    lines = cylinder_warnings(result, values["min_points"], values.get("max_depth"), values.get("projection_scale"))
    failed = quality.normal_failure_message(result, values.get("normal_scale") or 0.0)
    lines += [failed] if failed else []
    if reference is not None:
        lines += quality.scale_messages(values.get("normal_scale"), values.get("projection_scale"),
                                        values.get("max_depth"), quality.extent_of(reference))
    if reference is not None and compared is not None:
        lines += _empty_cylinder_warnings(result, values, reference, compared)
    return lines + normal_accuracy_warnings(result)


def _empty_cylinder_warnings(result, values: Mapping, reference, compared) -> list[str]:
    """m3c2kit.run.quality's diagnosis of empty cylinders: no overlap (no depth helps), or a depth too
    short (and the depth that reaches)."""
    status = np.asarray(result.status)
    with_normal = np.count_nonzero(status_in(status, SEARCHED))
    empty = np.count_nonzero(status_in(status, tuple(EMPTY_CYLINDER.values())))
    if not with_normal or empty / with_normal <= quality.EMPTY_SHARE:
        return []
    diagnoses = quality.cylinder_diagnosis(reference, compared, result, projection_scale=values["projection_scale"],
                                           max_depth=values["max_depth"], threads=values.get("threads", 0),
                                           at_most=quality.WARNING_SAMPLE)
    return quality.cylinder_messages(diagnoses, values["max_depth"])


def cylinder_warnings(result, min_points: int, max_depth=None, projection_scale=None) -> list[str]:
    """The median n1 or n2 below `min_points` (a cylinder too thin for the point spacing). Empty
    cylinders in one cloud are m3c2kit.run.quality's to diagnose (no overlap, or a depth too short)."""
    searched = status_in(result.status, SEARCHED)
    if not searched.any():
        return []
    lines = []
    n1, n2 = np.asarray(result.n1)[searched], np.asarray(result.n2)[searched]
    m1, m2 = float(np.median(n1)), float(np.median(n2))
    if min(m1, m2) < min_points:
        lines.append(f"the median cylinder holds n1 = {m1:g}, n2 = {m2:g} points, fewer than --min-points "
                     f"{min_points}: the projection scale d = {projection_scale} is small for the point spacing "
                     f"and most LODs are NaN; consider a larger --projection-scale")
    return lines


def normal_accuracy(result) -> dict:
    """Shares of core points with xi = D / sigma(D) > 20 and > 25, and the median predicted
    E_norm = 1.3e5 xi^-3.5 (%), eq. (5) of section 5.1, over the core points with a roughness
    (`core_points` of them, `planar` with sigma(D) = 0: xi = inf counts as > 25, E_norm 0);
    {} where none has one."""
    roughness, scale = np.asarray(result.roughness), np.asarray(result.normal_scale)
    with np.errstate(divide="ignore", invalid="ignore"):
        xi = scale / roughness
    xi = xi[np.isfinite(roughness) & np.isfinite(scale)]
    if xi.size == 0:
        return {}
    with np.errstate(divide="ignore"):
        e_norm = 1.3e5 * xi ** -3.5  # 0 where xi = inf
    return {"xi_over_20": float(np.mean(xi > 20)), "xi_over_25": float(np.mean(xi > 25)),
            "median_e_norm_percent": float(np.median(e_norm)), "core_points": int(xi.size),
            "planar": int(np.sum(np.isinf(xi)))}


def normal_accuracy_warnings(result) -> list[str]:
    acc = normal_accuracy(result)
    if acc and acc["xi_over_20"] < 0.5:
        return ["most core points have xi = D / sigma(D) < 20: the normals are affected by roughness "
                "(section 5.1); consider a larger --normal-scale"]
    return []


def warn(result, values: Mapping, reference=None, compared=None, *, stacklevel: int = 3) -> list[str]:
    """Emits each of run_warnings(...) as an M3C2Warning, naming the line `stacklevel` frames up
    (3: the caller of warn's caller); returns them."""
    messages = run_warnings(result, values, reference, compared)
    for message in messages:
        warnings.warn(message, M3C2Warning, stacklevel=stacklevel)
    return messages
