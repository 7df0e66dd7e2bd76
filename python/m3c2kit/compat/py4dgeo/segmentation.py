"""py4dgeo's segmentation module (py4dgeo 1.2.0's py4dgeo/segmentation.py) on m3c2kit's series
store: SpatiotemporalAnalysis (analysis.py), RegionGrowingAlgorithm (region_growing.py), the seeds
and objects it returns (change_objects.py) and temporal_averaging, the store's temporal median."""
from __future__ import annotations

import numpy as np

from ...base.errors import UsageError
from ...series import engine as series_engine
from . import util
from .analysis import SpatiotemporalAnalysis
from .analysis_epochs import require_timestamp
from .change_objects import ObjectByChange, RegionGrowingSeed
from .errors import translated
from .region_growing import RegionGrowingAlgorithm
from .util import regular_corepoint_grid

__all__ = ["SpatiotemporalAnalysis", "RegionGrowingAlgorithm", "RegionGrowingSeed", "ObjectByChange",
           "temporal_averaging", "check_epoch_timestamp", "regular_corepoint_grid", "SmoothedDistances"]


class SmoothedDistances(np.ndarray):
    """temporal_averaging's result: a plain float64 array that also says its window, so that
    ``analysis.smoothed_distances = temporal_averaging(analysis.distances, w)`` has the store
    compute the same smoothing (m3c2 series smooth --window w), which it checks it equals."""

    smoothing_window: int | None

    def __array_finalize__(self, obj) -> None:
        self.smoothing_window = getattr(obj, "smoothing_window", None)


@translated
def temporal_averaging(distances, smoothing_window: int = 24) -> SmoothedDistances:
    """py4dgeo's temporal_averaging: each core point's series smoothed by its median over a
    window of epochs, NaN ignored (m3c2kit's engine.temporal_median, as ``m3c2 series smooth``).
    The window is centred: epochs [t - w/2, t + w/2] clipped to the series (w/2 rounded down);
    py4dgeo takes [t - w/2, t + w/2) and never the series' last epoch, so the two differ by up
    to one epoch at each end of every window (docs/series.md, "Analysis")."""
    values = np.asarray(distances, dtype=np.float64)
    if values.ndim != 2:
        raise UsageError(f"temporal_averaging: distances must be a (core points, epochs) array, got shape "
                         f"{values.shape}")
    if isinstance(smoothing_window, bool) or not isinstance(smoothing_window, (int, np.integer)) \
            or smoothing_window < 1:
        raise UsageError(f"temporal_averaging: smoothing_window must be a whole number of epochs >= 1, got "
                         f"{smoothing_window!r} (py4dgeo's 0 and 1 give NaN everywhere)")
    smoothed = series_engine.temporal_median(values, int(smoothing_window), util.get_num_threads())
    out = np.asarray(smoothed, dtype=np.float64).view(SmoothedDistances)
    out.smoothing_window = int(smoothing_window)
    return out


@translated
def check_epoch_timestamp(epoch):
    """py4dgeo's check: an epoch of a time series needs a timestamp (returned as is)."""
    return require_timestamp(epoch)


def __getattr__(name: str):
    if name == "RegionGrowingAlgorithmBase":
        raise AttributeError("m3c2kit.compat.py4dgeo.segmentation does not provide py4dgeo's RegionGrowingAlgorithmBase: "
                             "m3c2kit's engine runs 4D-OBC whole (m3c2 series objects), so its steps cannot be "
                             "replaced; use RegionGrowingAlgorithm's parameters")
    raise AttributeError(f"module 'm3c2kit.compat.py4dgeo.segmentation' has no attribute {name!r}")
