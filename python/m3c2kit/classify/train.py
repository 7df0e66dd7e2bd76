"""Training a CANUPO classifier (Brodu & Lague 2012, section 3; docs/algorithm.md).

For each pair of classes: a linear discriminant (scikit-learn's LDA, Ledoit-Wolf shrinkage,
equal priors) of the multi-scale descriptors gives the plane's first axis; the same on the
descriptors with that direction removed gives the second. Each axis is scaled to unit pooled
within-class standard deviation and centred between the class means, so that distances in the
plane, hence the confidence, are in units of the classes' own spread. The boundary is the line of
that plane with the best balanced accuracy on the training samples (angles every degree on up
to 20,000 of them, the LDA's own line preferred on ties; its offset from all of them).
"""
from __future__ import annotations

import numpy as np

from ..base.errors import UsageError
from .apply import predict_vectors
from .features import features
from .model import BinaryClassifier, Classifier

EXTRA_HINT = "pip install 'm3c2kit[classify]'"
ANGLES_DEG = np.arange(-89.0, 90.0, 1.0)
BOUNDARY_SAMPLE = 20_000  # points that choose the boundary's angle (seeded subsample beyond)


def _lda():
    try:
        from sklearn.discriminant_analysis import LinearDiscriminantAnalysis
    except ImportError:
        raise UsageError(f"m3c2 classify train needs scikit-learn, which is not installed: {EXTRA_HINT} "
                         f"(the [classify] extra)") from None
    return LinearDiscriminantAnalysis(solver="lsqr", shrinkage="auto", priors=[0.5, 0.5])


def best_split(s: np.ndarray, positive: np.ndarray) -> tuple[float, float]:
    """(balanced accuracy, threshold) of the best split `s >= threshold` -> positive class, the
    threshold halfway between the two values it separates."""
    order = np.argsort(s, kind="stable")
    s, positive = s[order], positive[order]
    n_pos = int(positive.sum())
    n_neg = len(s) - n_pos
    # Split k: the first k points (below the threshold) negative.
    neg_below = np.concatenate([[0], np.cumsum(~positive)])
    pos_below = np.concatenate([[0], np.cumsum(positive)])
    ba = 0.5 * ((n_pos - pos_below) / n_pos + neg_below / n_neg)
    valid = np.ones(len(s) + 1, dtype=bool)
    valid[1:-1] = s[1:] > s[:-1]  # a threshold only between distinct values
    ba = np.where(valid, ba, -1.0)
    k = int(np.argmax(ba))
    if k == 0:
        threshold = s[0] - 1.0
    elif k == len(s):
        threshold = s[-1] + 1.0
    else:
        threshold = 0.5 * (s[k - 1] + s[k])
    return float(ba[k]), float(threshold)


def _unit_axis(X, w, is_b):
    """Weights (with constant) of the axis X @ w scaled to unit pooled within-class std and
    centred between the class means; None when the axis separates nothing (zero spread)."""
    u = X @ w
    a, b = u[~is_b], u[is_b]
    pooled = ((len(a) - 1) * a.var(ddof=1) + (len(b) - 1) * b.var(ddof=1)) / max(len(u) - 2, 1)
    if not (pooled > 0 and np.isfinite(pooled)):
        return None
    w = w / np.sqrt(pooled)
    centre = 0.5 * (a.mean() + b.mean()) / np.sqrt(pooled)
    return np.append(w, -centre)


def fit_pair(XA: np.ndarray, XB: np.ndarray, class1: str, class2: str, seed: int = 0) -> BinaryClassifier:
    """The two-class classifier: class1 (XA) on the negative side, class2 (XB) on the positive."""
    X = np.vstack([XA, XB])
    is_b = np.r_[np.zeros(len(XA), bool), np.ones(len(XB), bool)]
    lda = _lda().fit(X, is_b)
    w = lda.coef_.ravel().astype(float)
    axis1 = _unit_axis(X, w, is_b) if np.linalg.norm(w) > 0 else None
    if axis1 is None:
        raise UsageError(f"classes {class1!r} and {class2!r} have identical descriptors at every scale: no "
                         f"projection separates them")
    if np.mean(X[is_b] @ axis1[:-1]) < np.mean(X[~is_b] @ axis1[:-1]):
        axis1 = -axis1
    # Second axis: the discriminant of what the first leaves, orthogonal to it.
    unit = w / np.linalg.norm(w)
    X2 = X - np.outer(X @ unit, unit)
    w2 = None
    try:
        w2 = _lda().fit(X2, is_b).coef_.ravel().astype(float)
        w2 -= (w2 @ unit) * unit
    except (ValueError, np.linalg.LinAlgError):
        w2 = None
    if w2 is None or not np.linalg.norm(w2) > 1e-12 * np.linalg.norm(w):
        # Nothing discriminant left: the direction of largest remaining variance.
        w2 = np.linalg.svd(X2 - X2.mean(axis=0), full_matrices=False)[2][0]
        w2 -= (w2 @ unit) * unit
    # Within-class decorrelated from the first axis (w2 - beta w1): the plane shows the spread the
    # first axis leaves, not a copy of it.
    u, v = X @ axis1[:-1], X @ w2
    du = np.where(is_b, u - u[is_b].mean(), u - u[~is_b].mean())
    dv = np.where(is_b, v - v[is_b].mean(), v - v[~is_b].mean())
    w2 = w2 - (du @ dv) / (du @ du) * axis1[:-1]
    axis2 = _unit_axis(X, w2, is_b)
    if axis2 is None:
        axis2 = np.zeros_like(axis1)
    P = np.stack([X @ axis1[:-1] + axis1[-1], X @ axis2[:-1] + axis2[-1]], axis=1)
    sample = np.arange(len(P))
    if len(P) > BOUNDARY_SAMPLE:
        sample = np.sort(np.random.default_rng(seed).choice(len(P), BOUNDARY_SAMPLE, replace=False))
    best = (-1.0, 0.0, 0.0)
    for theta in sorted(np.deg2rad(ANGLES_DEG), key=abs):  # ties keep the angle nearest the LDA's
        n = np.array([np.cos(theta), np.sin(theta)])
        ba, t = best_split(P[sample] @ n, is_b[sample])
        if ba > best[0]:
            best = (ba, theta, t)
    theta = best[1]
    n = np.array([np.cos(theta), np.sin(theta)])
    ba, t = best_split(P @ n, is_b)  # the threshold from every point
    along = np.array([-n[1], n[0]])
    on_line = t * n
    path = np.stack([on_line - along, on_line + along])
    info = {"balanced_accuracy": ba, "boundary_angle_deg": float(np.rad2deg(theta)), "samples": [len(XA), len(XB)]}
    return BinaryClassifier(class1, class2, axis1, axis2, path, on_line + n, on_line - n, info)


def scale_power(XA: np.ndarray, XB: np.ndarray, scales) -> list[dict]:
    """Discriminative power of each scale alone: the balanced accuracy of the best split of the
    LDA projection of its two descriptor values (training samples)."""
    X = np.vstack([XA, XB])
    is_b = np.r_[np.zeros(len(XA), bool), np.ones(len(XB), bool)]
    out = []
    for k, scale in enumerate(scales):
        cols = X[:, 2 * k:2 * k + 2]
        try:
            s = cols @ _lda().fit(cols, is_b).coef_.ravel()
            ba = best_split(s, is_b)[0]
        except (ValueError, np.linalg.LinAlgError):
            ba = 0.5
        out.append({"scale": float(scale), "balanced_accuracy": max(ba, 1.0 - ba)})
    return out


def _sample_features(xyz, labels, scales, min_points, threads, max_per_class, rng):
    """Descriptors of the labelled points of one sample cloud (neighbourhoods in that cloud)."""
    labels = np.asarray(labels, dtype=object)
    chosen = []
    for name in sorted(set(labels[labels != None].tolist()) - {""}):  # noqa: E711
        idx = np.flatnonzero(labels == name)
        if max_per_class and len(idx) > max_per_class:
            idx = np.sort(rng.choice(idx, max_per_class, replace=False))
        chosen.append(idx)
    if not chosen:
        return np.empty((0, 2 * len(scales))), np.empty(0, dtype=object), 0
    idx = np.concatenate(chosen)
    f = features(xyz, scales, xyz[idx], min_points=min_points, threads=threads)
    ok = f.ok
    return f.vector()[ok], labels[idx][ok], int((~ok).sum())


def train(samples, scales, *, min_points: int = 3, threads: int = 0, max_per_class: int | None = 50_000,
          seed: int = 0) -> Classifier:
    """A classifier from labelled samples: each sample is (xyz, label) with one label for every
    point, or (xyz, labels) with one label per point ("" or None: not used). Features of each
    sample are computed in its own cloud. Scales are diameters; they are stored largest first
    (CANUPO's order). max_per_class: points of each class drawn (seeded) per sample."""
    return train_with_samples(samples, scales, min_points=min_points, threads=threads,
                              max_per_class=max_per_class, seed=seed)[0]


def train_with_samples(samples, scales, *, min_points=3, threads=0, max_per_class=50_000, seed=0):
    """train(), also returning the training descriptors and their labels (for the plot)."""
    scales = np.sort(np.asarray(scales, dtype=float).ravel())[::-1]
    rng = np.random.default_rng(seed)
    vectors, names, dropped = [], [], 0
    for xyz, labels in samples:
        xyz = np.ascontiguousarray(xyz, dtype=np.float64)
        if isinstance(labels, str):
            labels = np.full(len(xyz), labels, dtype=object)
        v, y, d = _sample_features(xyz, labels, scales, min_points, threads, max_per_class, rng)
        vectors.append(v)
        names.append(y)
        dropped += d
    X = np.vstack(vectors)
    y = np.concatenate(names).astype(str)
    classes = list(dict.fromkeys(y.tolist()))
    if len(classes) < 2:
        raise UsageError(f"training needs at least two classes with usable points, got {classes or 'none'} "
                         f"({dropped} labelled points had too few neighbours at the largest scale)")
    for c in classes:
        if np.count_nonzero(y == c) < 2:
            raise UsageError(f"class {c!r} has fewer than 2 usable training points")
    binaries, power = [], {}
    for i in range(len(classes)):
        for j in range(i + 1, len(classes)):
            XA, XB = X[y == classes[i]], X[y == classes[j]]
            b = fit_pair(XA, XB, classes[i], classes[j], seed)
            b.info["scale_power"] = scale_power(XA, XB, scales)
            binaries.append(b)
            power[f"{classes[i]}/{classes[j]}"] = b.info["scale_power"]
    clf = Classifier(scales, binaries, classes, min_points)
    p = predict_vectors(clf, X, np.ones(len(X), bool))
    truth = np.array([classes.index(c) for c in y])
    recall = [float(np.mean(p.index[truth == k] == k)) for k in range(len(classes))]
    clf.info = {"training": {"points": {c: int(np.count_nonzero(y == c)) for c in classes},
                             "points_without_features": dropped, "recall": dict(zip(classes, recall)),
                             "balanced_accuracy": float(np.mean(recall))},
                "scale_power": power}
    return clf, X, y
