"""SpatiotemporalAnalysis.add_epochs on m3c2kit's series store (series/run.py's create and add).

py4dgeo compares each epoch with the reference through the analysis' M3C2 object. Here the
store does it: its parameters are that M3C2's compare keywords (M3C2.compare_settings) with its
normals given as they are (normal source ``core``: M3C2.directions(), computed once from the
reference as py4dgeo's cached directions are), so each epoch's column equals that M3C2's
``run()`` on (reference, epoch), bit for bit (the store's exactness, docs/series.md).

The store reads epochs from files: each epoch is written, float64, to a temporary .npy file
holding its timestamp as a field (an epoch is the store's by its content, so two epochs with the
same points at different times stay two epochs) and named in an epoch list with its time. The
store's own rules then hold: epochs are committed in time order (an epoch older than the
analysis' last is refused; py4dgeo appends it), and one whose points and time equal a committed
epoch's is refused here (the store would skip it; py4dgeo adds it again)."""
from __future__ import annotations

import datetime
import logging
import tempfile
from pathlib import Path

import numpy as np

from ...base.errors import UsageError
from ...series import run as series_run
from ...series.run_options import CoreInput, EpochReading
from . import util
from .analysis_files import Location, load_array, save_array
from .m3c2 import M3C2
from .m3c2ep import M3C2EP

LOGGER = logging.getLogger("py4dgeo")
CORE_NORMALS = "core_normals.npy"


def require_timestamp(epoch):
    """py4dgeo's check_epoch_timestamp: an epoch of a time series needs a timestamp."""
    if getattr(epoch, "timestamp", None) is None:
        raise UsageError("Epochs need to define a timestamp to be usable in SpatiotemporalSegmentation")
    return epoch


def iso_utc(timestamp: datetime.datetime) -> str:
    """The time as the store reads it: ISO 8601, a naive datetime taken as UTC (py4dgeo's time
    deltas are differences of its datetimes, whatever their zone, so every one is read alike)."""
    return timestamp.isoformat()


def checked_algorithm(m3c2) -> M3C2:
    if m3c2 is None:
        raise UsageError("add_epochs: set the analysis' M3C2 first (analysis.m3c2 = py4dgeo.M3C2(cyl_radius=..., "
                         "normal_radii=..., max_distance=...))")
    if isinstance(m3c2, M3C2EP) or not isinstance(m3c2, M3C2):
        from .errors import UnsupportedArgument
        raise UnsupportedArgument(f"add_epochs: analysis.m3c2 is a {type(m3c2).__name__}; m3c2kit's series store "
                                  f"computes M3C2 with eq. (1)'s LOD (py4dgeo.M3C2 or CloudCompareM3C2), not "
                                  f"per-point uncertainties such as M3C2-EP's (docs/series.md)")
    m3c2._refuse_overridden_callbacks()
    return m3c2


def _epoch_file(folder: Path, index: int, epoch) -> str:
    cloud = np.asarray(epoch.cloud, dtype=np.float64)
    if cloud.ndim != 2 or cloud.shape[1] != 3 or len(cloud) == 0:
        raise UsageError(f"add_epochs: epoch {index} must hold an (N, 3) cloud of at least one point, got shape "
                         f"{cloud.shape}")
    if not np.isfinite(cloud).all():
        raise UsageError(f"add_epochs: epoch {index} ({epoch.timestamp}) has non-finite coordinates")
    rows = np.empty(len(cloud), dtype=[("x", "<f8"), ("y", "<f8"), ("z", "<f8"), ("timestamp_us", "<i8")])
    rows["x"], rows["y"], rows["z"] = cloud.T
    rows["timestamp_us"] = np.datetime64(epoch.timestamp.replace(tzinfo=None), "us").astype(np.int64)
    name = f"epoch_{index:06d}.npy"
    np.save(folder / name, rows, allow_pickle=False)
    return name


def _refuse_skipped(line: str) -> None:
    """The store's log: progress to py4dgeo's logger; an epoch it would skip as already stored
    is refused instead (py4dgeo would add it twice; nothing has been computed when it says so)."""
    if line.endswith(": skipped"):
        raise UsageError(f"add_epochs: an epoch with the same points and timestamp is already in the analysis "
                         f"({line})")
    LOGGER.info(line)


def _same_normals(stored: np.ndarray, given: np.ndarray) -> bool:
    return stored.shape == given.shape and bool(np.all((stored == given) | (np.isnan(stored) & np.isnan(given))))


def add_epochs(location: Location, reference: Path, core: np.ndarray, reference_epoch, m3c2: M3C2,
               epochs, store_exists: bool) -> int:
    """Compares `epochs` (sorted by time, as py4dgeo sorts them) with the reference into the
    store, creating it with the first; returns the epochs added."""
    m3c2 = checked_algorithm(m3c2)
    ordered = sorted(epochs, key=lambda e: e.timestamp)  # py4dgeo's order (stable)
    m3c2.corepoints = core
    m3c2.epochs = (reference_epoch, ordered[0])
    settings = dict(m3c2.compare_settings(), normal_source="core")
    normals = m3c2._core_normals(core)  # directions(): once from the reference, as py4dgeo's cache
    reading = EpochReading(threads=util.get_num_threads())
    if store_exists:
        stored = load_array(location, CORE_NORMALS)
        if stored is not None and not _same_normals(stored, normals):
            raise UsageError("add_epochs: this M3C2's normals differ from those the analysis' epochs were computed "
                             "with; an analysis holds epochs of one parameter set: start a new analysis")
    else:
        save_array(location, CORE_NORMALS, normals)
    location.folder.mkdir(parents=True, exist_ok=True)  # a store named as FILENAME: its folder made now
    with tempfile.TemporaryDirectory(prefix="epochs-", dir=location.folder) as tmp:
        folder = Path(tmp)
        lines = [f"{_epoch_file(folder, k, e)}, {iso_utc(e.timestamp)}" for k, e in enumerate(ordered)]
        listing = folder / "epochs.csv"
        listing.write_text("\n".join(lines) + "\n")
        if store_exists:
            return series_run.add(location.store, [listing], given_settings=settings, reading=reading,
                                  log=_refuse_skipped)
        return series_run.create(reference, [listing], location.store, settings,
                                 core=CoreInput(location.file("corepoints.npy"), location.file(CORE_NORMALS)),
                                 reading=reading, log=_refuse_skipped)
