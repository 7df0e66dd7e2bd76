"""py4dgeo's RegionGrowingSeed and ObjectByChange (py4dgeo 1.2.0's segmentation.py), holding
what m3c2kit's 4D-OBC (engine.objects_by_change) found: a seed is a core point and its epochs
[start_epoch, end_epoch]; an object its seed's epochs, the DTW threshold chosen and the DTW of
each member core point's series to the seed's."""
from __future__ import annotations

import numpy as np

from ...base.errors import UsageError
from .errors import translated

__all__ = ["RegionGrowingSeed", "ObjectByChange"]


class RegionGrowingSeed:
    """A seed of 4D-OBC: core point `index`, epochs [start_epoch, end_epoch]."""

    def __init__(self, index: int, start_epoch: int, end_epoch: int) -> None:
        self._seed = (int(index), int(start_epoch), int(end_epoch))

    @property
    def index(self) -> int:
        return self._seed[0]

    @property
    def start_epoch(self) -> int:
        return self._seed[1]

    @property
    def end_epoch(self) -> int:
        return self._seed[2]

    def __eq__(self, other) -> bool:
        return isinstance(other, RegionGrowingSeed) and self._seed == other._seed

    def __hash__(self) -> int:
        return hash(self._seed)

    def __repr__(self) -> str:
        return f"RegionGrowingSeed(index={self.index}, start_epoch={self.start_epoch}, end_epoch={self.end_epoch})"


class ObjectByChange:
    """A change object in space and time: :attr:`indices` (its core points, ascending here;
    py4dgeo's order is its hash map's), :meth:`distance` (a member's DTW to the seed),
    :attr:`start_epoch`, :attr:`end_epoch`, :attr:`threshold`, :attr:`seed`."""

    def __init__(self, indices_distances: dict, seed: RegionGrowingSeed, threshold: float, analysis=None) -> None:
        self._indices_distances = {int(k): float(v) for k, v in sorted(indices_distances.items())}
        self.seed = seed
        self._threshold = float(threshold)
        self._analysis = analysis

    @property
    def indices(self) -> list[int]:
        """The core point indices of the object."""
        return list(self._indices_distances)

    def distance(self, index: int) -> float:
        """The DTW distance of core point `index`'s series to the seed's (a KeyError for a core
        point outside the object, as py4dgeo's)."""
        return self._indices_distances[index]

    @property
    def start_epoch(self) -> int:
        return self.seed.start_epoch

    @property
    def end_epoch(self) -> int:
        return self.seed.end_epoch

    @property
    def threshold(self) -> float:
        """The DTW threshold the adaptive rule chose for this object."""
        return self._threshold

    def attach_analysis(self, analysis) -> None:
        self._analysis = analysis

    def __getstate__(self) -> dict:
        # As py4dgeo's: the analysis is not pickled with each object.
        return {"_indices_distances": self._indices_distances, "seed": self.seed, "_threshold": self._threshold}

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._analysis = None

    @translated
    def plot(self, filename=None) -> None:
        """py4dgeo's figure of the object: its members' series (10 epochs either side of its
        own), coloured by DTW, the seed's in blue; a histogram of the DTW values (matplotlib's;
        py4dgeo adds seaborn's density curve); the members' map. Saved to `filename` if given."""
        if self._analysis is None:
            raise UsageError("ObjectByChange.plot: the object has no analysis (attach_analysis(analysis) first)")
        try:
            import matplotlib
            import matplotlib.pyplot as plt
        except ImportError:
            raise UsageError("ObjectByChange.plot needs matplotlib: pip install 'm3c2kit[report]'") from None
        index = np.fromiter(self.indices, np.int64)
        dtw = np.fromiter((self.distance(i) for i in index), np.float64)
        series = self._analysis.distances_for_compute
        fig = plt.figure(figsize=plt.figaspect(0.3))
        ts_ax, hist_ax, map_ax = (fig.add_subplot(1, 3, k) for k in (1, 2, 3))
        ts_ax.set_ylabel("Height change [m]")
        ts_ax.set_xlabel("Time [h]")
        start, end = max(self.start_epoch - 10, 0), min(self.end_epoch + 10, series.shape[1])
        seed_ts = series[self.seed.index, start:end]
        ts_ax.set_ylim(np.nanmin(seed_ts) * 0.5, np.nanmax(seed_ts) * 1.5)
        cmap, most = matplotlib.colormaps.get_cmap("viridis"), np.nanmax(dtw)
        for i, d in zip(index, dtw):
            ts_ax.plot(series[i, start:end], linewidth=0.7, alpha=0.3, color=cmap(d / most if most > 0 else 0.0))
        ts_ax.plot(seed_ts, linewidth=2.0, zorder=10, color="blue")
        hist_ax.hist(dtw, color="r")
        hist_ax.set_title(f"Segment size: {len(dtw)}")
        hist_ax.set_xlabel("DTW distance")
        xy = self._analysis.corepoints.cloud[index, 0:2]
        map_ax.scatter(xy[:, 0], xy[:, 1], c=dtw)
        fig.tight_layout()
        if filename is not None:
            plt.savefig(filename)
