"""What SpatiotemporalAnalysis (analysis.py) reads from its store and folder (analysis_files.py):
the distances, uncertainties and time deltas add_epochs computed, the smoothing, the series 4D-OBC
runs on, and the seeds and objects region_growing.py keeps."""
from __future__ import annotations

import datetime

import numpy as np

from ...base.errors import UsageError
from ...series import analysis as series_analysis
from ...series import epochs as series_epochs
from ...series import store as series_store
from . import analysis_files as files
from . import util
from .errors import UnsupportedArgument, translated
from .m3c2 import UNCERTAINTY_DTYPE


def _by_hand(name: str) -> UnsupportedArgument:
    return UnsupportedArgument(
        f"SpatiotemporalAnalysis.{name}: m3c2kit's series store holds what add_epochs computed (or what m3c2 series "
        f"import read from a py4dgeo archive), so {name} cannot be set by hand; compute the epochs with "
        f"analysis.add_epochs(...), or open a py4dgeo archive holding them (docs/python.md)")


class AnalysisResults:
    """Mixin of SpatiotemporalAnalysis: needs its _location, _state, _cache, _has_store, _view,
    _save_state, corepoints, store and allow_pickle."""

    # -- what add_epochs computed --------------------------------------------------------------

    @property
    @translated
    def timedeltas(self) -> list[datetime.timedelta]:
        """Each epoch's time since the reference's."""
        if not self._has_store():
            return []
        times = self._view().read("time").astype(np.int64)
        reference = self._state["reference_timestamp"]
        if self._location.external_store:
            reference = series_store.attributes(self._location.store).get("reference_time") or None
        if reference is None or (times == series_store.NAT).any():
            raise UsageError(f"timedeltas: {self.store} does not know the time of its reference or of every epoch "
                             f"(give the epochs' times in an epoch list, PATH, TIME)")
        origin = series_epochs.microseconds(reference, "the reference's timestamp")
        return [datetime.timedelta(microseconds=int(t - origin)) for t in times]

    @timedeltas.setter
    def timedeltas(self, values) -> None:
        raise _by_hand("timedeltas")

    @property
    @translated
    def distances(self) -> np.ndarray:
        """(core points, epochs) float64, NaN where M3C2 gave no distance."""
        if "distances" not in self._cache:
            if self._has_store():
                self._cache["distances"] = self._view().read("distance").astype(np.float64)
            else:
                self._cache["distances"] = np.empty((len(self.corepoints.cloud), 0), dtype=np.float64)
        return self._cache["distances"]

    @distances.setter
    def distances(self, values) -> None:
        raise _by_hand("distances")

    @distances.deleter
    def distances(self) -> None:
        self._cache.pop("distances", None)

    @property
    @translated
    def uncertainties(self) -> np.ndarray:
        """(core points, epochs) records of py4dgeo's fields (M3C2's UNCERTAINTY_DTYPE)."""
        if "uncertainties" not in self._cache:
            n = len(self.corepoints.cloud)
            if not self._has_store():
                self._cache["uncertainties"] = np.empty((n, 0), dtype=UNCERTAINTY_DTYPE)
                return self._cache["uncertainties"]
            view = self._view()
            out = np.empty((n, view.n_epochs), dtype=UNCERTAINTY_DTYPE)
            out["lodetection"], out["spread1"], out["spread2"] = (view.read(a) for a in ("lod", "sigma1", "sigma2"))
            for field, name in (("num_samples1", "n1"), ("num_samples2", "n2")):
                counts = view.read(name)
                fill = series_store.INT_FILL[name][1]  # no cylinder searched: py4dgeo's count is 0
                out[field] = np.where(counts == fill, 0, counts)
            self._cache["uncertainties"] = out
        return self._cache["uncertainties"]

    @uncertainties.setter
    def uncertainties(self, values) -> None:
        raise _by_hand("uncertainties")

    @uncertainties.deleter
    def uncertainties(self) -> None:
        self._cache.pop("uncertainties", None)

    # -- smoothing --------------------------------------------------------------------------

    @property
    @translated
    def smoothed_distances(self) -> np.ndarray | None:
        """The store's smoothed_distance over the epochs it was computed from (fewer than the
        distances' after add_epochs, as py4dgeo's), None when not set or invalidated."""
        if self._state["smoothed_invalidated"] or not self._has_store():
            return None
        view = self._view()
        if series_analysis.SMOOTHED not in view.group:
            return None
        epochs = int(view.group[series_analysis.SMOOTHED].attrs.get("epochs", view.n_epochs))
        return view.read(series_analysis.SMOOTHED, (slice(None), slice(0, epochs))).astype(np.float64)

    @smoothed_distances.setter
    @translated
    def smoothed_distances(self, values) -> None:
        if not self._has_store():
            raise UsageError("SpatiotemporalAnalysis.smoothed_distances: the analysis has no epochs yet (add_epochs "
                             "first)")
        window = getattr(values, "smoothing_window", None)
        if window is None:
            raise UnsupportedArgument(
                "SpatiotemporalAnalysis.smoothed_distances: m3c2kit's store computes its smoothing itself (m3c2 "
                "series smooth): set it to py4dgeo.temporal_averaging(analysis.distances, smoothing_window=w); an "
                "array smoothed otherwise is not stored (py4dgeo stores any array)")
        from .segmentation import temporal_averaging
        expected = temporal_averaging(self.distances, smoothing_window=window)
        given = np.asarray(values, dtype=np.float64)
        if given.shape != expected.shape or not np.array_equal(given, expected, equal_nan=True):
            raise UnsupportedArgument(
                f"SpatiotemporalAnalysis.smoothed_distances: the array given is not temporal_averaging(analysis."
                f"distances, smoothing_window={window}) of this analysis, the smoothing its store computes; an array "
                f"smoothed otherwise is not stored")
        series_analysis.smooth(self.store, int(window), util.get_num_threads())
        self._state["smoothed_invalidated"] = False
        self._save_state()

    @smoothed_distances.deleter
    def smoothed_distances(self) -> None:
        """py4dgeo drops its in-memory copy here; the store's is read when asked for."""

    def _analysed_series(self) -> str:
        """Which series 4D-OBC runs on, in words (kept with the seeds and objects it gave)."""
        if self.smoothed_distances is None:
            return "distances"
        window = self._view().group[series_analysis.SMOOTHED].attrs.get("window")
        return f"smoothed_distances (window {window})"

    @property
    def distances_for_compute(self) -> np.ndarray:
        """The series 4D-OBC runs on: the smoothed distances when set, else the distances."""
        smoothed = self.smoothed_distances
        return self.distances if smoothed is None else smoothed

    # -- seeds and objects -------------------------------------------------------------------

    @property
    @translated
    def seeds(self):
        """4D-OBC's seeds (RegionGrowingSeed) in growing order, None before a run (and with
        allow_pickle=False, as py4dgeo keeps none then)."""
        from .change_objects import RegionGrowingSeed
        stored = files.read_seeds(self._location) if self.allow_pickle else None
        return None if stored is None else [RegionGrowingSeed(*s) for s in stored]

    @seeds.setter
    def seeds(self, values) -> None:
        raise UnsupportedArgument("SpatiotemporalAnalysis.seeds: m3c2kit's engine finds the seeds itself from "
                                  "RegionGrowingAlgorithm's parameters; seeds given by hand are not grown")

    @property
    @translated
    def objects(self):
        """4D-OBC's objects (ObjectByChange), None before a run (and with allow_pickle=False)."""
        from .change_objects import ObjectByChange, RegionGrowingSeed
        stored = files.read_objects(self._location) if self.allow_pickle else None
        if stored is None:
            return None
        return [ObjectByChange(o["members"], RegionGrowingSeed(o["seed"], o["start"], o["end"]), o["threshold"],
                               analysis=self) for o in stored]

    @objects.setter
    def objects(self, values) -> None:
        if values is not None:  # py4dgeo: None is no change
            raise UnsupportedArgument("SpatiotemporalAnalysis.objects: the objects are those RegionGrowingAlgorithm"
                                      ".run(analysis) computed into the store; objects given by hand are not stored")

    @translated
    def invalidate_results(self, seeds: bool = True, objects: bool = True, smoothed_distances: bool = False) -> None:
        """Forgets the seeds, objects and smoothing computed (the store's own labels and
        smoothed_distance stay until the next run or smoothing replaces them)."""
        files.remove_results(self._location, seeds=seeds, objects=objects)
        if seeds:
            self._state["seeds_parameters"] = None
        if objects:
            self._state["objects_parameters"] = None
        if smoothed_distances:
            self._state["smoothed_invalidated"] = True
        if self._location.folder.exists():
            self._save_state()

    def _results_parameters(self) -> tuple[dict | None, dict | None]:
        return self._state["seeds_parameters"], self._state["objects_parameters"]

    def _record_results(self, seeds_parameters: dict, objects_parameters: dict) -> None:
        self._state["seeds_parameters"], self._state["objects_parameters"] = seeds_parameters, objects_parameters
        self._save_state()
