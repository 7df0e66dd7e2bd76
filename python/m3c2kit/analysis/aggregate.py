"""``m3c2 aggregate``: per region of a compare output, the mean change, the volume (grid runs) and
the area of significant change, each with an interval that accounts for spatially correlated
errors (docs/algorithm.md, "Aggregates over a region"; docs/analysis.md, "m3c2 aggregate").

The error of core point i's distance is e_i = c(x_i) + w_i: c a zero-mean field with the error
model's correlated covariance C (analysis.error_model: its components, the nugget excluded) and
w_i independent, of variance u_i^2 = s1^2/n1 + s2^2/n2 (eq. 1's, from the result's sigma and n
columns) plus the model's nugget excess max(0, nugget - mean_u2) when the model records mean_u2
(the correlation shorter than the core spacing that the variogram puts in its nugget: excess over
eq. (1), uncorrelated between core points). So over a region of N core points with a distance

    Var(mean) = (1 / N^2) [ sum_i u_i^2 + sum_i sum_j C(|x_i - x_j|) ]

(Rolstad et al. 2009, eq. 8 generalised to any point layout); the double sum runs in C++
(engine.region_covariance_sum: bins of range/8, exact pairs nearby, within 1e-4 of the exact sum,
tests/cpp/test_region_covariance.cpp). Without a model the double sum is only its diagonal's
uncorrelated part: intervals too narrow when the errors are correlated, which the table says.

Volume (grid runs only, ``compare --grid CELL``): sum_i d_i x CELL^2 over the cells with a
distance (= mean x the area they cover); Var(volume) = CELL^4 N^2 Var(mean). Cells without a
distance (NaN) are left out: the table reports the area covered and the share of the region it is.

Area of significant change: CELL^2 x the core points with |distance| > lod (the count, without a
grid). Its interval is a parametric bootstrap of the significance map: K surveys simulated as the
estimated change plus an error drawn from the model (analysis.random_fields.sample_field, one
field over every region's points, seeded) plus independent N(0, u_i^2), each with the result's
lod; the interval is the K counts' percentile interval and the standard error their standard
deviation. It describes how much the significant area of a repeat survey of the ESTIMATED change
would vary; it is not a confidence interval for the area of true change, which significance
under-counts where the change is close to the LOD (docs/algorithm.md).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .. import engine
from ..base.errors import UsageError
from ..io.polygons import Polygon, region_index
from ..base.quantiles import z_critical
from .error_model import ErrorModel
from .random_fields import sample_field

__all__ = ["TOTAL", "Survey", "RegionAggregate", "AggregateTable", "survey_from_fields", "check_grid", "aggregate",
           "COLUMNS"]

#: the name of the row over every region's core points together
TOTAL = "(total)"
#: the fields a compare output must have (LAS/LAZ: written with --all-fields)
NEEDED = ("distance", "lod", "sigma1", "sigma2", "n1", "n2")
#: the grid check's tolerance: a core point is on the grid when within this share of a cell of a
#: cell centre (LAS/LAZ round coordinates to their scale, far below it)
GRID_TOLERANCE = 1e-3


@dataclass(frozen=True)
class Survey:
    """What aggregate reads of a compare output: plan-view position, distance, lod, u_i^2."""
    xy: np.ndarray
    distance: np.ndarray
    lod: np.ndarray
    u2: np.ndarray
    normal_z: np.ndarray | None = None


def survey_from_fields(xyz: np.ndarray, fields: dict, source) -> Survey:
    """The survey of a compare output's points and fields; a UsageError naming `source` and the
    missing fields."""
    missing = [f for f in NEEDED if f not in fields]
    if missing:
        raise UsageError(f"{source}: no {', '.join(repr(f) for f in missing)} field: aggregate needs a compare output "
                         f"with {', '.join(NEEDED)} (LAS/LAZ keep sigma1, sigma2 only with compare --all-fields)")
    col = {k: np.asarray(fields[k], dtype=np.float64) for k in NEEDED}
    with np.errstate(divide="ignore", invalid="ignore"):
        u2 = col["sigma1"] ** 2 / col["n1"] + col["sigma2"] ** 2 / col["n2"]
    nz = np.asarray(fields["nz"], dtype=np.float64) if "nz" in fields else None
    return Survey(np.ascontiguousarray(np.asarray(xyz, dtype=np.float64)[:, :2]), col["distance"], col["lod"], u2, nz)


def check_grid(xy: np.ndarray, cell: float, source) -> None:
    """A UsageError naming `source` unless the core points are centres of distinct cells of one
    grid of side `cell`, and some two are one cell apart (else the grid is coarser than `cell`)."""
    if len(xy) == 0:
        return
    with np.errstate(over="ignore", invalid="ignore"):
        r = (xy - xy[0]) / cell
    if not np.abs(r).max() < 2.0 ** 52:  # cell indices beyond exact integers (a cell of 1e-300 overflowed)
        raise UsageError(f"{source}: --cell-size {cell:g} is too small for the core points' extent: their cell "
                         f"indices exceed 2**52; --cell-size must be the --grid CELL of the compare run that wrote it")
    k = np.round(r)
    off = np.abs(r - k).max(axis=1)
    worst = int(np.argmax(off))
    if off[worst] > GRID_TOLERANCE:
        raise UsageError(f"{source}: the core points are not on a grid of cell {cell:g}: ({xy[worst, 0]:.10g}, "
                         f"{xy[worst, 1]:.10g}) is {off[worst] * cell:.3g} off the cell centres of the first core "
                         f"point's grid; --cell-size must be the --grid CELL of the compare run that wrote it")
    k = k.astype(np.int64)
    key = np.unique(k, axis=0, return_counts=True)
    if (key[1] > 1).any():
        raise UsageError(f"{source}: several core points in one cell of side {cell:g}: not the core points of a "
                         f"compare --grid {cell:g} run")
    steps = []
    for a, b in ((0, 1), (1, 0)):  # along x within a row, then along y within a column
        order = np.lexsort((k[:, a], k[:, b]))
        ka, kb = k[order, a], k[order, b]
        same = kb[1:] == kb[:-1]
        if same.any():
            steps.append(int(np.diff(ka)[same].min()))
    if steps and min(steps) > 1:
        raise UsageError(f"{source}: no two core points are closer than {min(steps)} cells of {cell:g}: their grid is "
                         f"coarser than --cell-size {cell:g} (--grid {min(steps) * cell:g}?)")


@dataclass
class RegionAggregate:
    """One row of the table (None: not defined for this run, the notes say why)."""
    region: str
    core_points: int = 0
    with_distance: int = 0
    mean: float = math.nan
    mean_se: float = math.nan
    mean_low: float = math.nan
    mean_high: float = math.nan
    se_uncorrelated: float = math.nan
    se_correlated: float | None = None
    volume: float | None = None
    volume_se: float | None = None
    volume_low: float | None = None
    volume_high: float | None = None
    covered_area: float | None = None
    region_area: float | None = None
    covered_share: float | None = None
    significant: int = 0
    significant_se: float | None = None
    significant_low: float | None = None
    significant_high: float | None = None
    significant_area: float | None = None
    significant_area_se: float | None = None
    significant_area_low: float | None = None
    significant_area_high: float | None = None


#: the table's columns in order
COLUMNS = tuple(RegionAggregate.__dataclass_fields__)


@dataclass
class AggregateTable:
    rows: list[RegionAggregate]
    confidence: float
    cell_size: float | None
    error_model: bool
    simulations: int
    seed: int
    notes: list[str] = field(default_factory=list)


def _interval(value: float, se: float, z: float) -> tuple[float, float]:
    return value - z * se, value + z * se


def _nugget_excess(model: ErrorModel | None) -> float:
    mean_u2 = getattr(model, "mean_u2", None) if model is not None else None
    return max(0.0, model.nugget - mean_u2) if mean_u2 is not None else 0.0


def _significance_counts(survey: Survey, masks: np.ndarray, usable: np.ndarray, model: ErrorModel | None,
                         simulations: int, seed: int, extra_u2: float) -> np.ndarray:
    """(simulations, regions) counts of |change + simulated error| > lod (module docstring)."""
    pts = np.flatnonzero(usable & np.isfinite(survey.lod) & masks.any(axis=0))
    out = np.zeros((simulations, len(masks)), dtype=np.int64)
    if len(pts) == 0:
        return out
    xy, d, lod = survey.xy[pts], survey.distance[pts], survey.lod[pts]
    sd = np.sqrt(survey.u2[pts] + extra_u2)
    sub = masks[:, pts]
    correlated = model is not None and any(c.sill > 0 for c in model.components)
    for k in range(simulations):
        draw = int(np.random.SeedSequence([seed, k]).generate_state(1)[0])
        rng = np.random.default_rng([seed, k, 1])
        err = rng.standard_normal(len(pts)) * sd
        if correlated:
            err += sample_field(xy, model, draw)
        sig = np.abs(d + err) > lod
        out[k] = sub @ sig.astype(np.int64)
    return out


def aggregate(survey: Survey, polygons: list[Polygon], *, model: ErrorModel | None = None, confidence: float = 0.95,
              cell: float | None = None, simulations: int = 200, seed: int = 0, threads: int = 0,
              source="the result") -> AggregateTable:
    """The table of :mod:`m3c2kit.analysis.aggregate`: a row per polygon, then TOTAL (their union)."""
    names = [p.name for p in polygons]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise UsageError(f"regions: the names {', '.join(map(repr, dup))} are used more than once: name each region "
                         f"once (a feature's property 'name' or 'id')")
    if TOTAL in names:
        raise UsageError(f"regions: {TOTAL!r} is the name of the total row: rename that region")
    if cell is not None:
        check_grid(survey.xy, cell, source)
    z = z_critical(confidence)
    n = len(survey.xy)
    masks = np.zeros((len(polygons) + 1, n), dtype=bool)
    for r, poly in enumerate(polygons):
        masks[r] = region_index(survey.xy, [poly]) == 0
    masks[-1] = masks[:-1].any(axis=0)
    extra_u2 = _nugget_excess(model)
    has_d = np.isfinite(survey.distance)
    usable = has_d & np.isfinite(survey.u2)
    table = AggregateTable([], confidence, cell, model is not None, simulations, seed)
    dropped = int((has_d & ~usable & masks[-1]).sum())
    if dropped:
        table.notes.append(f"{dropped} core points with a distance but no sigma1/sigma2/n1/n2 (u_i^2 unknown) are "
                           "left out of every figure")
    counts = _significance_counts(survey, masks, usable, model, simulations, seed, extra_u2) if simulations else None
    cell_area = None if cell is None else cell * cell
    for r in range(len(masks)):
        m = masks[r] & usable
        row = RegionAggregate(TOTAL if r == len(polygons) else polygons[r].name, core_points=int(masks[r].sum()),
                              with_distance=int(m.sum()))
        N = row.with_distance
        sig = int((np.abs(survey.distance[m]) > survey.lod[m]).sum())
        row.significant = sig
        if N:
            row.mean = float(np.mean(survey.distance[m]))
            sum_u2 = float(np.sum(survey.u2[m])) + N * extra_u2
            row.se_uncorrelated = math.sqrt(sum_u2) / N
            var = sum_u2
            if model is not None:
                s, _ = engine.region_covariance_sum(survey.xy[m], model.components, threads=threads)
                row.se_correlated = math.sqrt(max(s, 0.0)) / N
                var += s
            row.mean_se = math.sqrt(var) / N
            row.mean_low, row.mean_high = _interval(row.mean, row.mean_se, z)
        if counts is not None:
            sims = counts[:, r].astype(np.float64)
            row.significant_se = float(np.std(sims, ddof=1)) if simulations > 1 else math.nan
            row.significant_low, row.significant_high = (float(v) for v in np.quantile(
                sims, [0.5 - confidence / 2, 0.5 + confidence / 2]))
        if cell_area is not None:
            row.covered_area = N * cell_area
            if r < len(polygons):
                row.region_area = polygons[r].area()
                row.covered_share = row.covered_area / row.region_area if row.region_area > 0 else math.nan
            if N:
                row.volume = row.mean * N * cell_area
                row.volume_se = row.mean_se * N * cell_area
                row.volume_low, row.volume_high = _interval(row.volume, row.volume_se, z)
            row.significant_area = sig * cell_area
            if counts is not None:
                row.significant_area_se = row.significant_se * cell_area
                row.significant_area_low = row.significant_low * cell_area
                row.significant_area_high = row.significant_high * cell_area
        table.rows.append(row)
    _notes(table, survey, model, masks[-1] & usable)
    return table


def _notes(table: AggregateTable, survey: Survey, model: ErrorModel | None, used: np.ndarray) -> None:
    pct = f"{100 * table.confidence:g} %"
    if model is None:
        table.notes.append(f"intervals ({pct}, normal theory) from the uncorrelated errors only (no --error-model): "
                           "too narrow when the errors are spatially correlated (Rolstad et al. 2009); fit a model "
                           "with m3c2 variogram")
    else:
        table.notes.append(f"intervals ({pct}, normal theory) include the error model's spatial correlation "
                           "(lags in plan view)")
    if table.cell_size is None:
        table.notes.append("volume and areas: not defined (no --cell-size: they need the core points of a compare "
                           "--grid run and its CELL)")
    else:
        table.notes.append("volume = sum of distance x cell area over the cells with a distance; cells without "
                           "one are left out (covered_area, covered_share)")
        if survey.normal_z is not None and used.any():
            tilt = np.abs(survey.normal_z[used])
            if np.nanmin(tilt) < 1 - 1e-9:
                table.notes.append("normals are not vertical: distances, and so the volume, are along the normals, "
                                   "not vertical (run compare --grid, or --orient +z with vertical normals)")
    if table.simulations:
        table.notes.append(f"significant: core points with |distance| > lod; its interval is the {pct} percentile "
                           f"interval of {table.simulations} simulated surveys of the estimated change "
                           f"(parametric bootstrap, seed {table.seed}): the spread of a repeat survey's significant "
                           "area, not an interval for the area of true change")
    else:
        table.notes.append("significant: core points with |distance| > lod; no interval (--simulations 0)")
