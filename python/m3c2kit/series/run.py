"""Computing a series into its store: ``m3c2 series REFERENCE EPOCH... -o STORE`` (create) and
``m3c2 series add STORE EPOCH...`` (append). Core points and normals come from the reference once;
then one epoch at a time is read, compared and committed, so memory is bounded by the reference
and the largest epoch. With a Dask scheduler the epochs are tasks and their results are
committed in epoch order: the same store, bit for bit."""
from __future__ import annotations

import datetime as dt
import hashlib
import json
import os
import time
import uuid
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..run.cores import core_points_for
from ..base.errors import M3C2Error, UsageError
from ..io import read_cloud
from ..io.atomic import refuse_occupied, staged_directory
from ..engine.result import Result
from . import epochs as epochs_mod
from . import lock as lock_mod
from . import step
from . import store as st
from .engine import Comparison


def _version() -> str:
    try:
        from importlib.metadata import version
        return version("m3c2kit")
    except Exception:  # noqa: BLE001 - an uninstalled tree
        return "unknown"


def file_digest(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def file_state(path: Path) -> tuple:
    """What a write to the file changes: device, inode, size, modification and change time. The
    change time cannot be set back (touch restores a modification time), so an edit between the
    hash of an epoch and its read, even one keeping size and mtime, is seen (require_unchanged)."""
    s = os.stat(path)
    return s.st_dev, s.st_ino, s.st_size, s.st_mtime_ns, s.st_ctime_ns


def require_unchanged(epoch) -> None:
    """After an epoch is read: its file is the one hashed (HashedEpoch.state), or an M3C2Error;
    else the store would keep one content's SHA-256 with another content's distances."""
    if getattr(epoch, "state", ()) and file_state(epoch.path) != epoch.state:
        raise M3C2Error(f"{epoch.path}: changed while this run read it (its size, inode or times differ from when "
                        f"its SHA-256 was taken); it is not added: rerun when the file is written whole")


def epoch_columns(core: np.ndarray, raw: dict) -> dict:
    """The store's per-epoch columns: those of m3c2 compare's table (Result.columns)."""
    table = Result.from_engine(core, raw, {}).columns()
    return {name: table[name] for name in st.EPOCH_COLUMNS}


def _orient(settings: dict, reference) -> dict:
    """As m3c2 compare: --orient, else the reference's scan positions, else +z; none with
    --normal-source core (the given normals are used as they are: settings.needs)."""
    if "orient" not in settings and settings.get("normal_source") != "core":
        positions = getattr(reference, "scan_positions", None)
        settings = dict(settings, orient=positions.tolist() if positions is not None and len(positions) else "+z")
    return settings


def _engine_settings(settings: dict) -> dict:
    """The keywords of m3c2kit.settings.build_params (orientation points given as a list become an array)."""
    out = {k: v for k, v in settings.items() if k not in ("core_spacing",)}
    if isinstance(out.get("orient"), list):
        out["orient"] = np.asarray(out["orient"], dtype=np.float64).reshape(-1, 3)
    return out


def create(reference_path: Path, epoch_args, store: Path, settings: dict, *, core_path=None, core_normals=None,
           threads=0, dask_scheduler=None, client=None, core_chunk=16384, epoch_chunk=8, drop_nonfinite=False,
           ignore_crs=False, log=print) -> int:
    """Creates STORE from the reference and adds the epochs; returns the epochs added."""
    st.require_extra()
    store = Path(store)
    refuse_existing_output(store)
    resolved = epochs_mod.resolve(epoch_args)  # bad epoch names fail before any work
    reference = read_cloud(reference_path, drop_nonfinite=drop_nonfinite)
    core_cloud = read_cloud(core_path, drop_nonfinite=drop_nonfinite) if core_path is not None else None
    settings = _orient(settings, reference)
    core = core_points_for(reference.xyz, core_cloud.xyz if core_cloud is not None else None,
                               settings.get("core_spacing"))
    if len(core) == 0:
        raise UsageError("no core points: there is nothing to compute")
    core = np.ascontiguousarray(core)
    comparison = Comparison(reference.xyz, core, _engine_settings(settings), core_normals, threads)
    ref_time = epochs_mod.metadata_epoch(Path(reference_path))
    attrs = {
        "format": st.FORMAT, "format_version": st.FORMAT_VERSION, "Conventions": "CF-1.8",
        "title": "M3C2 time series (m3c2kit)",
        "parameters": st.canonical(settings),
        "reference": str(Path(reference_path).resolve()),
        "reference_sha256": file_digest(Path(reference_path)),
        "reference_time": "" if ref_time.time is None else str(ref_time.time),
        "core_points": "file " + str(Path(core_path).resolve()) if core_path is not None else (
            f"reference subsampled to {settings['core_spacing']}" if settings.get("core_spacing") else "reference"),
        "history": f"{dt.datetime.now(dt.timezone.utc).isoformat(timespec='seconds')} m3c2kit {_version()}: "
                   f"m3c2 series",
    }
    # The empty store is built in a private folder and appears at -o whole, its lock already held
    # (lockf locks the file, which the rename moves along), so no other writer comes in between;
    # its epochs are then committed into it as `add` commits them, so a kill keeps those committed.
    held = None
    try:
        with staged_directory(store) as folder:
            st.create(Path(folder), core, comparison.normals(), attrs, core_chunk=core_chunk,
                      epoch_chunk=epoch_chunk, core_normals_input=core_normals)
            held = lock_mod.acquire(Path(folder), "create", store)
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
        return _add_epochs(folder, todo, index, comparison, core, reference, threads=threads,
                           dask_scheduler=dask_scheduler, client=client, settings=settings,
                           drop_nonfinite=drop_nonfinite, ignore_crs=ignore_crs, log=log, store=store)


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


def stored_settings(store: Path) -> dict:
    return json.loads(st.attributes(store)["parameters"])


def check_settings(store: Path, stored: dict, given: dict) -> None:
    """A store holds one parameter set: an option given to `add` must equal the stored one."""
    for name, value in given.items():
        if name == "threads":
            continue
        if st.canonical(stored.get(name)) != st.canonical(value):
            raise UsageError(f"{store} was computed with {name} = {stored.get(name)!r}, not {value!r}: a store holds "
                             f"epochs of one parameter set; create a new store for other parameters")


def add(store: Path, epoch_args, *, given_settings=None, threads=0, dask_scheduler=None, client=None,
        drop_nonfinite=False, ignore_crs=False, log=print) -> int:
    """Appends the epochs not yet in STORE (a killed run resumes here); returns the epochs added."""
    xr, zarr = st.require_extra()
    store = Path(store)
    # The epochs committed when the lock is taken and those this run adds (for the messages);
    # bad epoch names fail here, before the lock is taken.
    plan = {"before": st.committed_epochs(store), "count": len(epochs_mod.resolve(epoch_args))}
    kept = lambda folder: step.committed_epochs_text(store, folder, plan["before"], plan["count"],
                                                     "rerun the same command to resume")
    with step.writing(store, "add", kept) as folder:
        return _add(store, folder, epoch_args, given_settings=given_settings, threads=threads,
                    dask_scheduler=dask_scheduler, client=client, drop_nonfinite=drop_nonfinite,
                    ignore_crs=ignore_crs, log=log, plan=plan)


def _add(store: Path, folder: Path, epoch_args, *, given_settings, threads, dask_scheduler, client, drop_nonfinite,
         ignore_crs, log, plan: dict) -> int:
    """add() in the pinned, locked `folder`; `plan` gets the committed count and the epochs to add."""
    attrs = st.attributes(folder)
    if attrs.get("imported_from"):
        raise UsageError(f"{store} was imported ({attrs['imported_from']}): its M3C2 parameters are unknown, so no "
                         f"epoch can be added that matches them; compute a new store with m3c2 series")
    settings = json.loads(attrs["parameters"])
    check_settings(store, settings, given_settings or {})
    reference_path = Path(attrs["reference"])
    if not reference_path.is_file():
        raise M3C2Error(f"{store}: its reference {reference_path} is gone; a series needs its reference")
    if file_digest(reference_path) != attrs["reference_sha256"]:
        raise M3C2Error(f"{store}: its reference {reference_path} changed since the store was created "
                        f"(SHA-256 differs); create a new store")
    todo, index = _todo(store, folder, epochs_mod.resolve(epoch_args), False, log)  # refusals before any work
    plan.update(before=index, count=len(todo))
    group = st.open_group(folder)
    core = np.column_stack([st.read(store, group, a) for a in "xyz"])
    normals_input = st.read(store, group, "core_normals_input") if "core_normals_input" in group else None
    reference = read_cloud(reference_path, drop_nonfinite=drop_nonfinite)
    comparison = Comparison(reference.xyz, np.ascontiguousarray(core), _engine_settings(settings), normals_input,
                            threads)
    return _add_epochs(folder, todo, index, comparison, core, reference, threads=threads,
                       dask_scheduler=dask_scheduler, client=client, settings=settings, drop_nonfinite=drop_nonfinite,
                       ignore_crs=ignore_crs, log=log, store=store)


def _identity(path: Path) -> tuple[str, int, int]:
    s = os.stat(path)
    return str(Path(path).resolve()), int(s.st_size), int(s.st_mtime_ns)


@dataclass(frozen=True)
class HashedEpoch(epochs_mod.Epoch):
    """An epoch to add with the SHA-256 of its file's content (its identity in the store)."""
    sha256: str = ""
    state: tuple = ()  # file_state when the hash was taken


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
            ident = _identity(e.path)
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


def _info(epoch, points: int) -> dict:
    path, size, mtime = _identity(epoch.path)
    return {"time": epoch.time, "source": path, "source_size": size, "source_mtime_ns": mtime,
            "time_source": epoch.time_source, "points": points,
            "source_sha256": getattr(epoch, "sha256", "") or file_digest(epoch.path)}


def _add_epochs(folder, todo, index, comparison, core, reference, *, threads, dask_scheduler, client, settings,
                drop_nonfinite, ignore_crs, log, store) -> int:
    """Adds the epochs `todo` (_todo) from epoch `index` on into the store's pinned `folder`
    (messages name `store`)."""
    if dask_scheduler is not None or client is not None:
        return _add_dask(store, todo, index, core, settings, threads, dask_scheduler, client, drop_nonfinite,
                         ignore_crs, log, folder=folder)
    from ..io.crs import check_crs
    batch = Batch(folder, index, len(core), log)
    try:
        with batch:
            for epoch in todo:
                cloud = read_cloud(epoch.path, drop_nonfinite=drop_nonfinite)
                require_unchanged(epoch)
                check_crs(reference, cloud, None, ignore=ignore_crs)
                raw = comparison.compare(cloud.xyz, cloud, threads)
                batch.add(epoch_columns(core, raw), _info(epoch, len(cloud)), epoch.path)
                del cloud, raw
    except M3C2Error as e:  # a bad or changed epoch file, a CRS mismatch: the epochs before it are committed
        raise _with_kept(e, store, folder, index, len(todo)) from None
    return len(todo)


def _with_kept(error: M3C2Error, store, folder, index: int, planned: int) -> M3C2Error:
    """`error` with what the store kept of this run (step.committed_epochs_text): the message
    of an epoch that failed after others were committed said nothing of them. An interruption is
    left to step.guarded, which says the same."""
    if step.is_interruption(error):
        return error
    kept = step.committed_epochs_text(store, folder, index, planned, f"resume with: m3c2 series add {store} EPOCH...")
    return type(error)(f"{error}; {kept}")


class Batch:
    """The epochs computed but not yet committed, committed together (store.append_batch) when
    the next one would start a new epoch chunk, when they hold more than MAX_BYTES, when the
    oldest waited MAX_SECONDS, and when the run ends, also by an error (the epochs before the
    failing one are kept, as when each was committed alone). Writing whole chunks at once instead
    of one column per epoch (each column rewrote every chunk it touched and every array's
    metadata) was 90 % of a series' time (docs/performance.md). A kill loses at most the
    batch's computation: the store stays at its last commit (store.py)."""

    MAX_BYTES = 256 << 20
    MAX_SECONDS = 60.0

    def __init__(self, store: Path, index: int, n_core: int, log):
        self.store, self.index, self.log = store, index, log
        self.chunk = st.epoch_chunk(store)
        self.epoch_bytes = n_core * 64  # 8 columns of at most 8 bytes
        self.pending: list = []
        self.started = 0.0

    def add(self, columns: dict, info: dict, path) -> None:
        if not self.pending:
            self.started = time.monotonic()
        self.pending.append((columns, info, path))
        end = self.index + len(self.pending)
        if (end % self.chunk == 0 or len(self.pending) * self.epoch_bytes >= self.MAX_BYTES
                or time.monotonic() - self.started >= self.MAX_SECONDS):
            self.commit()

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> bool:
        self.commit()
        return False

    def commit(self) -> None:
        if not self.pending:
            return
        pending, self.pending = self.pending, []  # a failed commit is not tried again on the way out
        st.append_batch(self.store, self.index, [(c, i) for c, i, _ in pending])
        self.pending = pending
        for k, (_, _, path) in enumerate(self.pending):
            self.log(f"epoch {self.index + k}: {path} committed")
        self.index += len(self.pending)
        self.pending = []


# Dask: a worker prepares the reference once per store and parameter set, then compares epochs.
_WORKER_CACHE: dict = {}


def dask_epoch(store: str, reference: str, settings: dict, normals_input, epoch: str, threads: int,
               drop_nonfinite: bool, ignore_crs: bool) -> dict:
    key = (store, reference, st.canonical(settings))
    if key not in _WORKER_CACHE:
        _WORKER_CACHE.clear()
        ref = read_cloud(reference, drop_nonfinite=drop_nonfinite)
        group = st.open_group(Path(store))
        core = np.ascontiguousarray(np.column_stack([np.asarray(group[a][:]) for a in "xyz"]))
        _WORKER_CACHE[key] = (ref, core, Comparison(ref.xyz, core, _engine_settings(settings), normals_input, threads))
    ref, core, comparison = _WORKER_CACHE[key]
    from ..io.crs import check_crs
    cloud = read_cloud(epoch, drop_nonfinite=drop_nonfinite)
    check_crs(ref, cloud, None, ignore=ignore_crs)
    out = epoch_columns(core, comparison.compare(cloud.xyz, cloud, threads))
    out["points"] = len(cloud)
    return out


def _add_dask(store, todo, index, core, settings, threads, address, client, drop_nonfinite, ignore_crs, log,
              folder=None) -> int:
    """The epochs as tasks on a Dask cluster, committed in epoch order (Batch). The connection and
    every wait are bounded (run.dask.connect, ClusterWatch: a lost scheduler or no live worker is
    an M3C2Error naming them); after any failure the store is at its last commit and the message
    says which epochs of this run it holds."""
    from ..run.dask import ClusterWatch, connect
    own = client is None
    if own:
        client = connect(address)  # the command line connects before the store is created
    try:
        watch = ClusterWatch(client, address)
        group = st.open_group(store)
        normals_input = np.asarray(group["core_normals_input"][:]) if "core_normals_input" in group else None
        reference = st.attributes(store)["reference"]
        run_id = uuid.uuid4().hex[:8]
        window = max(2, 2 * watch.workers)
        futures = []
        submitted = 0

        def submit():
            nonlocal submitted
            e = todo[submitted]
            futures.append(client.submit(dask_epoch, str(Path(store).resolve()), reference, settings, normals_input,
                                         str(e.path), threads, drop_nonfinite, ignore_crs, pure=False,
                                         key=f"m3c2-series-{run_id}-{submitted}"))
            submitted += 1

        while submitted < min(window, len(todo)):
            submit()
        batch = Batch(folder or store, index, len(core), log)  # folder: the store pinned by its writing step
        try:
            with batch:
                for k, epoch in enumerate(todo):  # committed in epoch order, whatever order they finish in
                    watch.wait([futures[k]], lambda: f"epoch {index + k} ({epoch.path})")
                    out = futures[k].result()
                    futures[k].release()
                    futures[k] = None
                    if submitted < len(todo):
                        submit()
                    require_unchanged(epoch)  # the worker read it before its result came back
                    batch.add(out, _info(epoch, out["points"]), epoch.path)
        except M3C2Error as e:  # a lost scheduler or worker, a task's error: say what the store kept
            raise _with_kept(e, store, folder or store, index, len(todo)) from None
        return len(todo)
    finally:
        if own:
            client.close()

