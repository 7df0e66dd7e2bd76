"""A CANUPO classifier and its files.

A classifier is a list of two-class classifiers over the same scales. Each projects the
descriptor (x, y of every scale, :meth:`Features.vector`) to a plane, (X, Y) = (w1 . f + w1_0,
w2 . f + w2_0), and splits that plane by a boundary polyline; the signed distance to the boundary
gives the class (class2 where >= 0) and the confidence (Brodu & Lague 2012; docs/algorithm.md).

Files (docs/classify.md): our JSON (any extension but .prm) and CloudCompare qCANUPO's binary
.prm, read and written with the same fields.
"""
from __future__ import annotations

import json
import os
import struct
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .. import engine
from ..base.errors import M3C2Error
from ..io.atomic import atomic_output
from ..io.input_file import read_small_bytes, read_small_json

FORMAT = "m3c2kit-canupo-classifier"
VERSION = 1
CLASSIFIER_KIND = "classifier"  # its size limit: io.input_file.SMALL_FILE_LIMITS


class ClassifierFileError(M3C2Error):
    """A classifier file could not be read or written; the message starts with the path."""


@dataclass
class BinaryClassifier:
    """class1 on the negative side of the boundary, class2 on the positive side.

    w1, w2: 2 S + 1 weights each (the last is the constant); path: (K, 2) boundary vertices,
    K >= 2, its first and last segments extended to half-lines; ref_pos: a point on class2's side
    (CANUPO's reference point: the side is found by the parity of the path crossings on the way
    from a point to it)."""
    class1: str
    class2: str
    w1: np.ndarray
    w2: np.ndarray
    path: np.ndarray
    ref_pos: np.ndarray
    ref_neg: np.ndarray
    info: dict = field(default_factory=dict)

    def project(self, vector: np.ndarray) -> np.ndarray:
        """(N, 2 S) descriptors -> (N, 2) plane coordinates."""
        return np.stack([vector @ self.w1[:-1] + self.w1[-1], vector @ self.w2[:-1] + self.w2[-1]], axis=1)

    def signed_distance(self, plane: np.ndarray) -> np.ndarray:
        """Distance of each plane point to the boundary, positive on class2's side."""
        return _signed_distance(plane, np.asarray(self.path, float), np.asarray(self.ref_pos, float))


@dataclass
class Classifier:
    """scales: diameters, in descriptor order; labels: every class, in training order."""
    scales: np.ndarray
    binaries: list[BinaryClassifier]
    labels: list[str]
    min_points: int = 3
    info: dict = field(default_factory=dict)
    source_format: str = "json"


def _signed_distance(q: np.ndarray, path: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Signed distance from each row of q (N, 2) to the polyline `path` whose end segments are
    half-lines: its magnitude is the distance to the nearest piece; its sign + where the segment
    from the point to `ref` crosses the polyline an even number of times (same side as ref)."""
    n = len(q)
    best = np.full(n, np.inf)
    crossings = np.zeros(n, dtype=np.int64)
    last = len(path) - 2
    for i in range(len(path) - 1):
        a, b = path[i], path[i + 1]
        ab = b - a
        length = float(np.hypot(*ab))
        if length == 0.0:
            continue
        v = ab / length
        ap = q - a
        along = ap @ v
        lo = -np.inf if i == 0 else 0.0
        hi = np.inf if i == last else length
        t = np.clip(along, lo, hi)
        foot = a + t[:, None] * v
        best = np.minimum(best, np.hypot(*(q - foot).T))
        # Crossing of [q, ref] with the piece: q + s (ref - q) = a + t v, s in [0, 1], t in [lo, hi).
        d = ref - q
        denom = d[:, 0] * v[1] - d[:, 1] * v[0]
        with np.errstate(divide="ignore", invalid="ignore"):
            s = (ap[:, 1] * v[0] - ap[:, 0] * v[1]) / denom
            tt = (ap[:, 1] * d[:, 0] - ap[:, 0] * d[:, 1]) / denom
        hit = (denom != 0) & (s >= 0) & (s <= 1) & (tt >= lo) & (tt < hi)
        crossings += hit
    return np.where(crossings % 2 == 0, best, -best)


# ------------------------------------------------------------------------------------ JSON

def _to_json(clf: Classifier) -> dict:
    return {
        "format": FORMAT, "version": VERSION, "descriptor": "dimensionality",
        "scales": [float(s) for s in clf.scales], "min_points": int(clf.min_points), "labels": list(clf.labels),
        "classifiers": [{
            "class1": b.class1, "class2": b.class2, "w1": [float(w) for w in b.w1], "w2": [float(w) for w in b.w2],
            "path": [[float(x), float(y)] for x, y in b.path], "ref_pos": [float(v) for v in b.ref_pos],
            "ref_neg": [float(v) for v in b.ref_neg], "info": b.info} for b in clf.binaries],
        "info": clf.info,
    }


#: The most scales and two-class classifiers a file may hold (as the .prm reader's bounds): far
#: above any real classifier, so that a forged count never sizes an allocation.
MAX_SCALES = 10000
MAX_CLASSIFIERS = 10000
MAX_BOUNDARY_POINTS = 100000
#: min_points is a neighbour count the engine takes as a 32-bit unsigned integer (engine.COUNT_MAX).
MAX_MIN_POINTS = engine.COUNT_MAX


def _numbers(path, value, where: str, shape: tuple) -> np.ndarray:
    """`value` as a float64 array of `shape` (-1: any length): a forged file's strings, objects,
    ragged lists or booleans are refused by name, not left to numpy's messages."""
    def flat(v):
        return isinstance(v, (int, float)) and not isinstance(v, bool)
    ok = isinstance(value, list) and (all(flat(v) for v in value) if len(shape) == 1 else
                                      all(isinstance(r, list) and len(r) == shape[1] and all(flat(v) for v in r)
                                          for r in value))
    if not ok:
        raise ClassifierFileError(f"{path}: {where} must be a list of {'numbers' if len(shape) == 1 else 'pairs of numbers'}")
    try:
        out = np.array(value, dtype=np.float64).reshape(-1, *shape[1:])
    except OverflowError:  # an integer past float64's range, e.g. 10**400 written in full
        raise ClassifierFileError(f"{path}: {where} holds a number out of range") from None
    if shape[0] != -1 and len(out) != shape[0]:
        raise ClassifierFileError(f"{path}: {where} must hold {shape[0]} values, got {len(out)}")
    return out


def _integer(path, value, where: str, low: int, high: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or value != value or \
            value in (float("inf"), float("-inf")) or value != int(value) or not low <= int(value) <= high:
        raise ClassifierFileError(f"{path}: {where} must be an integer in [{low}, {high}], got {value!r}")
    return int(value)


def _label(path, value, where: str) -> str:
    # Labels are written back (JSON, .prm) and printed: a string or an integer, nothing else.
    if isinstance(value, bool) or not isinstance(value, (str, int)):
        raise ClassifierFileError(f"{path}: {where} must be a string or an integer, got {type(value).__name__}")
    return str(value)


def _object(path, value, where: str) -> dict:
    if not isinstance(value, dict):
        raise ClassifierFileError(f"{path}: {where} must be a JSON object")
    return value


def _from_json(path: Path, d: dict) -> Classifier:
    def need(obj, key, where="the file"):
        if key not in obj:
            raise ClassifierFileError(f"{path}: {where} has no {key!r}")
        return obj[key]
    if d.get("format") != FORMAT:
        raise ClassifierFileError(f"{path}: not an m3c2kit classifier (format {printable_value(d.get('format'))}, "
                                  f"expected {FORMAT!r}; CloudCompare classifiers end in .prm)")
    version = _integer(path, d.get("version", 0), "'version'", 0, 2**31)
    if version > VERSION:
        raise ClassifierFileError(f"{path}: classifier version {version} is newer than this m3c2kit "
                                  f"reads ({VERSION})")
    scales = _numbers(path, need(d, "scales"), "'scales'", (-1,))
    if not 0 < len(scales) <= MAX_SCALES:
        raise ClassifierFileError(f"{path}: 'scales' must hold 1 to {MAX_SCALES} values, got {len(scales)}")
    dim = 2 * len(scales) + 1
    classifiers = need(d, "classifiers")
    if not isinstance(classifiers, list) or not 0 < len(classifiers) <= MAX_CLASSIFIERS:
        raise ClassifierFileError(f"{path}: 'classifiers' must be a list of 1 to {MAX_CLASSIFIERS} objects")
    labels_given = need(d, "labels")
    if not isinstance(labels_given, list):
        raise ClassifierFileError(f"{path}: 'labels' must be a list")
    labels = [_label(path, x, "'labels'") for x in labels_given]
    if len(set(labels)) != len(labels):
        raise ClassifierFileError(f"{path}: 'labels' lists a class twice")
    binaries = []
    for k, c in enumerate(classifiers):
        where = f"classifier {k}"
        c = _object(path, c, where)
        path_points = _numbers(path, need(c, "path", where), f"{where}'s 'path'", (-1, 2))
        if not 2 <= len(path_points) <= MAX_BOUNDARY_POINTS:
            raise ClassifierFileError(f"{path}: {where} has a boundary of {len(path_points)} points "
                                      f"(2 to {MAX_BOUNDARY_POINTS})")
        b = BinaryClassifier(_label(path, need(c, "class1", where), f"{where}'s 'class1'"),
                             _label(path, need(c, "class2", where), f"{where}'s 'class2'"),
                             _numbers(path, need(c, "w1", where), f"{where}'s 'w1'", (dim,)),
                             _numbers(path, need(c, "w2", where), f"{where}'s 'w2'", (dim,)),
                             path_points,
                             _numbers(path, need(c, "ref_pos", where), f"{where}'s 'ref_pos'", (2,)),
                             _numbers(path, need(c, "ref_neg", where), f"{where}'s 'ref_neg'", (2,)),
                             _object(path, c.get("info", {}), f"{where}'s 'info'"))
        unknown = [x for x in (b.class1, b.class2) if x not in labels]
        if unknown:  # applying it would look the class up in 'labels' and find nothing
            raise ClassifierFileError(f"{path}: {where} separates {unknown[0]!r}, which 'labels' does not list")
        binaries.append(b)
    return _checked(path, Classifier(scales, binaries, labels,
                                     _integer(path, d.get("min_points", 3), "'min_points'", 3, MAX_MIN_POINTS),
                                     _object(path, d.get("info", {}), "'info'"), "json"))


def printable_value(value) -> str:
    """A short repr of a value read from a forged file (a 'format' may be a megabyte of text)."""
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


def _checked(path, clf: Classifier) -> Classifier:
    if not clf.binaries:
        raise ClassifierFileError(f"{path}: holds no classifier")
    if len(clf.scales) == 0 or not np.all(np.isfinite(clf.scales)) or np.any(clf.scales <= 0):
        raise ClassifierFileError(f"{path}: scales must be positive numbers, got {list(clf.scales)}")
    for b in clf.binaries:
        for name in ("w1", "w2", "path", "ref_pos", "ref_neg"):
            if not np.all(np.isfinite(getattr(b, name))):
                raise ClassifierFileError(f"{path}: classifier {b.class1}/{b.class2} has non-finite {name}")
    return clf


# ------------------------------------------------------------------------------------- PRM
# CloudCompare qCANUPO's .prm (plugins qCanupo, classifier.cpp), little-endian, 4-byte fields:
#   [uint32 9999, uint32 descriptor id, uint32 dims per scale]  (only when not the defaults 1, 2)
#   uint32 scale count S, float32 scales[S]
#   uint32 classifier count C, then per classifier:
#     int32 class1, int32 class2, float32 w1[S*dims + 1], float32 w2[S*dims + 1],
#     uint32 path size K, float32 path[K][2], float32 refPointPos[2], float32 refPointNeg[2],
#     float32 absMaxXY, float32 axisScaleRatio   (display settings of the plugin: read, unused)
_NEW_HEADER = 9999
_DESC_DIMENSIONALITY = 1


class _Reader:
    def __init__(self, path: Path, data: bytes):
        self.path, self.data, self.pos = path, data, 0

    def take(self, fmt: str, count: int = 1):
        size = struct.calcsize("<" + fmt) * count
        if self.pos + size > len(self.data):
            raise ClassifierFileError(f"{self.path}: truncated .prm file ({len(self.data)} bytes; needs more at "
                                      f"byte {self.pos})")
        out = struct.unpack_from(f"<{count}{fmt}", self.data, self.pos)
        self.pos += size
        return out if count > 1 else out[0]


def _read_prm(path: Path) -> Classifier:
    r = _Reader(path, read_small_bytes(path, CLASSIFIER_KIND, error=ClassifierFileError))
    scale_count, descriptor, dims = r.take("I"), _DESC_DIMENSIONALITY, 2
    if scale_count == _NEW_HEADER:
        descriptor, dims, scale_count = r.take("I"), r.take("I"), r.take("I")
    if descriptor != _DESC_DIMENSIONALITY or dims != 2:
        raise ClassifierFileError(f"{path}: qCANUPO descriptor {descriptor} with {dims} values per scale; only "
                                  f"the dimensionality descriptor (1, 2 values per scale) is supported")
    if not 0 < scale_count <= MAX_SCALES:
        raise ClassifierFileError(f"{path}: not a qCANUPO .prm file ({scale_count} scales)")
    scales = np.atleast_1d(np.array(r.take("f", scale_count), dtype=np.float64))
    count = r.take("I")
    if not 0 < count <= MAX_CLASSIFIERS:
        raise ClassifierFileError(f"{path}: not a qCANUPO .prm file ({count} classifiers)")
    dim = scale_count * dims + 1
    binaries = []
    for _ in range(count):
        c1, c2 = r.take("i"), r.take("i")
        w1 = np.array(r.take("f", dim), dtype=np.float64)
        w2 = np.array(r.take("f", dim), dtype=np.float64)
        k = r.take("I")
        if not 2 <= k <= MAX_BOUNDARY_POINTS:
            raise ClassifierFileError(f"{path}: classifier {c1}/{c2} has a boundary of {k} points (>= 2 needed)")
        pts = np.array(r.take("f", 2 * k), dtype=np.float64).reshape(k, 2)
        ref_pos = np.array(r.take("f", 2), dtype=np.float64)
        ref_neg = np.array(r.take("f", 2), dtype=np.float64)
        abs_max, ratio = r.take("f"), r.take("f")
        binaries.append(BinaryClassifier(str(c1), str(c2), w1, w2, pts, ref_pos, ref_neg,
                                         {"absMaxXY": abs_max, "axisScaleRatio": ratio}))
    if r.pos != len(r.data):
        raise ClassifierFileError(f"{path}: {len(r.data) - r.pos} bytes left after the last classifier: not a "
                                  f"qCANUPO .prm file or a descriptor this reader does not know")
    labels: list[str] = []
    for b in binaries:
        for c in (b.class1, b.class2):
            if c not in labels:
                labels.append(c)
    return _checked(path, Classifier(scales, binaries, labels, 3, {"read_from": "qCANUPO .prm"}, "prm"))


def _prm_bytes(path, clf: Classifier) -> bytes:
    out = [struct.pack("<I", len(clf.scales)), struct.pack(f"<{len(clf.scales)}f", *clf.scales),
           struct.pack("<I", len(clf.binaries))]
    for b in clf.binaries:
        try:
            c1, c2 = int(b.class1), int(b.class2)
        except ValueError:
            raise ClassifierFileError(f"{path}: a .prm file stores integer classes; {b.class1!r}/{b.class2!r} are "
                                      f"not (train with integer labels, or write JSON)") from None
        out += [struct.pack("<ii", c1, c2), struct.pack(f"<{len(b.w1)}f", *b.w1),
                struct.pack(f"<{len(b.w2)}f", *b.w2), struct.pack("<I", len(b.path)),
                struct.pack(f"<{2 * len(b.path)}f", *np.asarray(b.path).ravel()),
                struct.pack("<2f", *b.ref_pos), struct.pack("<2f", *b.ref_neg),
                struct.pack("<ff", float(b.info.get("absMaxXY", 0.0)), float(b.info.get("axisScaleRatio", 1.0)))]
    return b"".join(out)


# ----------------------------------------------------------------------------------- files

def is_prm(path) -> bool:
    return Path(path).suffix.lower() == ".prm"


def read_classifier(path: str | os.PathLike) -> Classifier:
    """Reads our JSON classifier, or a CloudCompare qCANUPO .prm file (by extension). A forged or
    damaged file of either kind raises ClassifierFileError naming it, never another exception."""
    path = Path(path)
    if is_prm(path):
        return _read_prm(path)
    d = read_small_json(path, CLASSIFIER_KIND, error=ClassifierFileError)
    if not isinstance(d, dict):
        raise ClassifierFileError(f"{path}: not a classifier file (JSON without an object)")
    return _from_json(path, d)


def classifier_bytes(path: str | os.PathLike, clf: Classifier) -> bytes:
    """The file write_classifier writes at `path`: .prm (qCANUPO binary) by extension, else JSON."""
    path = Path(path)
    return _prm_bytes(path, clf) if is_prm(path) else (json.dumps(_to_json(clf), indent=1) + "\n").encode()


def write_classifier(path: str | os.PathLike, clf: Classifier) -> None:
    """Writes `clf` atomically: .prm (qCANUPO binary, integer classes only) by extension, else JSON."""
    path = Path(path)
    data = classifier_bytes(path, clf)
    try:
        with atomic_output(path) as tmp:
            Path(tmp).write_bytes(data)
    except OSError as e:
        raise ClassifierFileError(f"{path}: cannot write the classifier: {e.strerror or e}") from None
