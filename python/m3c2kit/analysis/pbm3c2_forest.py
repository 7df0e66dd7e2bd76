"""PB-M3C2's learned correspondences (Zahs et al. 2022, 3.4): a random forest (scikit-learn, as the
paper) trained on labelled segment pairs, applied to every compared segment within the search
radius of a reference segment; the most probable candidate is its pair when the forest gives it a
probability of at least 1/2 (py4dgeo takes the most probable even when the forest rejects it: a
pair of different surfaces is then measured as change). Features are py4dgeo's, from the engine
(include/m3c2/pbm3c2.hpp, pair_features)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..base.errors import UsageError
from ..engine import planes

EXTRA_HINT = "pip install 'm3c2kit[classify]'"
#: The forest's size (py4dgeo's and scikit-learn's default).
TREES = 100
#: A candidate is a pair when the forest's probability reaches this.
ACCEPT = 0.5
#: PairStatus codes (include/m3c2/pbm3c2.hpp).
_PAIRED, _NO_PLANE, _NO_CANDIDATE, _NOT_CLASSIFIED = 0, 1, 2, 4
_FEATURES = ("centroid_distance", "normal_angle", "roughness_difference")


def _forest(seed: int):
    try:
        from sklearn.ensemble import RandomForestClassifier
    except ImportError:
        raise UsageError(f"PB-M3C2's random forest needs scikit-learn, which is not installed: {EXTRA_HINT} "
                         f"(or pair segments by the geometric rule: correspondence 'nearest')") from None
    # n_jobs=1: the trees are the same for any n_jobs given the seed, but one job spares a pool.
    return RandomForestClassifier(n_estimators=TREES, random_state=seed, n_jobs=1)


def _matrix(features: dict) -> np.ndarray:
    return np.column_stack([np.asarray(features[name]) for name in _FEATURES])


class TrainingPairs(np.ndarray):
    """Labelled pairs read from a file: the rows, with where each came from (`where[k]`: "PATH, line
    N"), so that a pair refused later names its line."""
    where: list


def read_training(path) -> TrainingPairs:
    """py4dgeo's correspondences file: `reference id, compared id, 1 or 0` per line (',' or ';'), '#'
    comments and blank lines skipped, a header allowed before the first pair."""
    path = Path(path)
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except OSError as e:
        raise UsageError(f"{path}: cannot read the training pairs: {e.strerror or e}") from None
    except UnicodeDecodeError:
        raise UsageError(f"{path}: the training pairs are not text (UTF-8)") from None
    rows, where = [], []
    for number, line in enumerate(lines, 1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        cells = [c.strip() for c in line.replace(";", ",").split(",")]
        try:
            values = [float(c) for c in cells[:3]]
        except ValueError:
            if not rows:
                continue  # a header
            raise UsageError(f"{path}, line {number}: expected 'reference id, compared id, 1 or 0', got "
                             f"{line.strip()[:80]!r}") from None
        if len(values) < 3:
            raise UsageError(f"{path}, line {number}: expected 3 columns (reference id, compared id, 1 or 0), got "
                             f"{len(cells)}")
        rows.append(values)
        where.append(f"{path}, line {number}")
    if not rows:
        raise UsageError(f"{path}: no training pairs")
    out = np.array(rows).view(TrainingPairs)
    out.where = where
    return out


def _row_name(training, k: int) -> str:
    where = getattr(training, "where", None)
    return where[k] if where else f"training row {k + 1}"


def training_rows(training, reference: dict, compared: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The labelled pairs as rows of the two segment tables and their labels (bool). A pair naming
    a segment absent from its cloud is refused, naming it (py4dgeo drops it with a print)."""
    values = np.asarray(training, dtype=np.float64)
    if values.ndim != 2 or values.shape[1] < 3 or len(values) == 0:
        raise UsageError(f"training must be rows of (reference segment id, compared segment id, 1 or 0), got shape "
                         f"{values.shape}")
    if not np.all(np.isfinite(values[:, :3])) or np.any(values[:, :3] != np.round(values[:, :3])):
        raise UsageError("training: segment ids and labels must be integers")
    labels = values[:, 2]
    if not np.all((labels == 0) | (labels == 1)):
        raise UsageError("training: the third column must be 1 (the same surface) or 0 (not)")
    rows = []
    for column, table, name in ((0, reference, "reference"), (1, compared, "compared")):
        known = np.asarray(table["label"])
        at = np.searchsorted(known, values[:, column].astype(np.int64))
        found = (at < len(known)) & (known[np.minimum(at, len(known) - 1)] == values[:, column]) if len(known) else \
            np.zeros(len(values), bool)
        if not found.all():
            k = int(np.argmin(found))
            raise UsageError(f"{_row_name(training, k)}: the {name} cloud has no segment {int(values[k, column])}")
        rows.append(at.astype(np.int64))
    usable = np.isfinite(np.asarray(reference["roughness"])[rows[0]]) & \
        np.isfinite(np.asarray(compared["roughness"])[rows[1]])
    if not usable.all():
        k = int(np.argmin(usable))
        raise UsageError(f"{_row_name(training, k)}: segment {int(values[k, 0])} or {int(values[k, 1])} has no plane "
                         f"(fewer than 4 points, or a line)")
    return rows[0], rows[1], labels.astype(bool)


def forest_pairs(reference: dict, compared: dict, training, search_radius: float, seed: int) -> dict:
    """compared (row or -1), status (PairStatus) and probability per reference row."""
    ref_rows, cmp_rows, same = training_rows(training, reference, compared)
    if same.all() or not same.any():
        raise UsageError("training needs both kinds of pairs: some labelled 1 (the same surface) and some 0")
    forest = _forest(seed)
    forest.fit(_matrix(planes.pair_features(reference, compared, ref_rows, cmp_rows)), same)
    n = len(reference["label"])
    out = {"compared": np.full(n, -1, dtype=np.int64), "probability": np.full(n, np.nan),
           "status": np.where(np.isfinite(np.asarray(reference["normal"])[:, 0]) if n else np.zeros(0, bool),
                              _NO_CANDIDATE, _NO_PLANE).astype(np.uint8)}
    candidates = planes.segment_candidates(reference, compared, search_radius)
    if len(candidates["reference"]) == 0:
        return out
    features = planes.pair_features(reference, compared, candidates["reference"], candidates["compared"])
    usable = np.all(np.isfinite(_matrix(features)), axis=1)
    probability = np.full(len(usable), -1.0)
    if usable.any():
        probability[usable] = forest.predict_proba(_matrix(features)[usable])[:, list(forest.classes_).index(True)]
    # The best candidate of each reference row: candidates come in row order; the first maximum wins.
    rows = np.asarray(candidates["reference"])
    starts = np.flatnonzero(np.r_[True, rows[1:] != rows[:-1]])
    best = np.maximum.reduceat(probability, starts)
    for start, end, value in zip(starts, np.r_[starts[1:], len(rows)], best):
        i = rows[start]
        if value < 0:
            continue  # no candidate with a plane and a roughness
        out["probability"][i] = value
        if value >= ACCEPT:
            out["compared"][i] = candidates["compared"][start + int(np.argmax(probability[start:end]))]
            out["status"][i] = _PAIRED
        else:
            out["status"][i] = _NOT_CLASSIFIED
    return out
