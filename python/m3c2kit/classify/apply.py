"""Applying a CANUPO classifier: a class and a confidence per point, and the filter that keeps
the points of some classes (m3c2 compare --classifier FILE --keep CLASS)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..base.errors import UsageError
from .features import features
from .model import Classifier


@dataclass
class Prediction:
    """index[i]: position of point i's class in classifier.labels, -1 where the point has no
    features (too few neighbours at the largest scale: features.status); confidence[i] in [0, 1]
    (NaN there); distance[i]: the signed distance to the boundary of the deciding classifier."""
    index: np.ndarray
    confidence: np.ndarray
    distance: np.ndarray
    status: np.ndarray

    def labels(self, classifier: Classifier, missing: str = "") -> np.ndarray:
        names = np.array(list(classifier.labels) + [missing], dtype=object)
        return names[self.index]


def confidence_of(distance: np.ndarray) -> np.ndarray:
    """CANUPO's confidence from the signed distance d to the boundary: 2 / (1 + exp(-|d|)) - 1, in
    [0, 1) (0 on the boundary), i.e. tanh(|d| / 2)."""
    return np.tanh(np.abs(distance) / 2.0)


def predict_vectors(clf: Classifier, vector: np.ndarray, ok: np.ndarray, status=None) -> Prediction:
    """Classes of descriptors (N, 2 S). Several two-class classifiers vote (one vote each, for the
    side of its boundary the point is on); a tie goes to the class whose lowest confidence is the
    highest, and the confidence is the lowest of the winner's votes (as qCANUPO)."""
    n, L = len(vector), len(clf.labels)
    position = {label: k for k, label in enumerate(clf.labels)}
    votes = np.zeros((n, L), dtype=np.int64)
    lowest = np.full((n, L), np.inf)
    dist_of = np.full((n, L), np.nan)
    v = np.where(ok[:, None], vector, 0.0)
    for b in clf.binaries:
        d = b.signed_distance(b.project(v))
        conf = confidence_of(d)
        winner = np.where(d >= 0, position[b.class2], position[b.class1])
        rows = np.arange(n)
        votes[rows, winner] += 1
        better = conf < lowest[rows, winner]
        lowest[rows[better], winner[better]] = conf[better]
        dist_of[rows[better], winner[better]] = d[better]
    most = votes.max(axis=1, keepdims=True)
    key = np.where(votes == most, lowest, -np.inf)
    index = np.argmax(key, axis=1)
    rows = np.arange(n)
    confidence = lowest[rows, index]
    distance = dist_of[rows, index]
    index = np.where(ok, index, -1)
    confidence = np.where(ok, confidence, np.nan)
    distance = np.where(ok, distance, np.nan)
    return Prediction(index, confidence, distance, np.zeros(n, np.uint8) if status is None else status)


def classify(clf: Classifier, cloud_xyz, core_xyz=None, *, threads: int = 0, progress=None) -> Prediction:
    """Class and confidence of each point of `core_xyz` (default: every point of `cloud_xyz`),
    from the features of `cloud_xyz` at the classifier's scales."""
    f = features(cloud_xyz, clf.scales, core_xyz, min_points=clf.min_points, threads=threads, progress=progress)
    return predict_vectors(clf, f.vector(), f.ok, f.status)


def keep_mask(clf: Classifier, cloud_xyz, keep, *, threads: int = 0, progress=None) -> np.ndarray:
    """Boolean mask of the points of `cloud_xyz` classified as one of the classes `keep` (labels of
    the classifier, e.g. ["ground"]). Points without features (too few neighbours at the largest
    scale) are not kept. Raises UsageError naming a class the classifier does not know."""
    keep = [str(k) for k in ([keep] if isinstance(keep, (str, int)) else keep)]
    unknown = [k for k in keep if k not in clf.labels]
    if unknown:
        raise UsageError(f"--keep {','.join(unknown)}: not a class of the classifier (its classes: "
                         f"{', '.join(clf.labels)})")
    p = classify(clf, cloud_xyz, threads=threads, progress=progress)
    wanted = np.array([clf.labels.index(k) for k in keep])
    return np.isin(p.index, wanted)


def filtered(clf: Classifier, cloud, keep, name: str = "cloud", *, threads: int = 0):
    """`cloud` (an (N, 3) array or an object with ``xyz`` and ``select``, such as m3c2kit.io.Cloud)
    reduced to its points classified as one of `keep`; UsageError naming `name` when none is left."""
    xyz = np.ascontiguousarray(getattr(cloud, "xyz", cloud), dtype=np.float64)
    mask = keep_mask(clf, xyz, keep, threads=threads)
    if not mask.any():
        raise UsageError(f"the {name} cloud has no point classified as {', '.join(map(str, keep))} "
                         f"({len(xyz)} points classified)")
    return cloud.select(mask) if hasattr(cloud, "select") else xyz[mask]
