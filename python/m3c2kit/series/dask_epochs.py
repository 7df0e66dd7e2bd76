"""A series' epochs as tasks on a Dask cluster (docs/series.md, "Exactness"): each task compares
one epoch on a worker that prepares the reference once per store and parameter set, and the
client, the one writer (series.batch), commits the results in epoch order: the same store, bit
for bit, as a run on this machine.

The epochs are tasks of the one executor of tasks (run.dask.execute) in its ordered mode: a new
epoch is submitted only when the oldest one is committed, so at most the submission window's
epochs are computed or waiting at any time, and every wait is bounded (ClusterWatch)."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..base.errors import M3C2Error
from ..io import read_cloud
from ..io.crs import check_crs
from . import parameters
from . import store as st
from .batch import Batch, Target, epoch_columns, with_kept
from .engine import Comparison
from .epoch_files import provenance, require_unchanged
from .run_options import DaskTarget, EpochReading


@dataclass(frozen=True)
class EpochTask:
    """One epoch to compare on a worker (picklable): the store (its core points), the reference
    (absolute path), the store's recorded parameters (series.parameters: nothing else to read),
    the given core normals (--normal-source core), the epoch's file and how clouds are read."""

    store: str
    reference: str
    settings: dict
    normals_input: np.ndarray | None
    epoch: str
    reading: EpochReading


#: A worker's prepared reference: (key, (reference cloud, core points, Comparison)).
_WORKER_CACHE: dict = {}


def dask_epoch(task: EpochTask) -> dict:
    """The store's columns of one epoch, and its point count ("points"), computed on a worker."""
    key = (task.store, task.reference, st.canonical(task.settings))
    if key not in _WORKER_CACHE:
        _WORKER_CACHE.clear()
        ref = read_cloud(task.reference, drop_nonfinite=task.reading.drop_nonfinite)
        group = st.open_group(Path(task.store))
        core = np.ascontiguousarray(np.column_stack([np.asarray(group[a][:]) for a in "xyz"]))
        comparison = Comparison(ref.xyz, core, parameters.engine_params(task.settings, core), task.normals_input,
                                task.reading.threads)
        _WORKER_CACHE[key] = (ref, core, comparison)
    ref, core, comparison = _WORKER_CACHE[key]
    cloud = read_cloud(task.epoch, drop_nonfinite=task.reading.drop_nonfinite)
    check_crs(ref, cloud, None, ignore=task.reading.ignore_crs)
    out = epoch_columns(core, comparison.compare(cloud.xyz, cloud, task.reading.threads))
    out["points"] = len(cloud)
    return out


def add_on_dask(target: Target, todo, prepared, reading: EpochReading, dask: DaskTarget, log) -> int:
    """The epochs `todo` as tasks on the cluster of `dask` (run.dask.execute, the one executor of
    tasks, in its ordered mode), committed in epoch order (Batch) into `target`; `prepared`: the
    run's series.run.Prepared. Every wait is bounded (a lost scheduler or no live worker is an
    M3C2Error naming them); after any failure the store is at its last commit and the message
    says which epochs of this run it holds."""
    from ..run.dask import connect, execute
    client = dask.client if dask.client is not None else connect(dask.address)
    store = str(Path(target.store).resolve())
    tasks = [EpochTask(store, prepared.reference_path, prepared.settings, prepared.normals_input, str(e.path), reading)
             for e in todo]
    committed = 0

    def commit(out: dict) -> None:  # in epoch order (ordered=True), whatever order they finish in
        nonlocal committed
        epoch = todo[committed]
        committed += 1
        require_unchanged(epoch)  # the worker read it before its result came back
        batch.add(out, provenance(epoch, out["points"]), epoch.path)

    try:
        batch = Batch(target, len(prepared.core), log)
        try:
            with batch:
                execute(tasks, dask_epoch, commit, client=client, retries=0, ordered=True, address=dask.address,
                        log=lambda s: None,  # the batch reports each commit
                        describe=lambda task, k: f"epoch {target.index + k} ({todo[k].path})")
        except M3C2Error as e:  # a lost scheduler or worker, a task's error: say what the store kept
            raise with_kept(e, target, len(todo)) from None
        return len(todo)
    finally:
        if dask.client is None:
            client.close()
