"""The Zarr store of a series (docs/series.md), read by ``xarray.open_zarr(STORE)``.

Layout: dimensions ``core`` (the core points, in the order given) and ``epoch``. Per core point:
x, y, z, nx, ny, nz, normal_scale, roughness; per core point and epoch the columns of
``m3c2 compare`` (distance, lod, significant, n1, n2, sigma1, sigma2, status), NaN where compare
writes NaN; per epoch the ``time`` coordinate (CF, UTC; NaT when unknown) and the provenance of
the epoch's file. Root attributes: the compare parameters, the reference and the format.

Commit protocol. A batch of epochs (up to the next epoch-chunk boundary: run.py) is written past
the committed end of every array (each array resized once, its block of columns written: every
chunk write of zarr's local store is a file replaced atomically), then committed by consolidating
the metadata: one atomic replace of the root ``zarr.json``, whose consolidated shapes are what
xarray.open_zarr reads. A run killed before that leaves the store as it was at the last commit;
the next run overwrites the uncommitted columns. A kill loses the computation of at most one
batch, never an epoch of the store, and never adds one twice.

Integrity (format 2). Every chunk is written, also one holding only fill values (zarr's
``write_empty_chunks``), so an absent chunk is damage, not NaN; every chunk carries a CRC-32C
after its compression (zarr.codecs.Crc32cCodec), so a truncated or flipped chunk fails to decode
instead of reading as other numbers. A decode error is a StoreError naming the array and the
chunk (:func:`read`). Format 1 stores (no checksum, absent chunks legal) stay readable;
series/integrity.py says what can be proven of them. Writers hold the store's lock
(series/lock.py) and start from its last commit (integrity.recover)."""
from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np

from ..base.errors import M3C2Error, UsageError
from ..engine.result import COMPARISON_COLUMNS, CORE_COLUMNS

FORMAT = "m3c2kit-series"
FORMAT_VERSION = 2
#: The first format whose chunks are all written and checksummed (integrity.py relies on it).
CHECKSUMMED_FROM = 2
#: Per core point and epoch, and per core point: m3c2 compare's columns, split as engine.result does.
EPOCH_COLUMNS = COMPARISON_COLUMNS
EPOCH_INFO = ("time", "source", "source_size", "source_mtime_ns", "time_source", "points", "source_sha256")
TEXT_INFO = ("source", "time_source", "source_sha256")
#: Root attribute: the variables a step is replacing (view.publish_many); set in a commit before
#: the replacement and cleared in the commit after it, so a kill in between leaves them marked
#: and every later step refuses them.
REWRITING = "rewriting"
#: Encoded integer columns: NaN in the compare table is this fill value in the store.
INT_FILL = {"significant": (np.int8, -1), "n1": (np.uint32, 2**32 - 1), "n2": (np.uint32, 2**32 - 1)}
TIME_UNITS = "microseconds since 1970-01-01T00:00:00"
NAT = np.iinfo(np.int64).min


class StoreError(M3C2Error):
    """The store is missing, incomplete or not a series store (exit 1)."""


def require_extra():
    """xarray and zarr, or a UsageError naming the optional extra that installs them."""
    try:
        import xarray
        import zarr
    except ImportError as e:
        raise UsageError(f"m3c2 series needs the optional extra 'series' ({e.name} is not installed): "
                         f"pip install 'm3c2kit[series]'") from None
    if not hasattr(zarr.Array, "with_config"):  # writable(): Zarr 3.1.6 (pyproject.toml's extra says so)
        raise UsageError(f"m3c2 series needs zarr >= 3.1.6 (installed: {zarr.__version__}): "
                         f"pip install -U 'm3c2kit[series]'")
    warnings.filterwarnings("ignore", message="Consolidated metadata is currently not part")
    # The store's lock file and staging folder (series/lock.py, integrity.STAGING) are no Zarr nodes, by design.
    warnings.filterwarnings("ignore", message=r"Object at \.m3c2-\S+ is not recognized as a component")
    return xarray, zarr


def _compressor():
    from zarr.codecs import BloscCodec
    return BloscCodec(cname="zstd", clevel=5, shuffle="bitshuffle")


def codecs() -> tuple:
    """The bytes-to-bytes codecs of every array: compression, then a checksum of the result."""
    from zarr.codecs import Crc32cCodec
    return (_compressor(), Crc32cCodec())


#: Zarr's per-array runtime setting (not stored in the metadata): every chunk is written.
WRITE_CONFIG = {"write_empty_chunks": True}


def writable(group, name: str):
    """The array `name` of `group` (opened for writing) as the store writes: every chunk written."""
    return group[name].with_config(WRITE_CONFIG)


def create(path: Path, core: np.ndarray, normals: dict, attrs: dict, *, core_chunk: int, epoch_chunk: int,
           core_normals_input=None) -> None:
    """A store with the core points, their normals and no epoch, committed."""
    xr, zarr = require_extra()
    n = len(core)
    cc = max(1, min(int(core_chunk), n))
    data = {name: ("core", core[:, k]) for k, name in enumerate("xyz")}
    for k, name in enumerate(("nx", "ny", "nz")):
        data[name] = ("core", normals["normal"][:, k])
    data["normal_scale"] = ("core", normals["normal_scale"])
    data["roughness"] = ("core", normals["roughness"])
    if core_normals_input is not None:
        data["core_normals_input"] = (("core", "axis"), np.asarray(core_normals_input, dtype=np.float64))
    empty = lambda dtype: (("core", "epoch"), np.empty((n, 0), dtype=dtype))
    for name in EPOCH_COLUMNS:
        data[name] = empty(INT_FILL[name][0] if name in INT_FILL else np.uint8 if name == "status" else np.float64)
    for name in TEXT_INFO:
        data[name] = ("epoch", np.array([], dtype=np.dtypes.StringDType()))
    for name in ("source_size", "source_mtime_ns", "points"):
        data[name] = ("epoch", np.array([], dtype=np.int64))
    ds = xr.Dataset(data, coords={"time": ("epoch", np.array([], dtype="datetime64[us]"))}, attrs=attrs)
    ds["time"].attrs.update(standard_name="time", long_name="acquisition time of the epoch (UTC)")
    ds["distance"].attrs.update(long_name="M3C2 distance along the normal", units="same as the coordinates")
    ds["lod"].attrs.update(long_name="level of detection")
    ds["status"].attrs.update(flag_values=list(range(6)), flag_meanings=" ".join(_status_names()))
    comp = codecs()
    enc = {name: {"chunks": (cc, int(epoch_chunk)), "compressors": comp} for name in EPOCH_COLUMNS}
    for name, (dtype, fill) in INT_FILL.items():
        enc[name]["_FillValue"] = dtype(fill)
    for name in CORE_COLUMNS:
        enc[name] = {"chunks": (cc,), "compressors": comp}
    if core_normals_input is not None:
        enc["core_normals_input"] = {"compressors": comp}
    enc["time"] = {"units": TIME_UNITS, "calendar": "proleptic_gregorian", "dtype": "int64", "chunks": (256,),
                   "compressors": comp}
    for name in EPOCH_INFO[1:]:
        enc[name] = {"chunks": (256,), "compressors": comp}
    # "a": into the private folder, which holds its lock file ("w-" refuses a folder with any file)
    # and is a pinned /proc/self/fd path ("w" would try to delete it)
    ds.to_zarr(str(path), mode="a", encoding=enc, consolidated=True, zarr_format=3, write_empty_chunks=True)


def _status_names():
    from ..engine.result import STATUS_NAMES
    return STATUS_NAMES


def open_group(path: Path, mode="r", *, whole: bool = True):
    """The store's root group as committed (consolidated metadata). `whole`: also refuse root
    metadata that is no whole series store (committed_problems; `series check` lists them all)."""
    _, zarr = require_extra()
    if not (Path(path) / "zarr.json").is_file():
        raise StoreError(f"{path}: not a series store (no zarr.json); a new store is made by "
                         f"m3c2 series REFERENCE EPOCH... -o NEW_FOLDER")
    try:
        group = zarr.open_consolidated(str(path), mode=mode)
    except Exception as e:
        raise StoreError(f"{path}: no committed series store here (its root zarr.json {_root_problem(path, e)}); "
                         f"m3c2 series check {path} lists what it holds") from None
    if group.attrs.get("format") != FORMAT:
        raise StoreError(f"{path}: not an m3c2kit series store (format {group.attrs.get('format')!r})")
    version = group.attrs.get("format_version", 1)
    if type(version) is not int or not 1 <= version <= FORMAT_VERSION:
        raise StoreError(f"{path}: format version {version!r} of {FORMAT} is not one this m3c2kit reads (1 to "
                         f"{FORMAT_VERSION}); a newer m3c2kit may read it, nothing in it is touched")
    problems = committed_problems(group) if whole else []
    if problems:
        more = f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""
        raise StoreError(f"{path}: damaged: {problems[0]}{more}; m3c2 series check {path} lists every damage")
    return group


def _root_problem(path: Path, error: Exception) -> str:
    """Why zarr could not open the root zarr.json, in the user's terms (not zarr's or Python's)."""
    try:
        root = json.loads((Path(path) / "zarr.json").read_bytes())
    except ValueError as e:
        return f"is not valid JSON ({e}: truncated or overwritten?)"
    except OSError as e:
        return f"cannot be read ({e.strerror})"
    if not isinstance(root, dict) or root.get("node_type") != "group":
        return f"holds no Zarr group (a JSON {type(root).__name__} of another shape)"
    return "holds no consolidated metadata" if "consolidated_metadata" not in root else f"is not readable ({error})"


#: The dimensions of every array the store must hold (format 2 adds source_sha256).
REQUIRED_DIMS = {**{name: ("core",) for name in CORE_COLUMNS}, **{name: ("core", "epoch") for name in EPOCH_COLUMNS},
                 **{name: ("epoch",) for name in EPOCH_INFO}}
#: Root attributes every step relies on, all text (parameters a JSON object).
REQUIRED_TEXT_ATTRIBUTES = ("parameters", "reference", "reference_sha256")


def committed_problems(group) -> list[str]:
    """What makes the committed root metadata no whole series store: a required array missing or
    of other dimensions, an array's length along core or epoch not the store's, a required root
    attribute absent or of another type. Valid JSON of another shape was read as a store and
    failed later with tracebacks, or its steps ran on arrays of mismatched lengths."""
    version = group.attrs.get("format_version", 1)
    committed = group.metadata.consolidated_metadata.metadata
    arrays = {name: meta for name, meta in committed.items() if getattr(meta, "node_type", "") == "array"}
    problems = []
    if isinstance(version, int) and version < CHECKSUMMED_FROM:
        problems.extend(_newer_content(arrays, version))
    for name, dims in REQUIRED_DIMS.items():
        if name == "source_sha256" and version < CHECKSUMMED_FROM:
            continue
        if name not in arrays:
            problems.append(f"array {name}: missing from the committed metadata")
        elif tuple(arrays[name].dimension_names or ()) != dims:
            problems.append(f"array {name}: dimensions {arrays[name].dimension_names}, expected {dims}")
    length = {"core": arrays["x"].shape[0] if "x" in arrays and len(arrays["x"].shape) == 1 else None,
              "epoch": arrays["time"].shape[0] if "time" in arrays and len(arrays["time"].shape) == 1 else None}
    for name, meta in sorted(arrays.items()):
        dims = tuple(meta.dimension_names or ())
        if len(dims) != len(meta.shape):
            continue  # no or partial names: reported above when the array is required
        for axis, dim in enumerate(dims):
            if length.get(dim) is not None and meta.shape[axis] != length[dim]:
                problems.append(f"array {name}: {meta.shape[axis]} along {dim}, the store has {length[dim]}")
    attrs = group.attrs
    for name in REQUIRED_TEXT_ATTRIBUTES:
        if not isinstance(attrs.get(name), str):
            problems.append(f"root attribute {name}: {'missing' if name not in attrs else 'not text'}")
    if isinstance(attrs.get("parameters"), str):
        try:
            parameters = json.loads(attrs["parameters"])
        except ValueError:
            parameters = None
        if not isinstance(parameters, dict):
            problems.append("root attribute parameters: not a JSON object of M3C2 parameters")
    marked = attrs.get(REWRITING)
    if marked is not None and not (isinstance(marked, list) and all(isinstance(m, str) for m in marked)):
        problems.append(f"root attribute {REWRITING}: not a list of variable names ({marked!r})")
    return problems


def _newer_content(arrays: dict, version: int) -> list[str]:
    """A store is checked by what it holds, never by what its version says: format 2 content
    (the epochs' hashes, checksummed chunks) under a lower format_version is altered metadata, which
    would switch the missing-chunk and checksum checks off (issue 42: `series check` said sound and
    `objects` ran on all-NaN distances after format_version was set to 1)."""
    found = []
    if "source_sha256" in arrays:
        found.append("array source_sha256")
    checksummed = sorted(name for name, meta in arrays.items()
                         if any(type(c).__name__ == "Crc32cCodec" for c in getattr(meta, "codecs", ())))
    if checksummed:
        found.append(f"checksummed chunks (array {checksummed[0]}{' and more' if len(checksummed) > 1 else ''})")
    if not found:
        return []
    return [f"root attribute format_version: {version}, but the store holds format {CHECKSUMMED_FROM} content "
            f"({', '.join(found)}): its metadata was altered; nothing in it is trusted"]


def committed_epochs(path: Path) -> int:
    return int(open_group(path)["time"].shape[0])


def attributes(path: Path) -> dict:
    return dict(open_group(path).attrs)


def epoch_info(path: Path) -> dict:
    """Per committed epoch: source, size, mtime, time (datetime64[us]), time_source, points and,
    from format 2, source_sha256 (absent from a format 1 store)."""
    g = open_group(path)
    n = g["time"].shape[0]
    info = {name: np.asarray(read(path, g, name, slice(0, n))) for name in EPOCH_INFO if name in g}
    info["time"] = np.where(info["time"] == NAT, np.datetime64("NaT"), info["time"].astype("datetime64[us]"))
    return info


def decode_problem(error: Exception) -> str:
    """Why a chunk did not decode, in the user's terms: the CRC-32C codec's message held the raw
    checksum bytes (issue 42), others a codec's internals."""
    text = str(error)
    if "checksum" in text.lower():
        return "its checksum does not match: the chunk was altered or truncated"
    from ..base.errors import printable
    first = printable(" ".join(text.split()))[:120]
    return f"{type(error).__name__}{': ' + first if first else ''}"


def read(path: Path, group, name: str, selection=slice(None)) -> np.ndarray:
    """group[name][selection], or a StoreError naming the array and the first chunk that does not
    decode (a truncated, flipped or foreign chunk: never read as NaN)."""
    array = group[name]
    try:
        return np.asarray(array[selection])
    except Exception as e:  # noqa: BLE001 - zarr and its codecs raise many types for a bad chunk
        key = bad_chunk(array) or "?"
        raise StoreError(f"{path}: damaged: array {name} chunk {key} cannot be decoded ({decode_problem(e)}); "
                         f"m3c2 series check {path} lists every damage") from None


def write(path: Path, array, name: str, selection, values) -> None:
    """array[selection] = values; a chunk read back to be completed (a partial chunk) that does
    not decode is a StoreError naming it, never overwritten by a mix. OSError (a full disk)
    passes to the step, which says what the store kept."""
    try:
        array[selection] = values
    except OSError:
        raise
    except Exception as e:  # noqa: BLE001 - as read()
        key = bad_chunk(array) or "?"
        raise StoreError(f"{path}: damaged: array {name} chunk {key} cannot be decoded ({decode_problem(e)}); "
                         f"m3c2 series check {path} lists every damage") from None


def chunk_grid(shape, chunks):
    """Every chunk's (key, selection) of an array: key as zarr's default v3 encoding names the file."""
    import itertools
    counts = [-(-s // c) if s else 0 for s, c in zip(shape, chunks)]
    for index in itertools.product(*(range(n) for n in counts)):
        key = "c/" + "/".join(map(str, index)) if index else "c"
        yield key, tuple(slice(i * c, min(s, (i + 1) * c)) for i, c, s in zip(index, chunks, shape))


def bad_chunk(array) -> str | None:
    """The key of the first chunk of `array` that fails to decode, None when all do."""
    for key, selection in chunk_grid(array.shape, array.chunks):
        try:
            array[selection]
        except Exception:  # noqa: BLE001 - as read()
            return key
    return None


def append(path: Path, index: int, columns: dict, info: dict) -> None:
    """Writes epoch `index` (= the committed count) and commits it (see the module docstring)."""
    append_batch(path, index, [(columns, info)])


def epoch_chunk(path: Path) -> int:
    """Epochs per chunk of the store's (core, epoch) arrays."""
    return int(open_group(path)["distance"].chunks[1])


#: Fill of the epochs a derived variable (DERIVED_VARIABLES) was not computed for, by dtype kind.
DERIVED_FILL = {"f": np.nan, "i": -1}
#: The Kalman filter's variables (series/kalman.py; docs/series.md, "Kalman filter"): the smoothed
#: state and its standard deviations, the significance flag, and the filtered moments (core,
#: epoch, moment) a later run resumes from.
KALMAN_VARIABLES = ("kalman_distance", "kalman_distance_sigma", "kalman_rate", "kalman_rate_sigma",
                    "kalman_acceleration", "kalman_acceleration_sigma", "kalman_significant", "kalman_moments")
#: Time-adaptive M3C2's variables (series/tam3c2.py; docs/series.md, "TAM3C2"): distance, LOD,
#: significance, epochs aggregated, and the two sides' (effective) point counts.
TAM3C2_VARIABLES = ("tam3c2_distance", "tam3c2_lod", "tam3c2_significant", "tam3c2_window", "tam3c2_n1",
                    "tam3c2_n2")
#: tam3c2_window's code for a cell holding the epoch's own M3C2 (--fallback m3c2); -1: no distance.
TAM3C2_FROM_EPOCH = 0
#: Variables derived from the epochs (per core point and epoch), kept the length of the series
#: by append_batch: smooth's, objects' labels, the Kalman filter's, TAM3C2's.
DERIVED_VARIABLES = ("smoothed_distance", "object", *KALMAN_VARIABLES, *TAM3C2_VARIABLES)


def append_batch(path: Path, index: int, batch: list) -> None:
    """Writes the epochs index, index + 1, ... of `batch` ((columns, info) pairs; index = the
    committed count) and commits them together (the module docstring): one resize and one block
    write per array, one consolidation. A block that starts and ends on chunk boundaries writes
    whole chunks, never reading back what it replaces. A store of format 1 gets no hash column."""
    if not batch:
        return
    from ..base import fault_hook
    _, zarr = require_extra()
    group = zarr.open_group(str(path), mode="r+", use_consolidated=False)
    end = index + len(batch)
    fault_hook.checkpoint("store-write")
    for name in EPOCH_COLUMNS:
        array = writable(group, name)
        if array.shape[1] != end:
            array.resize((array.shape[0], end))
        write(path, array, name, (slice(None), slice(index, end)),
              np.column_stack([encode(name, columns[name]) for columns, _ in batch]))
    for name in DERIVED_VARIABLES:  # not computed for these epochs (NaN / -1) until their step reruns
        if name in group:
            array = writable(group, name)
            if array.shape[1] != end:
                array.resize((array.shape[0], end, *array.shape[2:]))
            write(path, array, name, (slice(None), slice(index, end)), DERIVED_FILL[array.dtype.kind])
    for name in EPOCH_INFO:
        if name not in group:
            continue  # source_sha256 in a format 1 store
        array = writable(group, name)
        if array.shape[0] != end:
            array.resize((end,))
        values = []
        for _, info in batch:
            value = info[name]
            if name == "time":
                value = NAT if value is None or np.isnat(value) else np.datetime64(value, "us").astype(np.int64)
            values.append(value)
        write(path, array, name, slice(index, end),
              np.asarray(values, dtype=np.dtypes.StringDType() if name in TEXT_INFO else np.int64))
    commit(path)


def commit(path: Path) -> None:
    """Publishes what is written: consolidates the metadata (one atomic replace of the root
    zarr.json)."""
    from ..base import fault_hook
    _, zarr = require_extra()
    fault_hook.checkpoint("store-commit")
    zarr.consolidate_metadata(str(path))


def rewriting(group) -> list[str]:
    """The variables marked as being replaced (REWRITING): half-written if their step is not running."""
    return list(group.attrs.get(REWRITING) or [])


def set_rewriting(path: Path, names) -> None:
    """Commits the REWRITING mark alone: the root attributes are rewritten with the committed
    (consolidated) metadata kept, in one atomic replace of the root zarr.json."""
    _, zarr = require_extra()
    group = zarr.open_consolidated(str(path), mode="r+")
    names = sorted(set(names))
    if names:
        group.attrs[REWRITING] = names
    elif REWRITING in group.attrs:
        del group.attrs[REWRITING]


def encode(name: str, values: np.ndarray) -> np.ndarray:
    if name in INT_FILL:
        dtype, fill = INT_FILL[name]
        return np.where(np.isnan(values), fill, values).astype(dtype)
    if name == "status":
        return np.asarray(values, dtype=np.uint8)
    return np.asarray(values, dtype=np.float64)


def canonical(settings: dict) -> str:
    return json.dumps(settings, sort_keys=True, default=str)
