"""Analysis on a series store, chunk by chunk over the core points (docs/series.md): temporal
median smoothing, change points, and 4D objects-by-change (Anders et al. 2021) written as a
table and as a label per core point and epoch.

A step that replaces a variable (smooth, objects' labels) holds the store's lock (series/step.py),
writes the new variable whole in the store's staging folder, invisible to zarr and xarray, and
then publishes it (series/view.py, the store view every analysis step shares): a kill or a full
disk while it computes or writes leaves the previous variable whole and in use; a kill inside the
publication leaves the variable marked half-written (store.REWRITING), which every later step
refuses, naming the step to rerun."""
from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from ..base import fault_hook
from ..base.errors import UsageError
from ..io.arrays import bounds
from ..io.atomic import staged_outputs
from . import engine
from . import integrity
from . import store as st
from .outputs import members_path, table_digests
from .view import StoreView, writing

SMOOTHED = "smoothed_distance"
KALMAN = st.KALMAN_VARIABLES[0]  # series/kalman.py's smoothed distance, which 4D-OBC can segment (--use kalman)
LABEL = "object"
#: Variables derived from the epochs: kept the length of the series by `add` (new epochs NaN /
#: no object), their `epochs` attribute saying how many epochs they were computed from.
DERIVED = st.DERIVED_VARIABLES  # smooth's, objects' labels and the Kalman filter's, listed once (store.py)


def smooth(store: Path, window: int, threads: int = 0) -> int:
    """Writes `smoothed_distance`: the temporal median of `distance` over `window` epochs."""
    if window < 1:
        raise UsageError(f"--window must be >= 1 epoch, got {window}")
    store = Path(store)
    with writing(store, "smooth", (SMOOTHED,), SMOOTHED) as view:
        epochs = view.n_epochs
        if epochs == 0:
            raise UsageError(f"{store} has no epoch to smooth")
        out = view.staged(SMOOTHED, np.float64, np.nan,
                          {"long_name": f"temporal median of distance over {window} epochs",
                           "window": int(window), "epochs": int(epochs)})
        fault_hook.checkpoint("store-write")
        for begin, end in view.core_chunks():
            block = view.read("distance", (slice(begin, end), slice(0, epochs)))
            out[begin:end, :epochs] = engine.temporal_median(block, window, threads)
        view.publish([SMOOTHED])
    return epochs


#: Above this many bytes, the series 4D-OBC runs on is held in a memory-mapped temporary file
#: (filled one core chunk at a time) rather than in memory: the kernel pages it in and out, so
#: the process's own memory stays at one chunk. Region growing reads any core point's series,
#: which is why the whole variable is mapped rather than streamed.
IN_MEMORY_LIMIT = 1 << 30


def analysed_variable(store: Path, use: str = "auto", shown: Path | None = None) -> str:
    """smoothed_distance when it covers every epoch (use auto or smoothed), else distance;
    kalman_distance for use kalman (never chosen by auto). A
    half-written smoothed_distance is refused, never replaced by distance behind the user's back.
    `shown`: the store's path in messages (`store` may be a pinned path)."""
    shown = store if shown is None else shown
    group = st.open_group(store)
    n = group["distance"].shape[1]
    if use == "kalman":  # the Kalman-smoothed series (series/kalman.py), covering every epoch
        integrity.require_whole(group, [KALMAN], shown)
        if KALMAN not in group or int(group[KALMAN].attrs.get("epochs", -1)) != n:
            raise UsageError(f"{shown}: no kalman_distance covering all {n} epochs; run m3c2 series kalman {shown}")
        return KALMAN
    if use in ("auto", "smoothed"):
        integrity.require_whole(group, [SMOOTHED], shown)
    if use in ("auto", "smoothed") and SMOOTHED in group and int(group[SMOOTHED].attrs.get("epochs", -1)) == n:
        return SMOOTHED
    if use == "smoothed":
        raise UsageError(f"{shown}: no smoothed_distance covering all {n} epochs; run m3c2 series smooth {shown}")
    return "distance"


def distances_for_analysis(store: Path, use: str = "auto", epochs: slice | None = None,
                           in_memory_limit: int | None = None, shown: Path | None = None) -> tuple[np.ndarray, str]:
    """The (core, epoch) float64 series 4D-OBC runs on (analysed_variable), read one core chunk
    at a time; only that variable is read. Larger than `in_memory_limit` (IN_MEMORY_LIMIT) bytes,
    it is a numpy.memmap of an unlinked temporary file."""
    shown = store if shown is None else shown
    view = StoreView(shown, store)
    n = view.n_epochs
    name = analysed_variable(store, use, shown)
    sl = epochs or slice(0, n)
    shape = (view.group[name].shape[0], len(range(*sl.indices(n))))
    limit = IN_MEMORY_LIMIT if in_memory_limit is None else in_memory_limit
    if shape[0] * shape[1] * 8 > limit:
        import tempfile
        values = np.memmap(tempfile.TemporaryFile(prefix="m3c2-series-"), dtype=np.float64, mode="w+", shape=shape)
    else:
        values = np.empty(shape)
    for begin, end in view.core_chunks(name):
        values[begin:end] = view.read(name, (slice(begin, end), sl)).astype(np.float64)
    return values, name


def series_of(store: Path, core: int, use: str = "auto") -> tuple[np.ndarray, str]:
    """One core point's series of the analysed variable (reads its chunks only)."""
    group = st.open_group(store)
    name = analysed_variable(store, use)
    integrity.require_present(store)
    n_core = group[name].shape[0]
    if not 0 <= core < n_core:
        raise UsageError(f"--core {core} is not a core point of {store} (0..{n_core - 1})")
    return st.read(store, group, name, (core, slice(None))).astype(np.float64), name


def objects(store: Path, output: Path, params, *, use="auto", threads=0, first_epoch=0, progress=None) -> dict:
    """4D-OBC on the store: the objects table at `output` (CSV), each object's core points at
    OUTPUT_members.csv, the label of each core point and epoch in the store's `object` variable."""
    store = Path(store)
    tables = []  # the tables once written, for the message of a later failure

    def tables_kept() -> str:
        return f"{output} and its members table written; " if tables else "no objects table written; "

    with writing(store, "objects", (LABEL,), LABEL, other_outputs=tables_kept) as view:
        n_epochs = view.n_epochs
        values, name = distances_for_analysis(view.folder, use, slice(first_epoch, n_epochs), shown=store)
        core = view.core()
        out = engine.objects_by_change(values, core, params, threads, progress)
        out["first_epoch"] = first_epoch
        out["variable"] = name
        times = view.read("time", slice(0, n_epochs))
        labels_array = write_labels(view, out, first_epoch, n_epochs)  # published after the tables
        write_tables(output, out, core, times, first_epoch)
        tables.append(output)
        labels_array.attrs.update(table_digests(output))  # a report takes these tables only (outputs.py)
        view.publish([LABEL])
    return out


def object_members(out: dict, k: int) -> tuple[np.ndarray, np.ndarray]:
    a, b = int(out["member_offsets"][k]), int(out["member_offsets"][k + 1])
    return out["members"][a:b], out["member_dtw"][a:b]


def _time_text(times, index):
    t = times[index]
    return "" if t == st.NAT else str(np.datetime64(int(t), "us"))


def write_tables(output: Path, out: dict, core: np.ndarray, times: np.ndarray, first_epoch: int) -> None:
    output = Path(output)
    members = members_path(output)
    # Both tables appear together, whole, or not at all (a failed or killed run leaves neither).
    with staged_outputs([output, members]) as staged, \
            open(staged[output], "w", newline="") as f, open(staged[members], "w", newline="") as g:
        w, m = csv.writer(f), csv.writer(g)
        w.writerow(["object", "seed_core", "start_epoch", "end_epoch", "start_time", "end_time", "threshold",
                    "seed_score", "core_points", "x_min", "y_min", "z_min", "x_max", "y_max", "z_max"])
        m.writerow(["object", "core", "dtw"])
        for k in range(len(out["object_seed"])):
            cores, dtw = object_members(out, k)
            lo, hi = bounds(core[cores])
            s, e = int(out["object_start"][k]) + first_epoch, int(out["object_end"][k]) + first_epoch
            w.writerow([k, int(out["object_seed"][k]), s, e, _time_text(times, s), _time_text(times, e),
                        repr(float(out["object_threshold"][k])), repr(float(out["object_score"][k])), len(cores),
                        *map(repr, map(float, lo)), *map(repr, map(float, hi))])
            for c, d in zip(cores, dtw):
                m.writerow([k, int(c), repr(float(d))])


def labels(out: dict, n_core: int, n_epochs: int, first_epoch: int, rows=None) -> np.ndarray:
    """The object label of each core point (rows [begin, end)) and epoch: the first object whose
    extent holds it, -1 for none."""
    begin, end = rows or (0, n_core)
    lab = np.full((end - begin, n_epochs), -1, dtype=np.int32)
    for k in range(len(out["object_seed"])):
        cores, _ = object_members(out, k)
        cores = cores[(cores >= begin) & (cores < end)] - begin
        if len(cores) == 0:
            continue
        s, e = int(out["object_start"][k]) + first_epoch, int(out["object_end"][k]) + first_epoch + 1
        view = lab[cores, s:e]
        lab[cores, s:e] = np.where(view < 0, k, view)
    return lab


def write_labels(view: StoreView, out: dict, first_epoch: int, n_epochs: int):
    """The `object` variable, staged in the store's staging folder (its writing step publishes
    it: StoreView.publish) and returned."""
    attrs = {"long_name": "4D object-by-change holding the core point at the epoch (-1: none)",
             "epochs": int(n_epochs), "_FillValue": -1, "source_variable": out["variable"]}
    array = view.staged(LABEL, np.int32, -1, attrs)
    fault_hook.checkpoint("store-write")
    for begin, end in view.core_chunks():
        array[begin:end, :n_epochs] = labels(out, array.shape[0], n_epochs, first_epoch, (begin, end))
    return array
