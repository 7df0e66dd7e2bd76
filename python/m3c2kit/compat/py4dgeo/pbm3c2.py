"""py4dgeo 1.2.0's PBM3C2 on m3c2kit's PB-M3C2 (m3c2kit.pbm3c2; docs/pbm3c2.md): epochs whose
``additional_dimensions["segment_id"]`` gives each point's segment, the same methods, the same
segment-id remapping and the same DataFrame. The numbers are m3c2kit's, which differ from
py4dgeo's where py4dgeo's are wrong or arbitrary (docs/pbm3c2.md, "Differences from py4dgeo"):
the distance along the oriented normal (py4dgeo's normal has an arbitrary sign), eq. (1)'s LOD
with the compared plane's lever, σ with n - 3, and the random forest's pair kept only when the
forest accepts it (py4dgeo keeps its best candidate even when rejected)."""
from __future__ import annotations

import numpy as np

from ...analysis.pbm3c2_forest import forest_pairs
from ...base.errors import UsageError
from ...engine import planes
from .epoch import Epoch
from .errors import Py4DGeoError, translated

__all__ = ["PBM3C2"]

#: py4dgeo's result columns, in its order.
COLUMNS = ("epoch0_original_id", "epoch1_original_id", "epoch0_segment_id", "epoch1_segment_id", "distance",
           "uncertainty")
_METRIC_COLUMNS = ("cog_x", "cog_y", "cog_z", "normal_x", "normal_y", "normal_z", "linearity", "planarity",
                   "sphericity", "roughness", "num_points")


def _pandas():
    try:
        import pandas
    except ImportError:
        raise UsageError("PBM3C2 returns pandas DataFrames, as py4dgeo's: pip install pandas") from None
    return pandas


def _segment_ids(epoch, name: str) -> np.ndarray:
    dims = getattr(epoch, "additional_dimensions", None)
    if dims is None or getattr(dims, "dtype", None) is None or dims.dtype.names is None \
            or "segment_id" not in dims.dtype.names:
        raise UsageError(f"PBM3C2: {name} has no segment_id in additional_dimensions (read it with "
                         "additional_dimensions={3: 'segment_id'}); py4dgeo's PBM3C2 takes segmented epochs")
    return np.asarray(dims["segment_id"])


def _read_correspondences(path) -> np.ndarray:
    try:
        values = np.genfromtxt(path, delimiter=",", dtype=np.float64)
    except (OSError, ValueError) as e:
        raise Py4DGeoError(f"Failed to read correspondence file '{path}': {e}") from None
    values = values.reshape(1, -1) if values.ndim == 1 else values
    if values.ndim != 2 or values.shape[1] < 2:
        raise Py4DGeoError(f"The correspondence file must contain at least two columns (got {values.shape}).")
    return values


class PBM3C2:
    """py4dgeo's PBM3C2 (Zahs et al. 2022): ``PBM3C2(registration_error=...).run(epoch0, epoch1,
    correspondences_file=..., apply_ids=..., search_radius=..., correspondence_method=...)``."""

    _VALID_CORRESPONDENCE_METHODS = ("random_forest", "nearest_neighbor")
    _VALID_CORRESPONDENCE_FILTERS = ("none", "mutual_nearest_neighbors")

    def __init__(self, registration_error=0.0):
        self.registration_error = registration_error
        self.random_state = 42  # py4dgeo's RandomForestClassifier(random_state=42)
        self.epoch0_segment_metrics = self.epoch1_segment_metrics = None
        self.epoch0_segments = self.epoch1_segments = None
        self.correspondences = None
        self.epoch0_id_mapping = self.epoch1_id_mapping = None
        self.epoch0_reverse_mapping = self.epoch1_reverse_mapping = None
        self._tables = None
        self._training = None
        self._rows = None  # the paired (reference rows, compared rows) of the last correspondences (_keep)

    @staticmethod
    @translated
    def preprocess_epochs(epoch0, epoch1, correspondences_file=None):
        """py4dgeo's remapping: epoch 0's ids become 1..K0 and epoch 1's K0+1..K0+K1 (ascending original
        order); the correspondences file's ids are remapped alike. Returns py4dgeo's 7-tuple."""
        ids0, ids1 = np.unique(_segment_ids(epoch0, "epoch0")), np.unique(_segment_ids(epoch1, "epoch1"))
        mapping0 = dict(zip(ids0.tolist(), range(1, len(ids0) + 1)))
        mapping1 = dict(zip(ids1.tolist(), range(len(ids0) + 1, len(ids0) + len(ids1) + 1)))
        remapped = None
        if correspondences_file is not None:
            values = _read_correspondences(correspondences_file)
            known = np.isin(values[:, 0], ids0) & np.isin(values[:, 1], ids1)
            if not known.any():
                raise Py4DGeoError("No valid correspondences remain after filtering. Please verify that segment IDs "
                                   "in the correspondence file match those in the input epochs.")
            remapped = values[known].copy()
            remapped[:, 0] = [mapping0[v] for v in values[known, 0].tolist()]
            remapped[:, 1] = [mapping1[v] for v in values[known, 1].tolist()]
        out = []
        for epoch, mapping in ((epoch0, mapping0), (epoch1, mapping1)):
            dims = epoch.additional_dimensions.copy()
            new = np.array([mapping[v] for v in dims["segment_id"].tolist()], dtype=np.int64)
            dims = _with_column(dims, "segment_id", new)
            out.append(Epoch(np.array(epoch.cloud, copy=True), additional_dimensions=dims))
        reverse0 = {v: k for k, v in mapping0.items()}
        reverse1 = {v: k for k, v in mapping1.items()}
        return out[0], out[1], remapped, mapping0, mapping1, reverse0, reverse1

    @translated
    def run(self, epoch0, epoch1, correspondences_file=None, apply_ids=None, search_radius=3.0,
            correspondence_method="random_forest", correspondence_filter="none"):
        """Segments' planes, correspondences and distances; returns py4dgeo's DataFrame (original and
        remapped ids, distance, uncertainty) of the pairs found for `apply_ids` (original epoch-0 ids)."""
        if correspondence_method not in self._VALID_CORRESPONDENCE_METHODS:
            raise Py4DGeoError("Invalid correspondence_method. Use one of: 'random_forest', 'nearest_neighbor'.")
        if correspondence_filter not in self._VALID_CORRESPONDENCE_FILTERS:
            raise Py4DGeoError("Invalid correspondence_filter. Use one of: 'none', 'mutual_nearest_neighbors'.")
        if correspondence_method == "random_forest" and correspondences_file is None:
            raise Py4DGeoError("correspondences_file is required when correspondence_method='random_forest'.")
        forest = correspondence_method == "random_forest"
        (new0, new1, training, self.epoch0_id_mapping, self.epoch1_id_mapping, self.epoch0_reverse_mapping,
         self.epoch1_reverse_mapping) = self.preprocess_epochs(epoch0, epoch1,
                                                               correspondences_file if forest else None)
        self._measure(new0, new1)
        if forest:
            self.train(training)
        ids = np.unique(_segment_ids(epoch0, "epoch0")) if apply_ids is None else np.asarray(apply_ids)
        new_ids = [self.epoch0_id_mapping[i] for i in ids.tolist() if i in self.epoch0_id_mapping]
        if forest:
            self.apply(new_ids, search_radius=search_radius)
        else:
            self.apply_nearest_neighbor(new_ids, search_radius=search_radius,
                                        correspondence_filter=correspondence_filter)
        if self.correspondences is None or self.correspondences.empty:
            return self.correspondences
        distance, uncertainty = self._changes()
        frame = self.correspondences
        frame["distance"], frame["uncertainty"] = distance, uncertainty
        frame["epoch0_original_id"] = frame["epoch0_segment_id"].map(self.epoch0_reverse_mapping)
        frame["epoch1_original_id"] = frame["epoch1_segment_id"].map(self.epoch1_reverse_mapping)
        self.correspondences = frame[list(COLUMNS)]
        return self.correspondences

    def _measure(self, epoch0, epoch1) -> None:
        """The segments' planes (the engine's tables) and py4dgeo's metric frames."""
        pd = _pandas()
        self._tables = []
        frames, segments = [], []
        for epoch in (epoch0, epoch1):
            cloud = np.asarray(epoch.cloud, dtype=np.float64)
            labels = np.asarray(epoch.additional_dimensions["segment_id"], dtype=np.int64)
            table = planes.plane_segments(cloud, labels)
            self._tables.append(table)
            frames.append(pd.DataFrame(_metrics(table), index=pd.Index(table["label"], name="segment_id")))
            order = np.argsort(labels, kind="stable")
            bounds = np.searchsorted(labels[order], table["label"])
            ends = np.r_[bounds[1:], len(order)]
            segments.append({int(s): {"points": cloud[order[b:e]]} for s, b, e in zip(table["label"], bounds, ends)})
        self.epoch0_segment_metrics, self.epoch1_segment_metrics = frames
        self.epoch0_segments, self.epoch1_segments = segments

    @translated
    def train(self, correspondences):
        """Keeps the labelled pairs (remapped ids, label in the third column) for apply()."""
        values = np.asarray(correspondences, dtype=np.float64)
        if values.ndim != 2 or values.shape[1] < 3:
            raise ValueError("Training data is missing positive or negative examples.")
        if not ((values[:, 2] == 1).any() and (values[:, 2] == 0).any()):
            raise ValueError("Training data is missing positive or negative examples.")
        self._training = values[:, :3]

    @translated
    def apply(self, apply_ids, search_radius=3.0):
        """The random forest's pairs of `apply_ids` (remapped epoch-0 ids) within `search_radius`."""
        if self._training is None:
            raise Py4DGeoError("PBM3C2.apply needs train() first")
        found = forest_pairs(self._tables[0], self._tables[1], self._training, search_radius, self.random_state)
        self._keep(apply_ids, found)

    @translated
    def apply_nearest_neighbor(self, apply_ids, search_radius=10.0, correspondence_filter="none"):
        """py4dgeo's nearest-centroid pairs within `search_radius` (no angle gate), mutual with
        correspondence_filter='mutual_nearest_neighbors'."""
        if correspondence_filter not in self._VALID_CORRESPONDENCE_FILTERS:
            raise Py4DGeoError("Invalid correspondence_filter. Use one of: 'none', 'mutual_nearest_neighbors'.")
        found = planes.nearest_segments(self._tables[0], self._tables[1], {
            "search_radius": float(search_radius), "max_angle_degrees": 90.0,  # 90: every plane passes
            "mutual": correspondence_filter == "mutual_nearest_neighbors"})
        self._keep(apply_ids, found)

    def _keep(self, apply_ids, found: dict) -> None:
        pd = _pandas()
        labels0, labels1 = self._tables[0]["label"], self._tables[1]["label"]
        wanted = np.isin(labels0, np.asarray(list(apply_ids), dtype=np.int64))
        paired = wanted & (np.asarray(found["compared"]) >= 0)
        self._rows = np.flatnonzero(paired), np.asarray(found["compared"])[paired]
        self.correspondences = pd.DataFrame({"epoch0_segment_id": labels0[self._rows[0]],
                                             "epoch1_segment_id": labels1[self._rows[1]]})

    def _changes(self):
        pairs = np.full(len(self._tables[0]["label"]), -1, dtype=np.int64)
        pairs[self._rows[0]] = self._rows[1]
        changes = planes.plane_changes(self._tables[0], self._tables[1], pairs,
                                       {"registration_error": float(self.registration_error)})
        return np.asarray(changes["distance"])[self._rows[0]], np.asarray(changes["lod"])[self._rows[0]]

    def get_original_ids(self, new_epoch0_id=None, new_epoch1_id=None):
        """py4dgeo's: the original ids of remapped ones (a tuple when both are given)."""
        found = [mapping.get(value) for value, mapping in ((new_epoch0_id, self.epoch0_reverse_mapping),
                                                           (new_epoch1_id, self.epoch1_reverse_mapping))
                 if value is not None]
        return tuple(found) if len(found) > 1 else (found[0] if found else None)

    def get_new_ids(self, orig_epoch0_id=None, orig_epoch1_id=None):
        """py4dgeo's: the remapped ids of original ones (a tuple when both are given)."""
        found = [mapping.get(value) for value, mapping in ((orig_epoch0_id, self.epoch0_id_mapping),
                                                           (orig_epoch1_id, self.epoch1_id_mapping))
                 if value is not None]
        return tuple(found) if len(found) > 1 else (found[0] if found else None)

    @translated
    def visualize_correspondences(self, epoch0_segment_id=None, use_original_ids=True, show_all=False,
                                  num_samples=10, figsize=(12, 10), elev=30, azim=45):
        """py4dgeo's plot of paired segments (matplotlib): returns (fig, ax)."""
        from .pbm3c2_plot import plot_correspondences
        return plot_correspondences(self, epoch0_segment_id, use_original_ids, show_all, num_samples, figsize,
                                    elev, azim)


def _with_column(dims: np.ndarray, name: str, values: np.ndarray) -> np.ndarray:
    """`dims` (a structured array) with column `name` replaced by `values` (its dtype too)."""
    fields = [(n, values.dtype if n == name else dims.dtype[n]) for n in dims.dtype.names]
    out = np.empty(len(dims), dtype=fields)
    for n in dims.dtype.names:
        out[n] = values if n == name else dims[n]
    return out


def _metrics(table: dict) -> dict:
    """py4dgeo's segment metrics from the engine's table: linearity, planarity and sphericity from the
    eigenvalues (0 where they sum to 0, as py4dgeo)."""
    ev = np.asarray(table["eigenvalues"])
    total = ev.sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        shares = np.where(total[:, None] > 0, ev / total[:, None], 0.0)
    centroid, normal = np.asarray(table["centroid"]), np.asarray(table["normal"])
    values = (centroid[:, 0], centroid[:, 1], centroid[:, 2], normal[:, 0], normal[:, 1], normal[:, 2],
              shares[:, 0] - shares[:, 1], shares[:, 1] - shares[:, 2], shares[:, 2], np.asarray(table["roughness"]),
              np.asarray(table["count"]).astype(np.int64))
    return dict(zip(_METRIC_COLUMNS, values))
