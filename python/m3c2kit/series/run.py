"""Computing a series into its store: ``m3c2 series REFERENCE EPOCH... -o STORE`` (create) and
``m3c2 series add STORE EPOCH...`` (append). Core points and normals come from the reference once;
then one epoch at a time is read, compared and committed, so memory is bounded by the reference
and the largest epoch. With a Dask scheduler the epochs are tasks (series.dask_epochs) and their
results are committed in epoch order: the same store, bit for bit.

Every option is checked, and its messages given, as `m3c2 compare` checks it (series.parameters:
the parameter table's resolve and the compare run's plan), the default orientation is the one
rule of settings.orientation, and the normals of --normal-source core are compare's
(run.core_normals)."""
from __future__ import annotations

import datetime as dt
import json
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..base.errors import M3C2Error, UsageError
from ..io import read_cloud
from ..io.atomic import refuse_occupied, staged_directory
from ..io.crs import check_crs
from ..run.checks import check_core_normals
from ..run.core_normals import given_core_normals, require_one_per_core_point
from ..run.cores import core_points_for
from . import epochs as epochs_mod
from . import lock as lock_mod
from . import parameters
from . import step
from . import store as st
from .batch import Batch, Target, epoch_columns, with_kept
from .engine import Comparison
from .epoch_files import HashedEpoch, file_digest, file_state, identity, provenance, require_unchanged
from .run_options import CoreInput, DaskTarget, EpochReading, StoreLayout


def _version() -> str:
    try:
        from importlib.metadata import version
        return version("m3c2kit")
    except Exception:  # noqa: BLE001 - an uninstalled tree
        return "unknown"


@dataclass(frozen=True)
class Prepared:
    """What every epoch of a run is compared with: the reference (its cloud and absolute path),
    the core points, the given core normals (--normal-source core, else None), the store's
    recorded parameters (series.parameters) and the engine's Comparison built from them."""

    reference: object  # m3c2kit.io.Cloud
    reference_path: str
    core: np.ndarray
    normals_input: np.ndarray | None
    settings: dict
    comparison: Comparison


def create(reference_path: Path, epoch_args, store: Path, settings: dict, *, core: CoreInput = CoreInput(),
           layout: StoreLayout = StoreLayout(), reading: EpochReading = EpochReading(),
           dask: DaskTarget = DaskTarget(), log=print) -> int:
    """Creates STORE from the reference and adds the epochs; returns the epochs added.
    `settings`: the parameter table's compare keywords (those given)."""
    st.require_extra()
    values = preflight(settings, core)
    store = Path(store)
    refuse_existing_output(store)
    resolved = epochs_mod.resolve(epoch_args)  # bad epoch names fail before any work
    prepared = _prepare(Path(reference_path), core, values, settings, reading)
    attrs = _new_store_attributes(Path(reference_path), core.path, prepared.settings)
    # The empty store is built in a private folder and appears at -o whole, its lock already held
    # (lockf locks the file, which the rename moves along), so no other writer comes in between;
    # its epochs are then committed into it as `add` commits them, so a kill keeps those committed.
    # Where the lock cannot move with the folder (Windows: base/portable.py), it is taken just after
    # the store appears, and a writer that came first refuses create with the usual message.
    held = None
    try:
        with staged_directory(store) as folder:
            st.create(Path(folder), prepared.core, prepared.comparison.normals(), attrs, core_chunk=layout.core_chunk,
                      epoch_chunk=layout.epoch_chunk, core_normals_input=prepared.normals_input)
            if lock_mod.moves_with_folder():
                held = lock_mod.acquire(Path(folder), "create", store)
        if held is None:
            held = lock_mod.acquire(store, "create", store)
    except BaseException:
        if held is not None:
            held.release()
        raise
    resume = f"resume with: m3c2 series add {store} EPOCH..."
    planned = [len(resolved)]  # the epochs this run adds, once duplicates are known (for the messages)
    with step.writing(store, "create", lambda f: step.committed_epochs_text(store, f, 0, planned[0], resume),
                      held=held) as folder:
        todo, index = _todo(store, folder, resolved, True, log)
        planned[0] = len(todo)
        return _add_epochs(Target(store, folder, index), todo, prepared, reading, dask, log)


def preflight(settings: dict, core: CoreInput = CoreInput()) -> dict:
    """The resolved values of a new store's settings: every option checked as m3c2 compare
    checks it, with its messages, before any file is read or a Dask scheduler reached."""
    values = parameters.checked(settings)
    check_core_normals(values, core.normals, "--core-normals")
    return values


def _prepare(reference_path: Path, core: CoreInput, values: dict, settings: dict, reading: EpochReading) -> Prepared:
    """A new store's reference, core points, core normals and parameters as recorded, read once."""
    read = lambda path: read_cloud(path, drop_nonfinite=reading.drop_nonfinite)  # noqa: E731
    reference = read(reference_path)
    core_cloud = read(core.path) if core.path is not None else None
    recorded = parameters.recorded(settings, reference, core_cloud, reference_name=str(reference_path),
                                   core_name=None if core.path is None else str(core.path),
                                   read_points=lambda path: read(path).xyz)
    core_xyz = core_points_for(reference.xyz, core_cloud.xyz if core_cloud is not None else None,
                               values["core_spacing"])
    if len(core_xyz) == 0:
        raise UsageError("no core points: there is nothing to compute")
    core_xyz = np.ascontiguousarray(core_xyz)
    normals_input = None
    if values["normal_source"] == "core":
        normals_input = given_core_normals(core.normals, core_cloud, read)
        require_one_per_core_point(normals_input, len(core_xyz))
    comparison = Comparison(reference.xyz, core_xyz, parameters.engine_params(recorded, core_xyz), normals_input,
                            reading.threads)
    return Prepared(reference, str(reference_path.resolve()), core_xyz, normals_input, recorded, comparison)


def _new_store_attributes(reference_path: Path, core_path, recorded: dict) -> dict:
    ref_time = epochs_mod.metadata_epoch(reference_path)
    spacing = recorded.get("core_spacing")
    return {
        "format": st.FORMAT, "format_version": st.FORMAT_VERSION, "Conventions": "CF-1.8",
        "title": "M3C2 time series (m3c2kit)",
        "parameters": st.canonical(recorded),
        "reference": str(reference_path.resolve()),
        "reference_sha256": file_digest(reference_path),
        "reference_time": "" if ref_time.time is None else str(ref_time.time),
        "core_points": "file " + str(Path(core_path).resolve()) if core_path is not None else (
            f"reference subsampled to {spacing}" if spacing else "reference"),
        "history": f"{dt.datetime.now(dt.timezone.utc).isoformat(timespec='seconds')} m3c2kit {_version()}: "
                   f"m3c2 series",
    }


def refuse_existing_output(store: Path) -> None:
    """Before any work: -o must be absent or an empty folder. Nothing there is ever deleted (a
    foreign zarr.json and a README were, and a damaged store's advice to create it again deleted
    its epochs)."""
    if not (store.exists() or store.is_symlink()):
        return
    if (store / "zarr.json").is_file():
        try:
            st.open_group(store)
        except st.StoreError:
            raise UsageError(f"{store}: -o holds a Zarr store that is no committed m3c2 series; nothing in it is "
                             f"touched: choose another -o (m3c2 series check {store} says what it holds)") from None
        raise UsageError(f"{store} already holds a series; add epochs with: m3c2 series add {store} EPOCH...")
    refuse_occupied(store)  # absent or an empty folder (the rule staged_directory applies again at publication)


def add(store: Path, epoch_args, *, given_settings=None, reading: EpochReading = EpochReading(),
        dask: DaskTarget = DaskTarget(), log=print) -> int:
    """Appends the epochs not yet in STORE (a killed run resumes here); returns the epochs added.
    `given_settings`: compare keywords given again, each checked against the store's."""
    st.require_extra()
    store = Path(store)
    # The epochs committed when the lock is taken and those this run adds (for the messages);
    # bad epoch names fail here, before the lock is taken.
    plan = {"before": st.committed_epochs(store), "count": len(epochs_mod.resolve(epoch_args))}
    kept = lambda folder: step.committed_epochs_text(store, folder, plan["before"], plan["count"],  # noqa: E731
                                                     "rerun the same command to resume")
    with step.writing(store, "add", kept) as folder:
        return _add(Target(store, folder, plan["before"]), epoch_args, given_settings or {}, reading, dask, log, plan)


def _add(target: Target, epoch_args, given: dict, reading: EpochReading, dask: DaskTarget, log, plan: dict) -> int:
    """add() in the pinned, locked `target.folder`; `plan` gets the committed count and the epochs to add."""
    store, folder = target.store, target.folder
    attrs = st.attributes(folder)
    if attrs.get("imported_from"):
        raise UsageError(f"{store} was imported ({attrs['imported_from']}): its M3C2 parameters are unknown, so no "
                         f"epoch can be added that matches them; compute a new store with m3c2 series")
    recorded = json.loads(attrs["parameters"])
    parameters.check_against_store(store, recorded, given)
    reference_path = Path(attrs["reference"])
    if not reference_path.is_file():
        raise M3C2Error(f"{store}: its reference {reference_path} is gone; a series needs its reference")
    if file_digest(reference_path) != attrs["reference_sha256"]:
        raise M3C2Error(f"{store}: its reference {reference_path} changed since the store was created "
                        f"(SHA-256 differs); create a new store")
    todo, index = _todo(store, folder, epochs_mod.resolve(epoch_args), False, log)  # refusals before any work
    plan.update(before=index, count=len(todo))
    group = st.open_group(folder)
    core = np.ascontiguousarray(np.column_stack([st.read(store, group, a) for a in "xyz"]))
    normals_input = st.read(store, group, "core_normals_input") if "core_normals_input" in group else None
    reference = read_cloud(reference_path, drop_nonfinite=reading.drop_nonfinite)
    if "orient" in given:  # resolved as create recorded it (the reference's scan positions, a FILE's points)
        read_points = lambda path: read_cloud(path, drop_nonfinite=reading.drop_nonfinite).xyz  # noqa: E731
        parameters.check_orient(store, recorded, given["orient"], parameters.recorded_orient(
            given["orient"], reference, reference_name=str(reference_path), read_points=read_points))
    comparison = Comparison(reference.xyz, core, parameters.engine_params(recorded, core), normals_input,
                            reading.threads)
    prepared = Prepared(reference, str(reference_path), core, normals_input, recorded, comparison)
    return _add_epochs(replace(target, index=index), todo, prepared, reading, dask, log)


def _todo(store: Path, folder: Path, resolved, sort: bool, log):
    """The epochs to add: not those whose content is an epoch of the store already (by SHA-256;
    in a format 1 store, without hashes, by resolved path, size and modification time). A file
    at a stored epoch's path whose content changed is refused: the stored epoch would no longer
    be its file's, and a touched file is no new epoch (docs/series.md)."""
    info = st.epoch_info(folder)
    hashes = info.get("source_sha256")
    if sort and all(e.time is not None for e in resolved):
        resolved = sorted(resolved, key=lambda e: e.time)  # stable: equal times keep their order
    todo = []
    if hashes is None:  # format 1
        done = {(s, int(z), int(m)) for s, z, m in zip(info["source"], info["source_size"], info["source_mtime_ns"])}
    else:
        done = {str(h): k for k, h in reversed(list(enumerate(hashes)))}  # the first epoch of each content
        at_path = {str(p): k for k, p in enumerate(info["source"])}
    for e in resolved:
        state = file_state(e.path)  # before the hash: a write during it changes the state too
        digest = file_digest(e.path)
        if hashes is None:
            ident = identity(e.path)
            if ident in done:
                log(f"{e.path}: already in {store} (same path, size and modification time): skipped")
                continue
            done.add(ident)
        else:
            if digest in done:
                k = done[digest]
                where = f"epoch {k} ({info['source'][k]})" if k >= 0 else "an earlier file of this command"
                log(f"{e.path}: its content is already in {store} as {where}: skipped")
                continue
            path = str(Path(e.path).resolve())
            if path in at_path:
                k = at_path[path]
                raise M3C2Error(f"{e.path}: its content changed since it was committed as epoch {k} of {store} "
                                f"(SHA-256 differs): the store's epoch {k} holds the file's former content; a new "
                                f"acquisition needs a file name of its own")
            done[digest] = -1
        todo.append(HashedEpoch(e.path, e.time, e.time_source, digest, state))
    known = info["time"][~np.isnat(info["time"])] if len(info["time"]) else np.array([], "datetime64[us]")
    last = known.max() if len(known) else None
    for e in todo:
        if e.time is not None:
            if last is not None and e.time < last:
                raise UsageError(f"the epoch {e.path} ({e.time}) is older than the store's last epoch ({last}): "
                                 f"epochs are added in time order")
            last = e.time
    return todo, len(info["time"])



def _add_epochs(target: Target, todo, prepared: Prepared, reading: EpochReading, dask: DaskTarget, log) -> int:
    """Adds the epochs `todo` (_todo) into `target`: here, one at a time, or on Dask."""
    if dask.used:
        from .dask_epochs import add_on_dask
        return add_on_dask(target, todo, prepared, reading, dask, log)
    batch = Batch(target, len(prepared.core), log)
    try:
        with batch:
            for epoch in todo:
                cloud = read_cloud(epoch.path, drop_nonfinite=reading.drop_nonfinite)
                require_unchanged(epoch)
                check_crs(prepared.reference, cloud, None, ignore=reading.ignore_crs)
                raw = prepared.comparison.compare(cloud.xyz, cloud, reading.threads)
                batch.add(epoch_columns(prepared.core, raw), provenance(epoch, len(cloud)), epoch.path)
                del cloud, raw
    except M3C2Error as e:  # a bad or changed epoch file, a CRS mismatch: the epochs before it are committed
        raise with_kept(e, target, len(todo)) from None
    return len(todo)
