"""Analysis on a series store, chunk by chunk over the core points (docs/series.md): temporal
median smoothing, change points, and 4D objects-by-change (Anders et al. 2021) written as a
table and as a label per core point and epoch."""
from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from ..errors import UsageError
from ..io.arrays import bounds
from ..io.atomic import staged_outputs
from . import engine
from . import store as st

SMOOTHED = "smoothed_distance"
LABEL = "object"
#: Variables derived from the epochs: kept the length of the series by `add` (new epochs NaN /
#: no object), their `epochs` attribute saying how many epochs they were computed from.
DERIVED = (SMOOTHED, LABEL)


def _core_chunks(group, name="distance"):
    n, chunk = group[name].shape[0], group[name].chunks[0]
    return [(b, min(n, b + chunk)) for b in range(0, n, chunk)]


def _new_variable(store: Path, name: str, dtype, fill, attrs: dict):
    """A (core, epoch) array shaped and chunked like `distance` (replacing any earlier one)."""
    xr, zarr = st.require_extra()
    group = zarr.open_group(str(store), mode="r+", use_consolidated=False)
    model = group["distance"]
    if name in group:
        del group[name]
    array = group.create_array(name, shape=model.shape, chunks=model.chunks, dtype=dtype, fill_value=fill,
                               compressors=(st._compressor(),), dimension_names=("core", "epoch"),
                               attributes=dict(attrs, coordinates="time"))
    return group, array


def smooth(store: Path, window: int, threads: int = 0) -> int:
    """Writes `smoothed_distance`: the temporal median of `distance` over `window` epochs."""
    if window < 1:
        raise UsageError(f"--window must be >= 1 epoch, got {window}")
    group = st.open_group(store)
    epochs = group["distance"].shape[1]
    if epochs == 0:
        raise UsageError(f"{store} has no epoch to smooth")
    _, zarr = st.require_extra()
    out_group, out = _new_variable(store, SMOOTHED, np.float64, np.nan,
                                   {"long_name": f"temporal median of distance over {window} epochs",
                                    "window": int(window), "epochs": int(epochs)})
    source = zarr.open_group(str(store), mode="r", use_consolidated=False)["distance"]
    for begin, end in _core_chunks(group):
        block = np.asarray(source[begin:end, :epochs])
        out[begin:end, :epochs] = engine.temporal_median(block, window, threads)
    zarr.consolidate_metadata(str(store))
    return epochs


#: Above this many bytes, the series 4D-OBC runs on is held in a memory-mapped temporary file
#: (filled one core chunk at a time) rather than in memory: the kernel pages it in and out, so
#: the process's own memory stays at one chunk. Region growing reads any core point's series,
#: which is why the whole variable is mapped rather than streamed.
IN_MEMORY_LIMIT = 1 << 30


def analysed_variable(store: Path, use: str = "auto") -> str:
    """smoothed_distance when it covers every epoch (use auto or smoothed), else distance."""
    group = st.open_group(store)
    n = group["distance"].shape[1]
    if use in ("auto", "smoothed") and SMOOTHED in group and int(group[SMOOTHED].attrs.get("epochs", -1)) == n:
        return SMOOTHED
    if use == "smoothed":
        raise UsageError(f"{store}: no smoothed_distance covering all {n} epochs; run m3c2 series smooth {store}")
    return "distance"


def distances_for_analysis(store: Path, use: str = "auto", epochs: slice | None = None,
                           in_memory_limit: int | None = None) -> tuple[np.ndarray, str]:
    """The (core, epoch) float64 series 4D-OBC runs on (analysed_variable), read one core chunk
    at a time; only that variable is read. Larger than `in_memory_limit` (IN_MEMORY_LIMIT) bytes,
    it is a numpy.memmap of an unlinked temporary file."""
    group = st.open_group(store)
    n = group["distance"].shape[1]
    name = analysed_variable(store, use)
    sl = epochs or slice(0, n)
    shape = (group[name].shape[0], len(range(*sl.indices(n))))
    limit = IN_MEMORY_LIMIT if in_memory_limit is None else in_memory_limit
    if shape[0] * shape[1] * 8 > limit:
        import tempfile
        values = np.memmap(tempfile.TemporaryFile(prefix="m3c2-series-"), dtype=np.float64, mode="w+", shape=shape)
    else:
        values = np.empty(shape)
    for begin, end in _core_chunks(group, name):
        values[begin:end] = np.asarray(group[name][begin:end, sl]).astype(np.float64)
    return values, name


def series_of(store: Path, core: int, use: str = "auto") -> tuple[np.ndarray, str]:
    """One core point's series of the analysed variable (reads its chunks only)."""
    group = st.open_group(store)
    name = analysed_variable(store, use)
    n_core = group[name].shape[0]
    if not 0 <= core < n_core:
        raise UsageError(f"--core {core} is not a core point of {store} (0..{n_core - 1})")
    return np.asarray(group[name][core, :]).astype(np.float64), name


def objects(store: Path, output: Path, params, *, use="auto", threads=0, first_epoch=0, progress=None) -> dict:
    """4D-OBC on the store: the objects table at `output` (CSV), each object's core points at
    OUTPUT_members.csv, the label of each core point and epoch in the store's `object` variable."""
    group = st.open_group(store)
    n_epochs = group["distance"].shape[1]
    values, name = distances_for_analysis(store, use, slice(first_epoch, n_epochs))
    core = np.column_stack([np.asarray(group[a][:]) for a in "xyz"])
    out = engine.objects_by_change(values, core, params, threads, progress)
    out["first_epoch"] = first_epoch
    out["variable"] = name
    times = np.asarray(group["time"][:n_epochs])
    write_tables(output, out, core, times, first_epoch)
    write_labels(store, out, first_epoch, n_epochs)
    return out


def object_members(out: dict, k: int) -> tuple[np.ndarray, np.ndarray]:
    a, b = int(out["member_offsets"][k]), int(out["member_offsets"][k + 1])
    return out["members"][a:b], out["member_dtw"][a:b]


def _time_text(times, index):
    t = times[index]
    return "" if t == st.NAT else str(np.datetime64(int(t), "us"))


def write_tables(output: Path, out: dict, core: np.ndarray, times: np.ndarray, first_epoch: int) -> None:
    output = Path(output)
    members_path = output.with_name(output.stem + "_members.csv")
    # Both tables appear together, whole, or not at all (a failed or killed run leaves neither).
    with staged_outputs([output, members_path]) as staged, \
            open(staged[output], "w", newline="") as f, open(staged[members_path], "w", newline="") as g:
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


def write_labels(store: Path, out: dict, first_epoch: int, n_epochs: int) -> None:
    _, zarr = st.require_extra()
    group, array = _new_variable(store, LABEL, np.int32, -1,
                                 {"long_name": "4D object-by-change holding the core point at the epoch (-1: none)",
                                  "epochs": int(n_epochs), "_FillValue": -1, "source_variable": out["variable"]})
    for begin, end in _core_chunks(group):
        array[begin:end, :n_epochs] = labels(out, array.shape[0], n_epochs, first_epoch, (begin, end))
    zarr.consolidate_metadata(str(store))
