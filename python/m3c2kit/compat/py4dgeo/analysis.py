"""py4dgeo's SpatiotemporalAnalysis (py4dgeo 1.2.0's segmentation.py) on m3c2kit's series store.

Where it keeps its data is analysis_files.py's rule (FILENAME.zip -> the folder FILENAME.m3c2
holding the store; a series store named directly; a py4dgeo archive imported). The epochs are
compared by the store (analysis_epochs.py), the smoothing is the store's temporal median
(``m3c2 series smooth``) and the objects its 4D-OBC (region_growing.py); the properties read
the store. Differences from py4dgeo are in docs/python.md ("Coming from py4dgeo"): among them, the
distances, uncertainties and time deltas come from ``add_epochs`` or an imported archive and
cannot be set by hand (UnsupportedArgument), and smoothed_distances stores
``temporal_averaging``'s result only."""
from __future__ import annotations

import warnings

from ...base.errors import M3C2Warning, UsageError
from ...series import store as series_store
from ...series.py4dgeo_archive import import_archive
from ...series.view import StoreView
from . import analysis_files as files
from .analysis_epochs import add_epochs as add_to_store, require_timestamp
from .analysis_results import AnalysisResults
from .epoch import Epoch, as_epoch
from .errors import refuse, translated

__all__ = ["SpatiotemporalAnalysis"]

_NOT_YET = "{} for analysis not yet set"
_SET_ONCE = "{} cannot be changed - please start a new analysis"


class SpatiotemporalAnalysis(AnalysisResults):
    """py4dgeo's analysis of a time series: reference epoch, core points, M3C2 distances and
    uncertainties per core point and epoch, their smoothing, and 4D-OBC's seeds and objects.
    m3c2kit's additions: :attr:`store` (the series store's path) and :attr:`folder`."""

    @translated
    def __init__(self, filename, compress: bool = True, allow_pickle: bool = True, force: bool = False,
                 **unsupported) -> None:
        refuse("SpatiotemporalAnalysis", unsupported, ("filename", "compress", "allow_pickle", "force"))
        self.filename = filename
        self.compress = compress
        if not compress:  # py4dgeo's trade of disk space for speed; the store's compression is lossless
            warnings.warn("SpatiotemporalAnalysis: compress=False has no effect: m3c2kit's series store is always "
                          "compressed (Blosc zstd, lossless)", M3C2Warning, stacklevel=3)
        self.allow_pickle = bool(allow_pickle)
        self._location = files.locate(filename)
        self._m3c2 = None
        self._cache: dict = {}
        if force:
            files.remove_folder(self._location)
        self._open(force)

    def _open(self, force: bool) -> None:
        loc = self._location
        if loc.external_store:
            self._state = files.load_state(loc)
            return
        if loc.folder.exists():
            if not files.is_analysis_folder(loc.folder):
                raise UsageError(f"{loc.folder} exists and is no analysis folder of m3c2kit.compat.py4dgeo (its "
                                 f"{files.STATE} is missing): move it away or choose another filename")
            self._state = files.load_state(loc)
            return
        self._state = files.new_state()
        if loc.archive is not None and not force:  # a py4dgeo archive: m3c2kit's importer
            loc.folder.mkdir(parents=True)
            try:
                import_archive(loc.archive, loc.store)  # whole or nothing (a staged folder)
            except BaseException:
                loc.folder.rmdir()  # the empty folder made above: a later open tries the import again
                raise
            self._state["imported_from"] = str(loc.archive.resolve())
            self._state["reference_timestamp"] = series_store.attributes(loc.store).get("reference_time") or None
        files.save_state(loc, self._state)

    # -- where the data lives (m3c2kit's additions) --------------------------------------------

    @property
    def store(self):
        """The series store's path (``m3c2 series ... STORE`` commands and xarray read it)."""
        return self._location.store

    @property
    def folder(self):
        """The analysis folder (analysis_files.py lists what it holds)."""
        return self._location.folder

    def _has_store(self) -> bool:
        return files.is_series_store(self._location.store)

    def _view(self) -> StoreView:
        return StoreView(self._location.store)

    def _save_state(self) -> None:
        files.save_state(self._location, self._state)

    def _imported_from(self) -> str | None:
        """The py4dgeo archive the store was imported from (m3c2 series import), None otherwise."""
        if self._location.external_store:
            return series_store.attributes(self._location.store).get("imported_from") or None
        return self._state.get("imported_from")

    # -- reference epoch, core points, M3C2 ---------------------------------------------------

    @property
    @translated
    def reference_epoch(self) -> Epoch:
        if "reference" not in self._cache:
            loc = self._location
            if self._imported_from():
                raise UsageError(f"Reference epoch: the analysis was imported from the py4dgeo archive "
                                 f"{self._imported_from()}, whose reference's timestamp m3c2kit reads but not its "
                                 f"points")
            if loc.external_store:
                attrs = series_store.attributes(loc.store)
                from ...io import read_cloud
                self._cache["reference"] = Epoch(read_cloud(attrs["reference"]).xyz,
                                                 timestamp=attrs.get("reference_time") or None)
            elif loc.file("reference.npy").is_file():
                self._cache["reference"] = Epoch(files.load_array(loc, "reference.npy"),
                                                 timestamp=self._state["reference_timestamp"])
            else:
                raise UsageError(_NOT_YET.format("Reference epoch"))
        return self._cache["reference"]

    @reference_epoch.setter
    @translated
    def reference_epoch(self, epoch) -> None:
        loc = self._location
        if self._has_store() or loc.file("reference.npy").is_file():
            raise UsageError(_SET_ONCE.format("Reference epoch"))
        epoch = require_timestamp(as_epoch(epoch))
        files.save_array(loc, "reference.npy", epoch.cloud)
        self._state["reference_timestamp"] = epoch.timestamp.isoformat()
        self._save_state()
        self._cache["reference"] = epoch

    @reference_epoch.deleter
    def reference_epoch(self) -> None:
        self._cache.pop("reference", None)

    @property
    @translated
    def corepoints(self) -> Epoch:
        if "corepoints" not in self._cache:
            if self._has_store():
                self._cache["corepoints"] = Epoch(self._view().core())
            elif self._location.file("corepoints.npy").is_file():
                self._cache["corepoints"] = Epoch(files.load_array(self._location, "corepoints.npy"))
            else:
                raise UsageError(_NOT_YET.format("Corepoints"))
        return self._cache["corepoints"]

    @corepoints.setter
    @translated
    def corepoints(self, corepoints) -> None:
        if self._has_store() or self._location.file("corepoints.npy").is_file():
            raise UsageError(_SET_ONCE.format("Corepoints"))
        cloud = as_epoch(corepoints).cloud
        files.save_array(self._location, "corepoints.npy", cloud)
        self._cache["corepoints"] = Epoch(cloud)

    @corepoints.deleter
    def corepoints(self) -> None:
        self._cache.pop("corepoints", None)

    @property
    def m3c2(self):
        """The M3C2 that add_epochs computes with (kept in memory only, as py4dgeo's)."""
        return self._m3c2

    @m3c2.setter
    def m3c2(self, m3c2) -> None:
        self._m3c2 = m3c2

    # -- the epochs ------------------------------------------------------------------------

    @translated
    def add_epochs(self, *epochs) -> None:
        """Compares the epochs with the reference into the store (analysis_epochs.py); the seeds
        and objects computed before are invalidated, the smoothing kept (as py4dgeo's)."""
        if not epochs:
            raise UsageError("add_epochs: give at least one epoch")
        if self._imported_from():
            raise UsageError(f"add_epochs: the analysis was imported from the py4dgeo archive {self._imported_from()}, "
                             f"which keeps neither the M3C2 parameters nor the reference's points, so no epoch can be "
                             f"compared like its epochs; start a new analysis")
        self.invalidate_results()
        for epoch in epochs:
            require_timestamp(epoch)
        reference = self.reference_epoch
        core = self.corepoints.cloud
        if self._location.external_store:
            reference_path = series_store.attributes(self._location.store)["reference"]
        else:
            reference_path = self._location.file("reference.npy")
        add_to_store(self._location, reference_path, core, reference, self._m3c2, epochs, self._has_store())
        for name in ("distances", "uncertainties", "corepoints"):
            self._cache.pop(name, None)
