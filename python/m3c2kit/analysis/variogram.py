"""``m3c2 variogram``: the empirical variogram of the M3C2 distance over stable core points of a
compare output, and its fit by nugget + spherical + exponential (docs/analysis.md, "m3c2
variogram"; Rolstad et al. 2009; Hugonnet et al. 2022, xDEM). The pair sums run in C++
(include/m3c2/variogram.hpp: sampled pairs, seeded, the same bits for any thread count); the fit
(scipy.optimize.least_squares) and the file glue are here.

Lags are 3D distances between core points by default: on cliffs and overhangs the surface is
vertical and plan-view distances would put points metres apart in height at lag 0 (``2d``
measures in plan view, as DEM differencing does).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import engine
from ..base.errors import UsageError
from .error_model import Component, ErrorModel

__all__ = ["Empirical", "Fitted", "empirical_variogram", "default_edges", "fit_model", "fit_error_model",
           "stable_mask", "result_column", "eq1_variance", "plot_variogram", "FIT_FAMILIES", "RANGE_SHARE_WARNED"]

#: the model families tried, the two-component one first
FIT_FAMILIES = (("spherical", "exponential"), ("spherical",), ("exponential",))
#: a two-component fit is degenerate when a partial sill is below this share of their sum ...
_MIN_SHARE = 0.05
#: ... when its ranges are within this factor of each other, or when it improves the weighted
#: misfit of the best single component by less than this fraction.
_SAME_RANGE = 1.5
_MIN_GAIN = 0.10
#: a fitted range over this share of the stable points' largest extent is warned about: the sill
#: then rests on fewer than about 16 independent patches (docs/algorithm.md, "finite area")
RANGE_SHARE_WARNED = 0.25


@dataclass(frozen=True)
class Empirical:
    """Per lag bin (non-empty bins only): mean lag, semivariance 0.5 mean((d_i - d_j)^2), pairs."""

    lag: np.ndarray
    semivariance: np.ndarray
    pairs: np.ndarray
    edges: np.ndarray


def _spacing(points: np.ndarray, lag_distance: str) -> tuple[float, float]:
    """(typical spacing between points, largest extent): sqrt(area / n) over the bounding box's
    two largest extents (a wall's plane for cliffs, the plan for terrain)."""
    extent = np.ptp(points[:, :2] if lag_distance == "2d" else points, axis=0)
    big = np.sort(extent)[::-1]
    area = max(big[0] * (big[1] if len(big) > 1 else big[0]), 1e-300)
    return math.sqrt(area / max(len(points), 1)), float(big[0])


def default_edges(points: np.ndarray, *, bins: int = 20, max_lag: float | None = None,
                  lag_distance: str = "3d") -> np.ndarray:
    """Lag-bin edges: 0, then `bins` log-spaced edges from the typical point spacing to `max_lag`
    (default half the largest extent)."""
    spacing, extent = _spacing(points, lag_distance)
    top = 0.5 * extent if max_lag is None else float(max_lag)
    if not top > spacing:
        raise UsageError(f"--max-lag {top:g} must exceed the core points' typical spacing ({spacing:g})")
    return np.r_[0.0, np.geomspace(spacing, top, bins)]


def empirical_variogram(points: np.ndarray, values: np.ndarray, edges=None, *, seed: int = 0, bins: int = 20,
                        max_lag: float | None = None, lag_distance: str = "3d", far_pairs: int = 10_000_000,
                        centres: int = 20_000, max_neighbours: int = 512, threads: int = 0) -> Empirical:
    """The empirical variogram of `values` at `points` (finite values only) over sampled pairs.
    The neighbourhood radius covers the short lags random pairs miss: where fewer than about
    20000 random pairs would fall in a disc of that radius, and at least 8 spacings."""
    points = np.ascontiguousarray(points, dtype=np.float64)
    values = np.ascontiguousarray(values, dtype=np.float64)
    if len(points) < 2:
        raise UsageError(f"the variogram needs at least 2 core points with a distance, got {len(points)}")
    edges = default_edges(points, bins=bins, max_lag=max_lag, lag_distance=lag_distance) if edges is None \
        else np.asarray(edges, dtype=np.float64)
    spacing, extent = _spacing(points, lag_distance)
    area = spacing * spacing * len(points)
    near = max(8.0 * spacing, math.sqrt(20000.0 * area / (math.pi * max(far_pairs, 1))))
    near = min(near, float(edges[-1]))
    sums = engine.variogram_pairs(points, values, edges, seed=seed, centres=centres, near_radius=near,
                                  max_neighbours=max_neighbours, far_pairs=far_pairs, planar=lag_distance == "2d",
                                  threads=threads)
    pairs = np.asarray(sums["pairs"], dtype=np.int64)
    keep = pairs > 0
    return Empirical(np.asarray(sums["lag_sum"])[keep] / pairs[keep],
                     np.asarray(sums["half_sq_sum"])[keep] / pairs[keep], pairs[keep], edges)


def _model(kinds, x) -> ErrorModel:
    comps = tuple(Component(k, float(x[1 + 2 * i]), float(x[2 + 2 * i])) for i, k in enumerate(kinds))
    return ErrorModel(float(x[0]), comps)


def _fit_family(kinds, emp: Empirical, seed: int):
    from scipy.optimize import least_squares

    h, g, w = emp.lag, emp.semivariance, np.sqrt(emp.pairs.astype(np.float64))
    top = float(np.max(g))
    # a range beyond the largest lag is not identified by the lags: bounded there
    lo_r, hi_r = max(float(h[0]) * 0.5, 1e-12), float(emp.edges[-1])
    lower = [0.0] + [0.0, lo_r] * len(kinds)
    upper = [top * 2] + [top * 2, hi_r] * len(kinds)

    def residual(x):
        return w * (_model(kinds, x).variogram(h) - g)

    best = None
    rng = np.random.default_rng(seed)
    # several starts: ranges spread over the lags (the two components apart), sills sharing the plateau
    starts = []
    for q in (0.1, 0.3, 0.6):
        r0 = float(np.quantile(h, q))
        if len(kinds) == 1:
            starts.append([0.1 * top, 0.9 * top, r0])
        else:
            starts.append([0.1 * top, 0.5 * top, r0 * 0.3, 0.4 * top, r0 * 3])
    for _ in range(3):
        starts.append([rng.uniform(0, 0.3) * top] + [v for _ in kinds for v in
                                                     (rng.uniform(0.1, 1) * top, math.exp(rng.uniform(
                                                         math.log(lo_r), math.log(float(emp.edges[-1])))))])
    for x0 in starts:
        x0 = np.clip(x0, lower, upper)
        r = least_squares(residual, x0, bounds=(lower, upper), x_scale="jac")
        cost = float(np.sum(r.fun ** 2))
        if best is None or cost < best[0]:
            best = (cost, r.x)
    return best[0], _model(kinds, best[1])


def fit_model(emp: Empirical, *, seed: int = 0) -> tuple[ErrorModel, str]:
    """nugget + spherical + exponential fitted to `emp` by least squares weighted by each bin's
    pair count, parameters >= 0, several starts; a single component (the better of spherical and
    exponential) when the two-component fit is degenerate (a partial sill under 5 % of the total,
    a range at the largest lag, ranges within a factor 1.5, or under 10 % less misfit than one
    component). Returns the model
    and a sentence saying which was kept and why."""
    if len(emp.lag) < 4:
        raise UsageError(f"only {len(emp.lag)} lag bins have pairs: too few to fit a variogram (more core points, "
                         "or other --bins / --max-lag)")
    fits = {kinds: _fit_family(kinds, emp, seed) for kinds in FIT_FAMILIES}
    single = min(FIT_FAMILIES[1:], key=lambda k: fits[k][0])
    cost2, two = fits[FIT_FAMILIES[0]]
    sills = [c.sill for c in two.components]
    total = sum(sills)
    reason = None
    if total <= 0 or min(sills) < _MIN_SHARE * total:
        reason = "a partial sill under 5 % of the total"
    elif max(c.range for c in two.components) >= 0.99 * float(emp.edges[-1]):
        reason = "a range at the largest lag (not identified)"
    elif max(c.range for c in two.components) < _SAME_RANGE * min(c.range for c in two.components):
        reason = "ranges within a factor 1.5"
    elif cost2 > (1.0 - _MIN_GAIN) * fits[single][0]:
        reason = "under 10 % less weighted misfit than one component"
    if reason is None:
        return two, "nugget + spherical + exponential"
    return fits[single][1], f"nugget + {single[0]} (the two-component fit was degenerate: {reason})"


@dataclass(frozen=True)
class Fitted:
    """What :func:`fit_error_model` found: the model (with mean_u2), the empirical variogram, the
    sentence saying which family was kept, the stable core points used and the warnings to give."""

    model: ErrorModel
    empirical: Empirical
    kept: str
    used: int
    warnings: tuple[str, ...]


def fit_error_model(points: np.ndarray, distance: np.ndarray, u2: np.ndarray, *, seed: int = 0, bins: int = 20,
                    max_lag: float | None = None, lag_distance: str = "3d", far_pairs: int = 10_000_000,
                    threads: int = 0) -> Fitted:
    """The error model of stable core points at `points` with their `distance` and eq. (1)'s
    variance `u2` = s1^2/n1 + s2^2/n2 (:func:`eq1_variance`): the variogram over the points
    where both are finite, its fit, and mean_u2 over the SAME points, so that the model's
    excess_variance is total sill - mean(u2) of one population (docs/algorithm.md)."""
    points = np.asarray(points, dtype=np.float64)
    distance, u2 = np.asarray(distance, dtype=np.float64), np.asarray(u2, dtype=np.float64)
    ok = np.isfinite(distance) & np.isfinite(u2)
    if ok.sum() < 2:
        raise UsageError(f"{int(ok.sum())} stable core points with a distance and a LOD: too few for a variogram")
    emp = empirical_variogram(points[ok], distance[ok], seed=seed, bins=bins, max_lag=max_lag,
                              lag_distance=lag_distance, far_pairs=far_pairs, threads=threads)
    model, kept = fit_model(emp, seed=seed)
    from dataclasses import replace
    model = replace(model, lag_distance=lag_distance, mean_u2=float(np.mean(u2[ok])),
                    empirical=tuple((float(a), float(b), int(n)) for a, b, n in
                                    zip(emp.lag, emp.semivariance, emp.pairs)))
    return Fitted(model, emp, kept, int(ok.sum()), _finite_area_warnings(model, points[ok], lag_distance, emp))


def _finite_area_warnings(model: ErrorModel, points: np.ndarray, lag_distance: str, emp: Empirical) -> tuple[str, ...]:
    # The semivariance at each lag is unbiased whatever the area; the sill is not when the
    # plateau is not reached inside the lags, and it is noisy when few range-sized patches fit
    # in the area (docs/algorithm.md, "Spatially correlated errors", finite area).
    _, extent = _spacing(points, lag_distance)
    out = []
    longest = max((c.range for c in model.components if c.sill > 0), default=0.0)
    if longest > RANGE_SHARE_WARNED * extent:
        patches = (extent / longest) ** 2
        out.append(f"the fitted range {longest:.4g} is over {RANGE_SHARE_WARNED:g} of the stable core points' extent "
                   f"({extent:.4g}): the sill rests on about {patches:.0f} independent patches and is uncertain, and "
                   f"if the true range exceeds the largest lag ({float(emp.edges[-1]):.4g}) the sill, hence the LOD, "
                   "is under-estimated; fit on a larger stable area")
    return tuple(out)


def result_column(cloud, name: str) -> np.ndarray | None:
    """The column `name` of a compare output (m3c2kit's name, or CloudCompare's or PDAL's, with
    spaces or underscores: io.fields), float64; None when the result lacks it."""
    from ..io.fields import output_name
    for names in ("m3c2", "cloudcompare", "pdal"):
        for spaces in (True, False):
            key = output_name(name, names, spaces=spaces)
            if key in cloud.fields:
                return np.asarray(cloud.fields[key], dtype=np.float64)
    return None


#: Without stable areas, a result whose core points are significant beyond this share holds change
#: that the variogram would take for error (a 95 % LOD flags about 5 % of unchanged core points).
CHANGED_SHARE_WARNED = 0.10


def change_taken_for_error(cloud) -> str | None:
    """A warning when the variogram, fitted on every core point (no stable areas given), would fit
    the change itself as if it were error: more than CHANGED_SHARE_WARNED of the core points with
    a distance are significant (issue 42)."""
    significant, distance = result_column(cloud, "significant"), result_column(cloud, "distance")
    if significant is None or distance is None:
        return None
    judged = np.isfinite(significant) & np.isfinite(distance)
    share = float(np.mean(significant[judged] > 0)) if judged.any() else 0.0
    if share <= CHANGED_SHARE_WARNED:
        return None
    return (f"{100 * share:.1f} % of the core points are significant at their LOD and every core point is taken "
            f"as stable: where that is change, not correlated error, the variogram fits the change as if it were "
            f"error (its sill and range, not the errors'); give the stable areas with --stable POLYGONS or "
            f"--stable-field NAME=VALUE")


def eq1_variance(cloud) -> np.ndarray:
    """u^2 = sigma1^2/n1 + sigma2^2/n2 per core point of a compare output (eq. (1)'s variance
    without the correlated part); UsageError naming the file when a column is missing."""
    cols = {k: result_column(cloud, k) for k in ("sigma1", "sigma2", "n1", "n2")}
    missing = [k for k, v in cols.items() if v is None]
    if missing:
        raise UsageError(f"{cloud.path or 'the result'}: no {', '.join(missing)} column(s): the error model needs "
                         "each core point's s1^2/n1 + s2^2/n2; write the compare output as text, PLY or NPY, or LAS/LAZ "
                         "with --all-fields")
    with np.errstate(invalid="ignore", divide="ignore"):
        return cols["sigma1"] ** 2 / cols["n1"] + cols["sigma2"] ** 2 / cols["n2"]


def stable_mask(cloud, *, polygons=None, field: str | None = None) -> np.ndarray:
    """Which core points of the result `cloud` are stable: inside `polygons` (a file,
    m3c2kit.io.polygons), where `field` ("NAME=VALUE") equals VALUE, or every point."""
    if polygons is not None:
        from ..io.polygons import read_regions_for, region_index, require_points_inside
        regions = read_regions_for(polygons, cloud, "--stable")
        xy = np.ascontiguousarray(cloud.xyz[:, :2])
        index = region_index(xy, regions)
        require_points_inside(np.bincount(index[index >= 0], minlength=len(regions)), xy, regions, polygons,
                              cloud.path or "the result")
        return index >= 0
    if field is None:
        return np.ones(len(cloud), dtype=bool)
    name, sep, value = field.partition("=")
    if not sep or not name:
        raise UsageError(f"--stable-field {field!r}: expected NAME=VALUE (e.g. classification=2)")
    if name not in cloud.fields:
        raise UsageError(f"--stable-field: {cloud.path or 'the result'} has no field {name!r} "
                         f"(its fields: {', '.join(sorted(cloud.fields)) or 'none'})")
    try:
        wanted = float(value)
    except ValueError:
        raise UsageError(f"--stable-field {field!r}: VALUE must be a number") from None
    if not np.isfinite(wanted):  # hostile round: NaN equals no value, so no point was ever stable
        raise UsageError(f"--stable-field {field!r}: VALUE must be a finite number (a field equals no NaN or inf)")
    return np.asarray(cloud.fields[name], dtype=np.float64) == wanted


def plot_variogram(emp: Empirical, model: ErrorModel, title: str = ""):
    """The figure of the empirical variogram (points, area by pair count) and the fitted model,
    log lag axis (the caller saves and closes it)."""
    from .common import pyplot

    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    size = 10 + 60 * np.sqrt(emp.pairs / emp.pairs.max())
    ax.scatter(emp.lag, emp.semivariance, s=size, color="#333333", label="empirical (area: pairs)", zorder=3)
    h = np.geomspace(max(float(emp.lag.min()), 1e-9), float(emp.edges[-1]), 300)
    ax.plot(h, model.variogram(h), color="#c0392b", label="fitted model")
    ax.axhline(model.nugget, color="#7f8c8d", lw=0.8, ls=":", label=f"nugget {model.nugget:.3g}")
    for c in model.components:
        ax.axvline(c.range, color="#2980b9", lw=0.8, ls="--")
        ax.text(c.range, 0.02, f" {c.kind} {c.range:.3g}", transform=ax.get_xaxis_transform(), fontsize=8,
                color="#2980b9", rotation=90, va="bottom")
    ax.set_xscale("log")
    ax.set_ylim(bottom=0)
    ax.set_xlabel(f"lag ({model.lag_distance})")
    ax.set_ylabel("semivariance of the distance")
    ax.set_title(title or "variogram of the M3C2 distance over stable core points")
    ax.legend(fontsize=8, loc="lower right")
    fig.tight_layout()
    return fig
