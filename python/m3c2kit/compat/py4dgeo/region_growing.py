"""py4dgeo's RegionGrowingAlgorithm (py4dgeo 1.2.0's segmentation.py): 4D objects-by-change
(Anders et al. 2021) run by m3c2kit's ``m3c2 series objects`` on the analysis' store
(series.analysis.objects: the engine's objects_by_change, the objects table beside the store and
its ``object`` labels in it), in the engine's ``py4dgeo`` mode (``--dtw py4dgeo``: py4dgeo
1.2.0's seeds, DTW offsets and object filter, docs/series.md "Analysis").

py4dgeo lets a subclass replace its steps (distance_measure, find_seedpoints,
seed_sorting_scorefunction, filter_objects); m3c2kit's engine runs its own, so such a subclass
is refused, as are arguments for resuming a run part way (the store's step is whole or nothing)."""
from __future__ import annotations

import logging
import math

import numpy as np

from ...base.errors import UsageError
from ...series import analysis as series_analysis
from ...series import engine as series_engine
from . import analysis_files as files
from . import util
from .change_objects import ObjectByChange, RegionGrowingSeed
from .errors import UnsupportedArgument, refuse, translated

__all__ = ["RegionGrowingAlgorithm"]

LOGGER = logging.getLogger("py4dgeo")
_ARGUMENTS = ("neighborhood_radius", "thresholds", "min_segments", "max_segments", "seed_subsampling",
              "seed_candidates", "window_width", "window_min_size", "window_jump", "window_penalty", "minperiod",
              "height_threshold", "use_unfinished", "intermediate_saving", "resume_from_seed", "stop_at_seed",
              "write_nr_seeds", "dtw")
#: py4dgeo's steps a subclass may replace, which m3c2kit's engine never calls.
_STEPS = ("distance_measure", "find_seedpoints", "seed_sorting_scorefunction", "filter_objects")
#: The parameters the seeds depend on (the others only the growth and the filter).
_SEED_FIELDS = ("window_width", "window_min_size", "window_jump", "window_penalty", "min_period", "height_threshold",
                "use_unfinished", "seed_subsampling", "neighbourhood_radius", "dtw")


def _count(name: str, value, least: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < least:
        raise UsageError(f"RegionGrowingAlgorithm: {name} must be an integer >= {least}, got {value!r}")
    return int(value)


def _number(name: str, value, positive: bool = False) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise UsageError(f"RegionGrowingAlgorithm: {name} must be a number, got {value!r}") from None
    if not math.isfinite(v) or (positive and v <= 0) or v < 0:
        raise UsageError(f"RegionGrowingAlgorithm: {name} must be a {'positive' if positive else 'non-negative'} "
                         f"number, got {value!r}")
    return v


class RegionGrowingAlgorithm:
    """py4dgeo's 4D-OBC with py4dgeo's parameters and defaults; ``run(analysis)`` returns the
    objects (ObjectByChange) and keeps them and the seeds in the analysis. m3c2kit's addition:
    ``dtw`` ("py4dgeo", the default; "baseline", m3c2kit's own rule, which also finds steps
    and slow subsidence py4dgeo misses; "seed-start"), docs/series.md "Analysis"."""

    @translated
    def __init__(self, seed_subsampling=1, seed_candidates=None, window_width=24, window_min_size=12, window_jump=1,
                 window_penalty=1.0, minperiod=24, height_threshold=0.0, use_unfinished=True, intermediate_saving=0,
                 resume_from_seed=0, stop_at_seed=np.inf, write_nr_seeds=False, neighborhood_radius=1.0,
                 thresholds=(0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9), min_segments=20, max_segments=None,
                 dtw="py4dgeo", **unsupported) -> None:
        refuse("RegionGrowingAlgorithm", unsupported, _ARGUMENTS)
        if seed_candidates is not None:
            raise UnsupportedArgument("RegionGrowingAlgorithm: seed_candidates: m3c2kit's engine searches every "
                                      "seed_subsampling-th core point for seeds; a list of candidates is not supported")
        if intermediate_saving:
            raise UnsupportedArgument("RegionGrowingAlgorithm: intermediate_saving: the store's objects step writes "
                                      "all objects at once, or none (docs/series.md, Writers)")
        if resume_from_seed not in (0, 1) or stop_at_seed != np.inf:
            raise UnsupportedArgument("RegionGrowingAlgorithm: resume_from_seed, stop_at_seed: m3c2kit's engine grows "
                                      "every seed in one run (a run of 9,216 core points x 100 epochs takes about "
                                      "a second, docs/series.md)")
        self.seed_subsampling = seed_subsampling
        self.seed_candidates = seed_candidates
        self.window_width = window_width
        self.window_min_size = window_min_size
        self.window_jump = window_jump
        self.window_penalty = window_penalty
        self.minperiod = minperiod
        self.height_threshold = height_threshold
        self.use_unfinished = use_unfinished
        self.intermediate_saving = intermediate_saving
        self.resume_from_seed = resume_from_seed
        self.stop_at_seed = stop_at_seed
        self.write_nr_seeds = write_nr_seeds
        self.neighborhood_radius = neighborhood_radius
        self.thresholds = thresholds
        self.min_segments = min_segments
        self.max_segments = max_segments
        self.dtw = dtw
        self._analysis = None
        self.parameters()  # every value checked now, as far as it needs no analysis

    @property
    @translated
    def analysis(self):
        """The analysis of the last run (py4dgeo: only while and after it runs)."""
        if self._analysis is None:
            raise UsageError("Analysis object is only available when the algorithm is run")
        return self._analysis

    @translated
    def parameters(self) -> dict:
        """The engine's ObjectsParams fields (include/m3c2/objects_by_change.hpp) of these arguments."""
        if self.seed_subsampling == 0:
            raise UsageError("Subsampling factor cannot be 0, use 1 or any integer larger than 1")
        thresholds = [_number("thresholds", t) for t in np.atleast_1d(self.thresholds)]
        if not thresholds:
            raise UsageError("RegionGrowingAlgorithm: thresholds must hold at least one DTW threshold")
        if self.dtw not in ("py4dgeo", "baseline", "seed-start"):
            raise UsageError(f"RegionGrowingAlgorithm: dtw must be 'py4dgeo', 'baseline' or 'seed-start', got "
                             f"{self.dtw!r}")
        return {"window_width": _count("window_width", self.window_width, 1),
                "window_min_size": _count("window_min_size", self.window_min_size, 1),
                "window_jump": _count("window_jump", self.window_jump, 1),
                "window_penalty": _number("window_penalty", self.window_penalty, positive=True),
                "min_period": _count("minperiod", self.minperiod, 1),
                "height_threshold": _number("height_threshold", self.height_threshold),
                "use_unfinished": bool(self.use_unfinished),
                "seed_subsampling": _count("seed_subsampling", self.seed_subsampling, 1),
                "neighbourhood_radius": _number("neighborhood_radius", self.neighborhood_radius, positive=True),
                "thresholds": thresholds, "min_segments": _count("min_segments", self.min_segments, 0),
                "max_segments": 0 if self.max_segments is None else _count("max_segments", self.max_segments, 1),
                "dtw": self.dtw}

    def distance_measure(self):
        raise UnsupportedArgument("RegionGrowingAlgorithm.distance_measure: m3c2kit's engine computes the normalised "
                                  "DTW itself (m3c2kit.engine.normalised_dtw computes one pair)")

    find_seedpoints = seed_sorting_scorefunction = filter_objects = distance_measure

    def _refuse_replaced_steps(self) -> None:
        for name in _STEPS:
            if getattr(type(self), name) is not getattr(RegionGrowingAlgorithm, name):
                raise UnsupportedArgument(
                    f"{type(self).__name__}.{name} replaces a step of py4dgeo's algorithm, which m3c2kit's engine "
                    f"never calls (it runs 4D-OBC whole: m3c2 series objects); run it with py4dgeo itself")

    @translated
    def run(self, analysis, force: bool = False) -> list[ObjectByChange]:
        """4D-OBC on the analysis' distances_for_compute (smoothed when set): its objects, also
        kept as ``analysis.objects`` and its seeds as ``analysis.seeds``. Objects an earlier run
        kept with the same parameters are returned as they are (as py4dgeo reuses them)."""
        from .analysis import SpatiotemporalAnalysis
        if not isinstance(analysis, SpatiotemporalAnalysis):
            raise UsageError(f"RegionGrowingAlgorithm.run: analysis must be a SpatiotemporalAnalysis, got "
                             f"{type(analysis).__name__}")
        self._refuse_replaced_steps()
        self._analysis = analysis
        if force:
            analysis.invalidate_results()
        params = self.parameters()
        series = analysis._analysed_series()  # seeds and objects depend on it as on the parameters
        recorded = dict(params, series=series)
        seed_recorded = dict({k: params[k] for k in _SEED_FIELDS}, series=series)
        reused = self._reused(analysis, recorded, seed_recorded)
        if reused is not None:
            return reused
        use = self._analysed(analysis, params["window_width"])
        analysis.folder.mkdir(parents=True, exist_ok=True)  # a store named as FILENAME: its folder made now
        out = series_analysis.objects(analysis.store, analysis.folder / files.OBJECTS,
                                      series_engine.objects_params(**params), use=use,
                                      threads=util.get_num_threads())
        files.write_seeds(analysis._location, out)
        analysis._record_results(seed_recorded, recorded)
        if self.write_nr_seeds:  # py4dgeo's file, in the working directory
            with open("number_of_seeds.txt", "w") as f:
                f.write(str(len(out["seed_core"])))
        return self._objects(out, analysis)

    @staticmethod
    def _reused(analysis, params: dict, seed_params: dict):
        """The objects kept by an earlier run with these parameters, None to compute them. py4dgeo
        keeps seeds and objects of other parameters and grows the rest with the new ones; here
        one run's objects come from one parameter set, so such leftovers are an error."""
        if not analysis.allow_pickle:  # py4dgeo keeps nothing to reuse then
            return None
        kept_seeds, kept_objects = analysis._results_parameters()
        advice = "call analysis.invalidate_results() or run(analysis, force=True) first"
        if kept_objects is not None and files.read_objects(analysis._location) is not None:
            if kept_objects != params:
                raise UsageError(f"RegionGrowingAlgorithm.run: the analysis keeps objects of other parameters "
                                 f"({_changed(kept_objects, params)}); {advice}")
            LOGGER.info("Reusing objects by change stored in analysis object")
            return analysis.objects
        if kept_seeds is not None and kept_seeds != seed_params:
            raise UsageError(f"RegionGrowingAlgorithm.run: the analysis keeps seeds of other parameters "
                             f"({_changed(kept_seeds, seed_params)}); {advice}")
        return None

    @staticmethod
    def _analysed(analysis, window_width: int) -> str:
        """series.analysis.objects' `use`: the smoothed distances when set (whole), else the raw."""
        smoothed = analysis.smoothed_distances
        epochs = analysis.distances.shape[1]
        if smoothed is not None and smoothed.shape[1] != epochs:
            raise UsageError(f"RegionGrowingAlgorithm.run: smoothed_distances covers {smoothed.shape[1]} of the "
                             f"{epochs} epochs (epochs were added since; py4dgeo would segment the shorter series): "
                             f"set analysis.smoothed_distances = py4dgeo.temporal_averaging(analysis.distances, ...) "
                             f"again")
        if window_width >= epochs:
            raise UsageError("Window width cannot be larger than the length of the time series - please adapt "
                             "parameter")
        return "raw" if smoothed is None else "smoothed"

    @staticmethod
    def _objects(out: dict, analysis) -> list[ObjectByChange]:
        objects = []
        for k, (core, start, end) in enumerate(zip(out["object_seed"], out["object_start"], out["object_end"])):
            members, dtw = series_analysis.object_members(out, k)
            objects.append(ObjectByChange(dict(zip(members.tolist(), dtw.tolist())),
                                          RegionGrowingSeed(core, start, end), out["object_threshold"][k], analysis))
        return objects


def _changed(before: dict, now: dict) -> str:
    return ", ".join(f"{k} {before.get(k)!r} -> {now[k]!r}" for k in now if before.get(k) != now[k])
