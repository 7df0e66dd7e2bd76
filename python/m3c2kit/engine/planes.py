"""PB-M3C2's engine calls (include/m3c2/pbm3c2.hpp): segmentation, the segments' planes, their
pairs and the planes' distances. A segment table is a dict of numpy arrays, one row per segment
(label, count, centroid, normal, eigenvalues, major_axis, roughness), as the engine returns it."""
from __future__ import annotations

import numpy as np

from . import _bound_struct, _progress, _threads, make_params, translated
from .. import _core

#: The columns of a segment table and their dtypes: what the engine reads back.
SEGMENT_COLUMNS = {"label": np.int64, "count": np.uint64, "centroid": np.float64, "normal": np.float64,
                   "eigenvalues": np.float64, "major_axis": np.float64, "roughness": np.float64}


def _points(points) -> np.ndarray:
    return np.ascontiguousarray(points, dtype=np.float64)


def _table(table: dict) -> dict:
    return {name: np.ascontiguousarray(table[name], dtype=dtype) for name, dtype in SEGMENT_COLUMNS.items()}


def segment_planes(points, params: dict, *, threads: int = 0, progress=None) -> dict:
    """Region growing on normals; `params`: PlaneSegmentationParams' fields by name. Returns
    labels (int64, -1 unsegmented), status (uint8, SegmentStatus) and segments."""
    bound = _bound_struct(_core.PlaneSegmentationParams, params)
    with translated():
        return _core.segment_planes(_points(points), bound, threads=_threads(threads), progress=_progress(progress))


def plane_segments(points, labels, *, direction=(0.0, 0.0, 1.0), orientation_points=None, away: bool = False,
                   threads: int = 0) -> dict:
    """The least-squares plane of each segment (labels >= 0), normals oriented along `direction`
    or towards the nearest of `orientation_points` ((K, 3); away from it with `away`)."""
    extra = [] if orientation_points is None else np.asarray(orientation_points, dtype=np.float64).ravel().tolist()
    with translated():
        return _core.plane_segments(_points(points), np.ascontiguousarray(labels, dtype=np.int64),
                                    [float(v) for v in direction], extra, away=away, threads=_threads(threads))


def nearest_segments(reference: dict, compared: dict, params: dict) -> dict:
    """The geometric rule's pairs: compared (int64 row or -1) and status (uint8, PairStatus) per
    reference row; `params`: CorrespondenceParams' fields by name."""
    bound = _bound_struct(_core.CorrespondenceParams, params)
    with translated():
        return _core.nearest_segments(_table(reference), _table(compared), bound)


def overlapping_segments(reference, reference_labels, reference_planes: dict, compared, compared_labels,
                         compared_planes: dict, params: dict, *, threads: int = 0, progress=None) -> dict:
    """The overlap rule's pairs: each reference point votes for the segment of its nearest segmented
    compared point; compared (int64 row or -1) and status (uint8, PairStatus) per reference row."""
    bound = _bound_struct(_core.CorrespondenceParams, params)
    with translated():
        return _core.overlapping_segments(
            _points(reference), np.ascontiguousarray(reference_labels, dtype=np.int64), _table(reference_planes),
            _points(compared), np.ascontiguousarray(compared_labels, dtype=np.int64), _table(compared_planes), bound,
            threads=_threads(threads), progress=_progress(progress))


def compared_plane_misfit(reference, reference_labels, reference_planes: dict, compared, compared_labels,
                          compared_planes: dict, compared_of_reference, *, threads: int = 0) -> dict:
    """Per reference row: the mean signed distance to its paired compared plane of that segment's
    points over the reference segment's footprint (mean_residual, NaN: none) and how many (points)."""
    with translated():
        return _core.compared_plane_misfit(
            _points(reference), np.ascontiguousarray(reference_labels, dtype=np.int64), _table(reference_planes),
            _points(compared), np.ascontiguousarray(compared_labels, dtype=np.int64), _table(compared_planes),
            np.ascontiguousarray(compared_of_reference, dtype=np.int64), threads=_threads(threads))


def segment_candidates(reference: dict, compared: dict, search_radius: float) -> dict:
    """Every (reference row, compared row) whose centroids are within search_radius."""
    with translated():
        return _core.segment_candidates(_table(reference), _table(compared), float(search_radius))


def plane_changes(reference: dict, compared: dict, compared_of_reference, fields: dict) -> dict:
    """Distance, lod, significant and normal_angle per reference row; `fields`: Params' fields
    (confidence, registration_error, lod, correlated_variance)."""
    params = make_params(fields)
    with translated():
        return _core.plane_changes(_table(reference), _table(compared),
                                   np.ascontiguousarray(compared_of_reference, dtype=np.int64), params)


def pair_features(reference: dict, compared: dict, reference_rows, compared_rows) -> dict:
    """The classifier's features of the pairs (reference_rows[k], compared_rows[k]):
    centroid_distance, normal_angle (radians, unoriented), roughness_difference."""
    with translated():
        return _core.pair_features(_table(reference), _table(compared),
                                   np.ascontiguousarray(reference_rows, dtype=np.int64),
                                   np.ascontiguousarray(compared_rows, dtype=np.int64))
