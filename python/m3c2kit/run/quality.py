"""What the data-quality warnings say (issue 13): the diagnosis behind each, decided from the
result and, where needed, one more engine run; the wording a scientist can act on.

- :func:`cylinder_diagnosis`: of the core points with an empty cylinder in one cloud, which have
  no point of that cloud along their normal however far the cylinder reaches (the clouds do not
  overlap there: no --max-depth can help), which have points beyond --max-depth (a larger depth
  would find them, and how large), and which have the cloud's surface within the depth but
  between the points of a sparse cloud (a larger --projection-scale would find them). Decided by
  the engine itself: the same core points, normals and cylinder diameter, with a cylinder as long
  as the clouds' extent (where it meets the cloud: the offset of its points' mean along the
  normal); where that finds nothing in a cloud sparse for d (:data:`SPARSE_EXPECTED`), one
  :data:`WIDE_FACTOR` times as wide tells the spacing from the edge of its coverage.
- :func:`normal_failure_message`: more than :data:`NORMAL_FAILURE_SHARE` of the core points
  without a normal, with the likely cause (D is a diameter: a radius given for it halves it).
- :func:`share_text`: shares stated over the core points they describe ("of the N core points
  with a normal"), never over a subset left unnamed.

The emitting module (Python ``warnings``, stderr at the command line) calls these.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..engine.result import EMPTY_CYLINDER, NO_NORMAL, STATUS_NAMES, status_in

__all__ = ["CylinderDiagnosis", "cylinder_diagnosis", "cylinder_messages", "normal_failure_message",
           "share_text", "NORMAL_FAILURE_SHARE", "EMPTY_SHARE", "WIDE_FACTOR", "SPARSE_EXPECTED", "ADVISED_POINTS",
           "WARNING_SAMPLE"]

#: Share of core points without a normal above which the run warns.
NORMAL_FAILURE_SHARE = 0.5
#: Share of core points with a normal whose cylinder is empty in one cloud above which the run warns.
EMPTY_SHARE = 0.10
#: The diagnosis's cylinder is this many times as wide as d (16 times the area): it finds a
#: sparse cloud's points where the cylinder of d falls between them.
WIDE_FACTOR = 4.0
#: Mean points per cylinder of d below which a cloud is sparse for it (e^-3: 5 % of the cylinders
#: of a Poisson cloud are empty by chance there): its empty cylinders are the spacing's where the
#: cloud lies within the depth, not a missing overlap. Above it, an empty line is the edge of
#: the cloud's coverage.
SPARSE_EXPECTED = 3.0
#: Points in the median cylinder that the advised --projection-scale aims at (section 3.3: the
#: LOD needs a few points in each cylinder; --min-points is 5 by default, as CloudCompare's).
ADVISED_POINTS = 10
#: Empty cylinders the warnings diagnose at most, evenly spaced in the core points' order: the
#: shares they state are then estimates (a binomial standard error below 1.2 percentage points),
#: said as "about". Diagnosing every empty cylinder of a sparse pair took twice the run itself
#: (issue 19: W1, 19,099 cylinders as long as the clouds' extent).
WARNING_SAMPLE = 2000

_EMPTY = {cloud: STATUS_NAMES.index(name) for cloud, name in EMPTY_CYLINDER.items()}


def share_text(count: int, total: int, of: str, about: bool = False) -> str:
    """``"1,234 of the 5,678 core points with a normal (21.7 %)"``; ``about``: the count is an
    estimate, rounded to 2 significant digits (``"about 1,200 of the ..."``)."""
    pct = 100.0 * count / total if total else 0.0
    if about:
        return f"about {int(float(f'{count:.2g}')):,} of the {total:,} {of} ({pct:.0f} %)"
    return f"{count:,} of the {total:,} {of} ({pct:.1f} %)"


@dataclass
class CylinderDiagnosis:
    """For one cloud (1 reference, 2 compared): core points with a normal whose cylinder was empty
    in that cloud, split into ``no_overlap`` (no point along the normal at any depth),
    ``beyond_depth`` (the cloud met beyond --max-depth), with the depth that reaches 95 % of them
    (``needed_depth``), and ``too_thin`` (the cloud met within --max-depth, but the cylinder of d
    fell between its points), with the projection scale (diameter) whose median cylinder holds
    about :data:`ADVISED_POINTS` of them (``needed_scale``). ``diagnosed``: how many of the
    ``empty`` were diagnosed (an evenly spaced sample, ``cylinder_diagnosis(at_most=...)``); the
    three arrays hold those, and :meth:`estimate` scales a count of them to all."""

    cloud: int
    with_normal: int
    empty: int
    no_overlap: np.ndarray
    beyond_depth: np.ndarray
    needed_depth: float | None
    too_thin: np.ndarray
    needed_scale: float | None
    diagnosed: int | None = None

    @property
    def sampled(self) -> bool:
        return self.diagnosed is not None and self.diagnosed < self.empty

    def estimate(self, kind: np.ndarray) -> int:
        """The number of the empty cylinders of this kind (no_overlap, beyond_depth, too_thin)."""
        return int(round(kind.size * self.empty / self.diagnosed)) if self.sampled else int(kind.size)


def cylinder_diagnosis(reference, compared, result, *, projection_scale: float, max_depth: float, threads: int = 0,
                       at_most: int | None = None) -> list[CylinderDiagnosis]:
    """One :class:`CylinderDiagnosis` per cloud with empty cylinders (see the module docstring);
    `at_most`: diagnose at most that many of each cloud's empty cylinders, evenly spaced in the
    core points' order (the warnings: :data:`WARNING_SAMPLE`), else all. The clouds are xyz arrays,
    or what m3c2kit.run.cylinder_points gives a tiled run (a cloud streamed: its extent, and the
    index of the points in the cylinders asked); `result` has the per-core-point arrays, or
    ``status``, ``n1``, ``n2`` and ``rows_at(idx)`` -> (core points, normals) of those rows."""
    status = np.asarray(result.status)
    with_normal = int(np.count_nonzero(~status_in(status, NO_NORMAL)))
    clouds = {1: _as_cloud(reference), 2: _as_cloud(compared)}
    out = []
    reach = None
    for cloud, code in _EMPTY.items():
        idx = np.flatnonzero(status == code)
        if not idx.size:
            continue
        empty = int(idx.size)
        if at_most is not None and empty > at_most:
            idx = idx[np.unique(np.linspace(0, empty - 1, int(at_most)).round().astype(np.int64))]
        if reach is None:  # once for both clouds
            (lo1, hi1), (lo2, hi2) = clouds[1].bounds(), clouds[2].bounds()
            reach = max(float(np.linalg.norm(np.maximum(hi1, hi2) - np.minimum(lo1, lo2))), 2.0 * float(max_depth))
        core, normals = _rows(result, idx)
        # The cloud is sparse for d when a cylinder of d holds few points on average (its mean
        # count over the core points with a normal): then a wider cylinder is asked too.
        n_run = np.asarray(result.n1 if cloud == 1 else result.n2)[~status_in(status, NO_NORMAL)]
        sparse = bool(np.nanmean(n_run) < SPARSE_EXPECTED)
        wide = WIDE_FACTOR * float(projection_scale)
        # Only that cloud is indexed, once for both questions below (the diagnosis was most of a
        # sparse run's time: issue 19, W8).
        cylinders = clouds[cloud].cylinder_index(core, normals, (wide if sparse else float(projection_scale)) / 2.0,
                                                 reach, float(projection_scale), threads=threads)

        def along(keep: np.ndarray, diameter: float):
            """Points of that cloud, offset and spread of their mean along the normal, in a
            cylinder of `diameter` as long as the extent, at the core points idx[keep]."""
            s = cylinders.statistics(core[keep], normals[keep], diameter, reach, threads=threads)
            return np.asarray(s["count"]), np.asarray(s["mean"]), np.asarray(s["sigma"])

        counts, offset, spread = along(np.ones(idx.size, bool), float(projection_scale))
        found = counts > 0
        needed = None
        if found.any():
            # Where the cylinder meets that cloud: the offset of its points' mean along the normal.
            reach_needed = np.abs(offset[found]) + 2.0 * np.nan_to_num(spread[found])
            needed = float(np.percentile(reach_needed[np.isfinite(reach_needed)], 95)) if np.isfinite(
                reach_needed).any() else None
        # Not found along the whole line: no overlap (the edge of the cloud's coverage), unless the
        # cloud is sparse and a wider cylinder meets the cloud within the depth there.
        thin = np.zeros(idx.size, bool)
        scale = None
        if (~found).any() and sparse:
            n_wide, off_wide, _ = along(~found, wide)
            sparse_here = (n_wide > 0) & (np.abs(off_wide) <= float(max_depth))
            thin[np.flatnonzero(~found)[sparse_here]] = True
            if sparse_here.any():
                density = float(np.median(n_wide[sparse_here])) / (np.pi * wide**2 / 4.0)
                scale = 2.0 * float(np.sqrt(ADVISED_POINTS / (np.pi * density)))
        out.append(CylinderDiagnosis(cloud, with_normal, empty, idx[~found & ~thin], idx[found], needed,
                                     idx[thin], scale, diagnosed=int(idx.size)))
    return out


def _as_cloud(cloud):
    """An xyz array as m3c2kit.run.cylinder_points.WholeCloud; a streamed cloud as it is."""
    if hasattr(cloud, "cylinder_index"):
        return cloud
    from .cylinder_points import WholeCloud
    return WholeCloud(np.asarray(cloud))


def _rows(result, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The core points and normals of rows `idx` of `result` (a Result, or a tiled run's evidence)."""
    rows_at = getattr(result, "rows_at", None)
    if rows_at is not None:
        return rows_at(idx)
    return np.asarray(result.core)[idx], np.asarray(result.normal)[idx]


def _nice_up(value: float) -> float:
    """`value` rounded up to 2 significant digits."""
    if not value > 0:
        return value
    k = np.floor(np.log10(value)) - 1
    return float(np.ceil(value / 10**k) * 10**k)


def cylinder_messages(diagnoses: list[CylinderDiagnosis], max_depth: float) -> list[str]:
    """The warnings for :func:`cylinder_diagnosis`: no overlap (never advising a depth) and depth
    too short (advising the depth that reaches the points), above :data:`EMPTY_SHARE`."""
    lines = []
    for d in diagnoses:
        name = "reference" if d.cloud == 1 else "compared"
        if not d.with_normal or d.empty / d.with_normal <= EMPTY_SHARE:
            continue
        def share(kind: np.ndarray) -> str:
            return share_text(d.estimate(kind), d.with_normal, "core points with a normal", about=d.sampled)

        if d.no_overlap.size:
            lines.append(
                f"{share(d.no_overlap)} have no {name} "
                f"point in their cylinder at any depth: the {name} cloud does not cover them (the surveys do not "
                f"overlap there). Their distance is NaN (status empty_cylinder_{name}); a larger --max-depth "
                f"cannot help: restrict the core points to the overlap.")
        if d.too_thin.size and d.needed_scale is not None:
            lines.append(
                f"{share(d.too_thin)} have no {name} "
                f"point in their cylinder although the {name} surface lies within --max-depth {max_depth:g} (a "
                f"cylinder {WIDE_FACTOR:g} times as wide meets it there): the cylinder falls between the points, "
                f"the projection scale is small for the point spacing; --projection-scale "
                f"{_nice_up(d.needed_scale):g} holds about {ADVISED_POINTS} points in the median cylinder.")
        if d.beyond_depth.size and d.needed_depth is not None:
            lines.append(
                f"{share(d.beyond_depth)} have {name} "
                f"points only beyond --max-depth {max_depth:g} along the normal: the change exceeds the depth; "
                f"--max-depth {_nice_up(d.needed_depth):g} reaches 95 % of them.")
    return lines


def normal_failure_message(result, normal_scale) -> str | None:
    """A warning when more than :data:`NORMAL_FAILURE_SHARE` of the core points have no normal,
    naming the likely cause (D is a diameter)."""
    status = np.asarray(result.status)
    n = len(status)
    failed = int(np.count_nonzero(status_in(status, NO_NORMAL)))
    if not n or failed / n <= NORMAL_FAILURE_SHARE:
        return None
    scales = np.atleast_1d(np.asarray(normal_scale, dtype=float))
    d = float(scales.max()) if scales.size else float("nan")
    few = int(np.count_nonzero(status_in(status, NO_NORMAL[:1])))
    if few < failed - few:
        # A larger D does not help neighbourhoods that are there but degenerate (issue 42: the
        # radius advice at --normal-scale 1e15).
        return (f"{share_text(failed, n, 'core points')} have no normal (collinear or coincident neighbours "
                f"within D/2 = {d / 2:g} of --normal-scale {d:g}): their points lie on a line or coincide; a "
                f"normal needs a surface around the core point (paper 3.2), or give one (--normal-source "
                f"vertical or --core-normals)")
    return (f"{share_text(failed, n, 'core points')} have no normal (too few neighbours within D/2): D = "
            f"--normal-scale {d:g} is a DIAMETER (neighbours within D/2 = {d / 2:g}); did you give a radius? Try "
            f"--normal-scale {2 * d:g} or larger (about 10 points within D/2, paper 3.2).")


def extent_of(cloud) -> float:
    """The diagonal of the cloud's bounding box: an (N, 3) array, or a tiled run's streamed cloud
    (its bounds()); NaN when it has no finite point."""
    if hasattr(cloud, "bounds"):
        lo, hi = cloud.bounds()
    else:
        xyz = np.asarray(cloud, dtype=np.float64)
        if xyz.size == 0:
            return float("nan")
        with np.errstate(invalid="ignore"):
            lo, hi = np.nanmin(xyz, axis=0), np.nanmax(xyz, axis=0)
    diagonal = float(np.linalg.norm(np.asarray(hi) - np.asarray(lo)))
    return diagonal if np.isfinite(diagonal) else float("nan")


def scale_messages(normal_scale, projection_scale, max_depth, extent: float) -> list[str]:
    """Scales absurd for the data (issue 44): D, d or the depth beyond the reference's extent (the
    diagonal of its bounding box). A d past half the extent puts most of the cloud in every
    cylinder: each distance is then the offset between the clouds' means, and at n in the
    thousands every core point is significant; typed 100 times too large, they passed silently."""
    if not np.isfinite(extent) or extent <= 0.0:
        return []
    lines = []
    scales = np.atleast_1d(np.asarray(normal_scale if normal_scale is not None else [], dtype=np.float64))
    if scales.size and float(np.nanmax(scales)) > extent:
        lines.append(f"--normal-scale {float(np.nanmax(scales)):g} exceeds the reference's extent ({extent:.4g}, the "
                     f"diagonal of its bounding box): every normal is fitted to the whole cloud; D is a diameter, "
                     f"of the order of the roughness' scale (paper 3.2), not of the site")
    if projection_scale is not None and float(projection_scale) > 0.5 * extent:
        lines.append(f"--projection-scale {float(projection_scale):g} is over half the reference's extent "
                     f"({extent:.4g}): each cylinder holds most of the cloud, so each distance is the offset between "
                     f"the clouds' means and its LOD shrinks with thousands of points; d is a diameter of the order of "
                     f"the point spacing's few multiples (paper 3.3)")
    if max_depth is not None and float(max_depth) > extent:
        lines.append(f"--max-depth {float(max_depth):g} exceeds the reference's extent ({extent:.4g}): the cylinders "
                     f"reach other surfaces of the scene; the depth need only exceed the largest change expected")
    return lines
