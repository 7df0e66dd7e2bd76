"""The parameter table's rows of `m3c2 pbm3c2` (PB-M3C2, Zahs et al. 2022; docs/pbm3c2.md): each
option once, with its flag, range, help and default. A default the engine's
PlaneSegmentationParams or CorrespondenceParams holds (include/m3c2/pbm3c2.hpp) is read from it;
the others are the row's. The command line's parser and m3c2kit.pbm3c2's options
(analysis/pbm3c2.py, PBM3C2Options) are built from these rows; D (--normal-scale), the LOD's
confidence and reg and the threads are the options other commands share (cli/options.py)."""
from __future__ import annotations

from .needs import Needs
from .parsers import UINT32_MAX, Choice, Flag, Integer, Real, Text
from .row import FROM_ENGINE, Parameter, same

__all__ = ["PBM3C2", "PBM3C2_ROWS", "CORRESPONDENCES"]

PBM3C2 = "pbm3c2"
SEGMENTATION = "PlaneSegmentationParams"
CORRESPONDENCE = "CorrespondenceParams"
#: How a reference segment finds its compared segment: two geometric rules or the random forest.
CORRESPONDENCES = ("overlap", "nearest", "forest")
SECTION = "Zahs et al. 2022"

GEOMETRIC = Needs(lambda v: v.get("correspondence") in (None, "overlap", "nearest"),
                  "with --correspondence overlap or nearest")
FOREST = Needs(lambda v: v.get("correspondence") == "forest", "with --correspondence forest")
GROWN = Needs(lambda v: v.get("segments") is None, "without --segments (when m3c2 segments the clouds)")
ANGLE = Real(0.0, below=90.0)


def _row(name, flag, kind, help, *, struct=None, field=None, default=None, **more):
    """A pbm3c2 row; `struct`/`field`: the engine field holding its default (else `default`, the
    row's own; None: not given); `more`: Parameter's other fields (cli_type, str unless given)."""
    more.setdefault("cli_type", str)
    engine_field = same(field, struct) if struct is not None else None
    return Parameter(name, flag, kind, help, SECTION, engine=engine_field,
                     default=FROM_ENGINE if engine_field is not None else default, commands=(PBM3C2,),
                     scope="step", **more)


PBM3C2_ROWS: tuple[Parameter, ...] = (
    # The segments: given (py4dgeo's segment_id) or grown (Rabbani et al. 2006)
    _row("segments", "--segments", Text("a field name"), "each point's segment id, from this field of both clouds "
         "(py4dgeo's segment_id, CloudCompare's plane ids); negative: in no segment", metavar="FIELD",
         unset="both clouds segmented by region growing on normals", label="Segment id field"),
    _row("growth_scale", "--growth-scale", Real(closed=True), "a segment grows to the points within this diameter "
         "of its points; 0: D", struct=SEGMENTATION, field="growth_diameter", cli_type=float, metavar="D", needs=(GROWN,)),
    _row("segment_angle", "--segment-angle", ANGLE, "a point joins a segment when its normal is within this many "
         "degrees of the segment's plane", struct=SEGMENTATION, field="max_angle_degrees", cli_type=float,
         metavar="DEG", needs=(GROWN,)),
    _row("segment_distance", "--segment-distance", Real(closed=True), "a point joins a segment only within this "
         "distance of its plane; 0: D / 4", struct=SEGMENTATION, field="max_plane_distance", cli_type=float, metavar="DIST",
         needs=(GROWN,)),
    _row("min_segment_points", "--min-segment-points", Integer(1, UINT32_MAX, "an integer >= 1"), "fewest points "
         "of a segment (smaller ones leave their points in none)", struct=SEGMENTATION, field="min_points",
         cli_type=int, metavar="N", needs=(GROWN,)),
    # The pairs (Zahs et al. 2022, 3.4)
    _row("correspondence", "--correspondence", Choice(*CORRESPONDENCES), "overlap: the compared segment most of "
         "the reference segment's points have as their nearest within the search radius (robust where the two "
         "segmentations cut a surface differently); nearest: the compared segment whose centroid is nearest "
         "(py4dgeo's); both behind --max-angle; forest: a random forest trained on --training's labelled pairs "
         "(scikit-learn)", default="overlap"),
    _row("search_radius", "--search-radius", Real(), "overlap: the farthest nearest point that votes; nearest "
         "and forest: compared segments whose centroid is farther than this from the reference segment's are not "
         "candidates", cli_type=float, metavar="R",
         unset="the reference segments' median radius sqrt(lambda1 + lambda2), at least D"),
    _row("max_angle", "--max-angle", ANGLE, "overlap and nearest: a candidate's plane within this many degrees of "
         "the reference segment's", struct=CORRESPONDENCE, field="max_angle_degrees", cli_type=float, metavar="DEG",
         needs=(GEOMETRIC,)),
    _row("mutual", "--mutual", Flag(), "overlap and nearest: keep a pair only when each segment is the other's "
         "choice", struct=CORRESPONDENCE, field="mutual", cli_type=None, needs=(GEOMETRIC,)),
    _row("training", "--training", Text("a CSV file"), "forest: labelled pairs, one per line: reference segment id, "
         "compared segment id, 1 (the same surface) or 0 (py4dgeo's correspondences file)", metavar="CSV",
         needs=(FOREST,), unset="none"),
    _row("forest_seed", "--forest-seed", Integer(0, UINT32_MAX, "an integer >= 0"), "forest: the random forest's "
         "seed (py4dgeo's random_state)", default=42, cli_type=int, metavar="SEED", needs=(FOREST,)),
    # What is written
    _row("per_point", "--per-point", Text("a point-cloud file"), "also write the reference points with their "
         "segment, its pair's distance, lod, significant and status", metavar="FILE", unset="none"),
)
