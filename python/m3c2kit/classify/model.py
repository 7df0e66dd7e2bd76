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

from ..errors import M3C2Error
from ..io.atomic import atomic_output

FORMAT = "m3c2kit-canupo-classifier"
VERSION = 1


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


def _from_json(path: Path, d: dict) -> Classifier:
    def need(obj, key, where="the file"):
        if key not in obj:
            raise ClassifierFileError(f"{path}: {where} has no {key!r}")
        return obj[key]
    if d.get("format") != FORMAT:
        raise ClassifierFileError(f"{path}: not an m3c2kit classifier (format {d.get('format')!r}, "
                                  f"expected {FORMAT!r}; CloudCompare classifiers end in .prm)")
    if int(d.get("version", 0)) > VERSION:
        raise ClassifierFileError(f"{path}: classifier version {d['version']} is newer than this m3c2kit "
                                  f"reads ({VERSION})")
    scales = np.asarray(need(d, "scales"), float)
    dim = 2 * len(scales) + 1
    binaries = []
    for k, c in enumerate(need(d, "classifiers")):
        where = f"classifier {k}"
        b = BinaryClassifier(str(need(c, "class1", where)), str(need(c, "class2", where)),
                             np.asarray(need(c, "w1", where), float), np.asarray(need(c, "w2", where), float),
                             np.asarray(need(c, "path", where), float).reshape(-1, 2),
                             np.asarray(need(c, "ref_pos", where), float), np.asarray(need(c, "ref_neg", where), float),
                             c.get("info", {}))
        if len(b.w1) != dim or len(b.w2) != dim or len(b.path) < 2:
            raise ClassifierFileError(f"{path}: {where} has {len(b.w1)} and {len(b.w2)} weights for {len(scales)} "
                                      f"scales (expected {dim}) and {len(b.path)} boundary points (>= 2)")
        binaries.append(b)
    return _checked(path, Classifier(scales, binaries, [str(x) for x in need(d, "labels")],
                                     int(d.get("min_points", 3)), d.get("info", {}), "json"))


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
    r = _Reader(path, path.read_bytes())
    scale_count, descriptor, dims = r.take("I"), _DESC_DIMENSIONALITY, 2
    if scale_count == _NEW_HEADER:
        descriptor, dims, scale_count = r.take("I"), r.take("I"), r.take("I")
    if descriptor != _DESC_DIMENSIONALITY or dims != 2:
        raise ClassifierFileError(f"{path}: qCANUPO descriptor {descriptor} with {dims} values per scale; only "
                                  f"the dimensionality descriptor (1, 2 values per scale) is supported")
    if not 0 < scale_count <= 10000:
        raise ClassifierFileError(f"{path}: not a qCANUPO .prm file ({scale_count} scales)")
    scales = np.atleast_1d(np.array(r.take("f", scale_count), dtype=np.float64))
    count = r.take("I")
    if not 0 < count <= 10000:
        raise ClassifierFileError(f"{path}: not a qCANUPO .prm file ({count} classifiers)")
    dim = scale_count * dims + 1
    binaries = []
    for _ in range(count):
        c1, c2 = r.take("i"), r.take("i")
        w1 = np.array(r.take("f", dim), dtype=np.float64)
        w2 = np.array(r.take("f", dim), dtype=np.float64)
        k = r.take("I")
        if not 2 <= k <= 100000:
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
    """Reads our JSON classifier, or a CloudCompare qCANUPO .prm file (by extension)."""
    path = Path(path)
    try:
        if is_prm(path):
            return _read_prm(path)
        text = path.read_text(encoding="utf-8")
    except OSError as e:
        raise ClassifierFileError(f"{path}: cannot read the classifier: {e.strerror or e}") from None
    try:
        d = json.loads(text)
    except (ValueError, UnicodeDecodeError) as e:
        raise ClassifierFileError(f"{path}: not a classifier file (JSON: {e})") from None
    if not isinstance(d, dict):
        raise ClassifierFileError(f"{path}: not a classifier file (JSON without an object)")
    try:
        return _from_json(path, d)
    except (TypeError, ValueError) as e:
        raise ClassifierFileError(f"{path}: malformed classifier: {e}") from None


def write_classifier(path: str | os.PathLike, clf: Classifier) -> None:
    """Writes `clf` atomically: .prm (qCANUPO binary, integer classes only) by extension, else JSON."""
    path = Path(path)
    data = _prm_bytes(path, clf) if is_prm(path) else (json.dumps(_to_json(clf), indent=1) + "\n").encode()
    try:
        with atomic_output(path) as tmp:
            Path(tmp).write_bytes(data)
    except OSError as e:
        raise ClassifierFileError(f"{path}: cannot write the classifier: {e.strerror or e}") from None
