"""Where a compat SpatiotemporalAnalysis keeps its data (docs/python.md, "Coming from py4dgeo").

py4dgeo keeps an analysis in one zip archive, FILENAME. Here the distances live in m3c2kit's
series store (docs/series.md), which ``m3c2 series`` commands and xarray read, and the rest in
the analysis folder beside the name given: ``NAME.zip`` -> ``NAME.m3c2/`` (a name without
``.zip`` gets ``.m3c2`` appended), holding

* ``store/``: the series store (``m3c2 series smooth/objects/report NAME.m3c2/store`` work on it);
* ``reference.npy``, ``corepoints.npy``, ``core_normals.npy``: the reference epoch, the core
  points and their normals, float64 as given (the store's ``add`` needs its reference file);
* ``analysis.json``: the reference's timestamp and what the analysis has computed;
* ``objects.csv``, ``objects_members.csv``: 4D-OBC's objects, the tables of ``m3c2 series
  objects``; ``seeds.csv``: its seeds in growing order.

A FILENAME that is a series store (made by ``m3c2 series``) is used as the store, its folder
``STORE.m3c2/`` made only when something is written. A py4dgeo archive at FILENAME, without an
analysis folder, is read through m3c2kit's importer (``m3c2 series import``) into the folder's
store; the archive itself is never written.
"""
from __future__ import annotations

import csv
import json
import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ...base.errors import UsageError
from ...io.atomic import atomic_output

FORMAT = "m3c2kit-compat-py4dgeo-analysis"
STATE = "analysis.json"
OBJECTS = "objects.csv"
MEMBERS = "objects_members.csv"  # series.outputs.members_path of OBJECTS
SEEDS = "seeds.csv"
SEED_COLUMNS = ["seed", "core", "start_epoch", "end_epoch", "score"]


@dataclass(frozen=True)
class Location:
    """The analysis folder, its store and, for a new analysis, the py4dgeo archive to import."""

    folder: Path
    store: Path
    archive: Path | None = None
    external_store: bool = False  # a store made by `m3c2 series`, named as FILENAME

    def file(self, name: str) -> Path:
        return self.folder / name


def is_series_store(path: Path) -> bool:
    return path.is_dir() and (path / "zarr.json").is_file()


def locate(filename) -> Location:
    """The module docstring's rule for a py4dgeo FILENAME."""
    path = Path(filename)
    if is_series_store(path):
        return Location(Path(f"{path}.m3c2"), path, external_store=True)
    folder = path.with_suffix(".m3c2") if path.suffix.lower() == ".zip" else Path(f"{path}.m3c2")
    return Location(folder, folder / "store", archive=path if path.is_file() else None)


def is_analysis_folder(folder: Path) -> bool:
    try:
        return json.loads((folder / STATE).read_text()).get("format") == FORMAT
    except (OSError, ValueError, AttributeError):
        return False


def new_state() -> dict:
    """What a new analysis knows: nothing computed yet."""
    return {"format": FORMAT, "version": 1, "reference_timestamp": None, "smoothed_invalidated": False,
            "seeds_parameters": None, "objects_parameters": None}


def load_state(location: Location) -> dict:
    path = location.file(STATE)
    if not path.is_file():
        return new_state()
    try:
        state = json.loads(path.read_text())
    except (OSError, ValueError) as e:
        raise UsageError(f"{path}: not readable as the analysis' state ({e})") from None
    if not isinstance(state, dict) or state.get("format") != FORMAT:
        raise UsageError(f"{path}: not a m3c2kit py4dgeo-compat analysis state ({FORMAT})")
    return dict(new_state(), **state)


def save_state(location: Location, state: dict) -> None:
    location.folder.mkdir(parents=True, exist_ok=True)
    with atomic_output(location.file(STATE)) as tmp:
        tmp.write_text(json.dumps(state, indent=1, sort_keys=True))


def remove_folder(location: Location) -> None:
    """force=True: py4dgeo replaces its archive; here the analysis folder goes, but only one this
    module made (its state file says so): nothing else is ever deleted."""
    if location.external_store:
        raise UsageError(f"{location.store} is a series store: force=True would start a new analysis in its place, "
                         f"and m3c2kit never deletes a store; choose another filename")
    if not location.folder.exists():
        return
    if not is_analysis_folder(location.folder):
        raise UsageError(f"{location.folder} exists and is no analysis folder of m3c2kit.compat.py4dgeo: "
                         f"force=True does not delete it; move it away or choose another filename")
    shutil.rmtree(location.folder)


def save_array(location: Location, name: str, values: np.ndarray) -> Path:
    location.folder.mkdir(parents=True, exist_ok=True)
    path = location.file(name)
    with atomic_output(path) as tmp:
        with open(tmp, "wb") as f:
            np.save(f, np.ascontiguousarray(values, dtype=np.float64), allow_pickle=False)
    return path


def load_array(location: Location, name: str) -> np.ndarray | None:
    path = location.file(name)
    return np.load(path, allow_pickle=False) if path.is_file() else None


def write_seeds(location: Location, out: dict) -> None:
    """seeds.csv: the engine's seeds (objects_by_change's output) in growing order."""
    with atomic_output(location.file(SEEDS)) as tmp, open(tmp, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(SEED_COLUMNS)
        for k, row in enumerate(zip(out["seed_core"], out["seed_start"], out["seed_end"], out["seed_score"])):
            w.writerow([k, int(row[0]), int(row[1]), int(row[2]), repr(float(row[3]))])


def _rows(path: Path, columns) -> list[dict]:
    with open(path, newline="") as f:
        reader = csv.DictReader(f)
        missing = [c for c in columns if c not in (reader.fieldnames or [])]
        if missing:
            raise UsageError(f"{path}: no column {', '.join(missing)}: not written by this analysis")
        return list(reader)


def read_seeds(location: Location) -> list[tuple[int, int, int]] | None:
    """(core, start, end) of each stored seed, in growing order; None when none are stored."""
    path = location.file(SEEDS)
    if not path.is_file():
        return None
    return [(int(r["core"]), int(r["start_epoch"]), int(r["end_epoch"])) for r in _rows(path, SEED_COLUMNS)]


def read_objects(location: Location) -> list[dict] | None:
    """The objects of the tables `m3c2 series objects` wrote (series.analysis.write_tables):
    seed core, start, end, threshold and {core: DTW} of each; None when none are stored."""
    table, members = location.file(OBJECTS), location.file(MEMBERS)
    if not (table.is_file() and members.is_file()):
        return None
    objects = [{"seed": int(r["seed_core"]), "start": int(r["start_epoch"]), "end": int(r["end_epoch"]),
                "threshold": float(r["threshold"]), "members": {}}
               for r in _rows(table, ["object", "seed_core", "start_epoch", "end_epoch", "threshold"])]
    for r in _rows(members, ["object", "core", "dtw"]):
        objects[int(r["object"])]["members"][int(r["core"])] = float(r["dtw"])
    return objects


def remove_results(location: Location, seeds: bool, objects: bool) -> None:
    """The seeds' and objects' tables of this analysis (its own files only)."""
    names = ([SEEDS] if seeds else []) + ([OBJECTS, MEMBERS] if objects else [])
    for name in names:
        location.file(name).unlink(missing_ok=True)
