"""`m3c2kit.pbm3c2`: correspondence-driven plane-based M3C2 (Zahs et al. 2022; docs/pbm3c2.md).
Both epochs are cut into planar segments (or their own segment ids are used), each reference
segment is paired with the compared segment of the same surface (the geometric rule, or a random
forest trained on labelled pairs, pbm3c2_forest.py), and the change is the distance between the
two planes along the reference normal with eq. (1)'s LOD from the planes' fits. The engine
(include/m3c2/pbm3c2.hpp) does the numbers; this module chooses the scales and assembles the table."""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, field

import numpy as np

from ..base.errors import UsageError
from ..engine import planes
from ..run.checks import as_points
from ..settings.needs import check_effective
from ..settings.pbm3c2_rows import CORRESPONDENCES, PBM3C2
from ..settings.table import by_name, parameters_of

__all__ = ["PBM3C2Options", "PBM3C2Result", "pbm3c2", "STATUS", "CORRESPONDENCES"]


def _default(row: str):
    """The default of the parameter table's row (settings/pbm3c2_rows.py): the engine's or the row's."""
    return by_name()[row].default_for()


#: Why a row (a reference segment) or a point has no distance: the engine's PairStatus (0-4), then
#: the segmentation's reasons for a point in no segment.
STATUS = {0: "paired", 1: "no plane (fewer than 3 points, or a line)", 2: "no candidate within the search radius "
          "and angle", 3: "not mutual (its compared segment's own choice is another reference segment)",
          4: "the classifier accepted no candidate", 5: "the compared plane is off its own points under the "
          "reference segment by more than the LOD (not a plane there)", 6: "in no segment: too few neighbours for a "
          "normal", 7: "in no segment: its segment was smaller than the minimum", 8: "in no segment: a negative "
          "segment id"}
_MISFIT = 5
#: A compared plane whose mean residual under the reference segment exceeds the LOD by more than this
#: many of its own standard errors is no model of the surface there (docs/pbm3c2.md, "Plane misfit").
MISFIT_SIGMAS = 3.0
_POINT_STATUS = {1: 6, 2: 7}  # the engine's SegmentStatus -> STATUS
_NO_SEGMENT_GIVEN = 8


@dataclass(frozen=True)
class PBM3C2Options:
    """What m3c2kit.pbm3c2 does (docs/pbm3c2.md). Lengths in the clouds' unit, angles in degrees.
    The defaults are the parameter table's rows' (settings/pbm3c2_rows.py; the engine's where its
    structs hold them, include/m3c2/pbm3c2.hpp)."""
    normal_scale: float | None = None  # D of the segmentation's normals; None: m3c2 suggest's D
    growth_scale: float = _default("growth_scale")  # 0: D
    segment_angle: float = _default("segment_angle")
    segment_distance: float = _default("segment_distance")  # 0: D / 4
    min_segment_points: int = _default("min_segment_points")
    correspondence: str = _default("correspondence")
    search_radius: float | None = _default("search_radius")  # None: the segments' median radius, >= D
    max_angle: float = _default("max_angle")
    mutual: bool = _default("mutual")
    forest_seed: int = _default("forest_seed")  # the random forest's random_state (py4dgeo's)
    registration_error: float = _default("registration_error")
    confidence: float = _default("confidence")
    orientation: tuple = (0.0, 0.0, 1.0)  # the normals' preferred direction (section 3.1.2)
    threads: int = 0


@dataclass
class PBM3C2Result:
    """One row per reference segment in `pairs` (x, y, z its centroid; nx, ny, nz its oriented
    normal; distance, lod, significant, n1, n2, then reference_segment, compared_segment,
    roughness1, roughness2, normal_angle, status, plane_misfit and, with the forest, probability); the
    segmentation of each cloud (labels per point, -1 none) and its reason per point."""
    pairs: dict
    reference_labels: np.ndarray
    compared_labels: np.ndarray
    reference_status: np.ndarray  # per reference point: STATUS code (0 in a segment)
    compared_status: np.ndarray
    reference_segments: dict  # the engine's segment tables (engine/planes.py)
    compared_segments: dict
    details: dict = field(default_factory=dict)

    def per_point(self) -> dict:
        """The reference points' columns: their segment, its pair's distance, lod, significant and
        status (a point in no segment: its own reason)."""
        row_of = {int(label): row for row, label in enumerate(self.pairs["reference_segment"])}
        rows = np.array([row_of.get(int(label), -1) for label in self.reference_labels], dtype=np.int64)
        inside = rows >= 0
        out = {"segment": self.reference_labels.copy()}
        for name in ("distance", "lod"):
            column = np.full(len(rows), math.nan)
            column[inside] = self.pairs[name][rows[inside]]
            out[name] = column
        out["significant"] = np.zeros(len(rows), dtype=np.uint8)
        out["significant"][inside] = self.pairs["significant"][rows[inside]]
        status = self.reference_status.copy()
        status[inside] = self.pairs["status"][rows[inside]]
        out["status"] = status
        return out


def pbm3c2(reference, compared, *, reference_segments=None, compared_segments=None, training=None, progress=None,
           **options) -> PBM3C2Result:
    """PB-M3C2 of `compared` against `reference` ((N, 3) arrays or m3c2kit.io.Cloud).

    reference_segments / compared_segments: each point's segment id (integers; negative: none),
    both or neither; without them both clouds are segmented (region growing on normals).
    training: with correspondence="forest", labelled pairs (K, 3): reference segment id, compared
    segment id, 1 (the same surface) or 0; or the path of such a CSV file (py4dgeo's
    correspondences file). The keywords are PBM3C2Options'."""
    try:
        opts = PBM3C2Options(**options)
    except TypeError as e:
        raise UsageError(f"pbm3c2: {e}") from None
    if isinstance(training, (str, os.PathLike)):
        from .pbm3c2_forest import read_training
        training = read_training(training)
    _check(opts, training, reference_segments, compared_segments)
    given = {**options, "training": training, "segments": None if reference_segments is None else "given"}
    check_effective(parameters_of(PBM3C2), {**vars(opts), **given}, given)
    ref, cmp_ = as_points("reference", reference), as_points("compared", compared)
    for name, cloud in (("reference", ref), ("compared", cmp_)):
        if len(cloud) == 0:
            raise UsageError(f"the {name} cloud is empty")
    # D only where m3c2 grows the segments (suggest's costs seconds on a large pair).
    scale = _normal_scale(ref, cmp_, opts) if reference_segments is None else None
    ref_labels, ref_status = _segmentation(ref, reference_segments, "reference_segments", opts, scale, progress)
    cmp_labels, cmp_status = _segmentation(cmp_, compared_segments, "compared_segments", opts, scale, progress)
    orient = {"direction": opts.orientation, "threads": opts.threads}
    ref_table = planes.plane_segments(ref, ref_labels, **orient)
    cmp_table = planes.plane_segments(cmp_, cmp_labels, **orient)
    radius = opts.search_radius if opts.search_radius is not None else _median_radius(ref_table, scale)
    probability = None
    rule = {"search_radius": radius, "max_angle_degrees": opts.max_angle, "mutual": opts.mutual}
    if opts.correspondence == "forest":
        from .pbm3c2_forest import forest_pairs
        found = forest_pairs(ref_table, cmp_table, training, radius, opts.forest_seed)
        probability = found["probability"]
    elif opts.correspondence == "overlap":
        found = planes.overlapping_segments(ref, ref_labels, ref_table, cmp_, cmp_labels, cmp_table, rule,
                                            threads=opts.threads, progress=progress)
    else:
        found = planes.nearest_segments(ref_table, cmp_table, rule)
    # The paper's rule for the critical value (3.3): Student's t with eq. (2)'s degrees of freedom
    # when a segment has under 30 points (z there covered 90 % at 8-15 points, docs/validation.md).
    changes = planes.plane_changes(ref_table, cmp_table, found["compared"],
                                   {"confidence": opts.confidence, "registration_error": opts.registration_error,
                                    "lod": "auto"})
    misfit = planes.compared_plane_misfit(ref, ref_labels, ref_table, cmp_, cmp_labels, cmp_table, found["compared"],
                                          threads=opts.threads)
    found, changes = _refuse_misfits(found, changes, misfit, cmp_table)
    pairs = _pairs_table(ref_table, cmp_table, found, changes, misfit, probability)
    _warn_if_empty(ref_table, cmp_table, found, ref_status, cmp_status, reference_segments is None)
    details = {"normal_scale": scale, "search_radius": float(radius), "correspondence": opts.correspondence,
               "reference_segments": len(ref_table["label"]), "compared_segments": len(cmp_table["label"]),
               "paired": int(np.count_nonzero(found["status"] == 0)),
               "segmented_by": "given" if reference_segments is not None else "region growing"}
    return PBM3C2Result(pairs, ref_labels, cmp_labels, ref_status, cmp_status, ref_table, cmp_table, details)


def _refuse_misfits(found: dict, changes: dict, misfit: dict, cmp_table: dict) -> tuple[dict, dict]:
    """A pair whose compared plane lies farther from its own points under the reference segment than
    the LOD plus MISFIT_SIGMAS of that mean's standard error (sigma2 / sqrt(points)) has no distance:
    the plane misrepresents its surface there, by more than the precision the LOD claims."""
    compared = np.asarray(found["compared"])
    at = np.where(compared >= 0, compared, 0)
    sigma2 = np.asarray(cmp_table["roughness"])[at] if len(cmp_table["roughness"]) else np.zeros(len(compared))
    points = np.asarray(misfit["points"]).astype(float)
    with np.errstate(divide="ignore", invalid="ignore"):
        excess = np.abs(np.asarray(misfit["mean_residual"])) - MISFIT_SIGMAS * sigma2 / np.sqrt(points)
    off = (compared >= 0) & np.isfinite(excess) & (excess > np.asarray(changes["lod"]))
    if not off.any():
        return found, changes
    found = {**found, "status": np.where(off, _MISFIT, found["status"]).astype(np.uint8)}
    changes = {**changes, "distance": np.where(off, np.nan, changes["distance"]),
               "lod": np.where(off, np.nan, changes["lod"]),
               "significant": np.where(off, 0, changes["significant"]).astype(np.uint8)}
    return found, changes


def _warn_if_empty(ref_table: dict, cmp_table: dict, found: dict, ref_status, cmp_status, grown: bool) -> None:
    """A run that measures nothing says why (a table of NaN or no rows is no answer)."""
    import warnings

    from ..base.errors import M3C2Warning
    for name, table, status in (("reference", ref_table, ref_status), ("compared", cmp_table, cmp_status)):
        if len(table["label"]) == 0:
            reasons = ", ".join(f"{int(np.count_nonzero(status == code))} {STATUS[code].split(': ')[-1]}"
                                for code in (6, 7, 8) if np.any(status == code))
            hint = (": raise the segment angle or distance, lower the fewest points of a segment, or change D" if grown else "")
            warnings.warn(f"the {name} cloud has no planar segment ({reasons}){hint}", M3C2Warning, stacklevel=3)
            return
    if not np.any(np.asarray(found["status"]) == 0):
        warnings.warn("no reference segment found a compared segment: raise the search radius or the angle, or "
                      "register the clouds first (m3c2 register)", M3C2Warning, stacklevel=3)


def _check(opts: PBM3C2Options, training, reference_segments, compared_segments) -> None:
    if opts.correspondence not in CORRESPONDENCES:
        raise UsageError(f"correspondence must be one of {', '.join(CORRESPONDENCES)}, got {opts.correspondence!r}")
    if opts.correspondence == "forest" and training is None:
        raise UsageError("correspondence='forest' learns from labelled pairs: give training (reference id, "
                         "compared id, 1 or 0 per row)")
    if opts.correspondence != "forest" and training is not None:
        raise UsageError("training pairs teach the random forest: they need correspondence='forest'")
    if (reference_segments is None) != (compared_segments is None):
        raise UsageError("give the segments of both clouds or of neither (then both are segmented)")
    if reference_segments is not None and opts.normal_scale is not None:
        raise UsageError("normal_scale would change nothing in this run: it is the segmentation's D, and the "
                         "segments are given")
    for name in ("normal_scale", "search_radius"):
        value = getattr(opts, name)
        if value is not None and not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
            raise UsageError(f"{name} must be a positive number, got {value!r}")
    if not (isinstance(opts.registration_error, (int, float)) and opts.registration_error >= 0
            and math.isfinite(opts.registration_error)):
        raise UsageError(f"registration_error must be a number >= 0, got {opts.registration_error!r}")
    if not (isinstance(opts.max_angle, (int, float)) and 0 < opts.max_angle <= 90):
        raise UsageError(f"max_angle must be in (0, 90] degrees, got {opts.max_angle!r}")


def _normal_scale(ref: np.ndarray, cmp_: np.ndarray, opts: PBM3C2Options) -> float:
    if opts.normal_scale is not None:
        return float(opts.normal_scale)
    import warnings

    from .suggest import suggest
    with warnings.catch_warnings():  # suggest's trial runs warn about their own trial scales
        warnings.simplefilter("ignore")
        return float(suggest(ref, cmp_, threads=opts.threads)["D"])


def _segmentation(points: np.ndarray, given, name: str, opts: PBM3C2Options, scale: float, progress):
    """Each point's segment (-1: none) and STATUS code (0 in a segment)."""
    if given is not None:
        labels = _given_labels(given, len(points), name)
        return labels, np.where(labels >= 0, 0, _NO_SEGMENT_GIVEN).astype(np.uint8)
    found = planes.segment_planes(points, {"normal_diameter": scale, "growth_diameter": opts.growth_scale,
                                           "max_angle_degrees": opts.segment_angle,
                                           "max_plane_distance": opts.segment_distance,
                                           "min_points": opts.min_segment_points},
                                  threads=opts.threads, progress=progress)
    status = np.asarray(found["status"])
    codes = np.zeros(len(status), dtype=np.uint8)
    for engine_code, code in _POINT_STATUS.items():
        codes[status == engine_code] = code
    return np.asarray(found["labels"]), codes


def _given_labels(given, n: int, name: str) -> np.ndarray:
    values = np.asarray(given)
    if values.shape != (n,):
        raise UsageError(f"{name} must hold one segment id per point ({n}), got shape {values.shape}")
    if values.dtype.kind == "f":
        if not np.all(np.isfinite(values)) or np.any(values != np.round(values)):
            raise UsageError(f"{name} must be integers (segment ids), got non-integer values")
        if np.any(np.abs(values) > 2.0 ** 53):
            raise UsageError(f"{name}: segment ids beyond 2^53 are not exact in floating point")
    elif values.dtype.kind not in "iub":
        raise UsageError(f"{name} must be integers (segment ids), got {values.dtype}")
    if values.dtype.kind == "u" and values.size and values.max() > np.iinfo(np.int64).max:
        raise UsageError(f"{name}: segment ids beyond 2^63 - 1")
    return values.astype(np.int64)


def _median_radius(table: dict, scale: float | None) -> float:
    """The search radius a move of up to a segment's size is found within: the median over the
    reference segments of sqrt(lambda1 + lambda2), the RMS in-plane distance of a segment's points
    from its centroid (half the side of a square facet times 0.82), and at least D when m3c2 grew
    the segments."""
    ev = np.asarray(table["eigenvalues"])
    radii = np.sqrt(ev[:, 0] + ev[:, 1]) if len(ev) else np.array([])
    radii = radii[np.isfinite(radii) & (radii > 0)]
    median = float(np.median(radii)) if len(radii) else 0.0
    radius = max(median, scale or 0.0)
    if radius <= 0.0:
        raise UsageError("no reference segment has an extent to take the search radius from: give search_radius")
    return radius


def _pairs_table(ref: dict, cmp_: dict, found: dict, changes: dict, misfit: dict, probability) -> dict:
    compared = np.asarray(found["compared"])
    paired = compared >= 0
    at = np.where(paired, compared, 0)
    centroid, normal = np.asarray(ref["centroid"]), np.asarray(ref["normal"])

    def from_compared(column, fill):
        values = np.asarray(cmp_[column])[at] if len(cmp_[column]) else np.zeros(len(compared), dtype=float)
        return np.where(paired, values, fill)

    table = {"x": centroid[:, 0], "y": centroid[:, 1], "z": centroid[:, 2],
             "nx": normal[:, 0], "ny": normal[:, 1], "nz": normal[:, 2],
             "distance": np.asarray(changes["distance"]), "lod": np.asarray(changes["lod"]),
             "significant": np.asarray(changes["significant"]),
             "n1": np.asarray(ref["count"]).astype(np.int64), "n2": from_compared("count", 0).astype(np.int64),
             "reference_segment": np.asarray(ref["label"]),
             "compared_segment": from_compared("label", -1).astype(np.int64),
             "roughness1": np.asarray(ref["roughness"]), "roughness2": from_compared("roughness", math.nan),
             "normal_angle": np.asarray(changes["normal_angle"]), "status": np.asarray(found["status"]),
             "plane_misfit": np.asarray(misfit["mean_residual"])}
    if probability is not None:
        table["probability"] = np.asarray(probability)
    return table
