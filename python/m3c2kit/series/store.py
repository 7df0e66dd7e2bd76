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
batch, never an epoch of the store, and never adds one twice."""
from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np

from ..errors import M3C2Error, UsageError

FORMAT = "m3c2kit-series"
FORMAT_VERSION = 1
#: Per core point and epoch, as m3c2 compare's columns (result.COLUMNS).
EPOCH_COLUMNS = ("distance", "lod", "significant", "n1", "n2", "sigma1", "sigma2", "status")
CORE_COLUMNS = ("x", "y", "z", "nx", "ny", "nz", "normal_scale", "roughness")
EPOCH_INFO = ("time", "source", "source_size", "source_mtime_ns", "time_source", "points")
TEXT_INFO = ("source", "time_source")
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
    warnings.filterwarnings("ignore", message="Consolidated metadata is currently not part")
    return xarray, zarr


def _compressor():
    from zarr.codecs import BloscCodec
    return BloscCodec(cname="zstd", clevel=5, shuffle="bitshuffle")


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
    data["source"] = ("epoch", np.array([], dtype=np.dtypes.StringDType()))
    data["time_source"] = ("epoch", np.array([], dtype=np.dtypes.StringDType()))
    for name in ("source_size", "source_mtime_ns", "points"):
        data[name] = ("epoch", np.array([], dtype=np.int64))
    ds = xr.Dataset(data, coords={"time": ("epoch", np.array([], dtype="datetime64[us]"))}, attrs=attrs)
    ds["time"].attrs.update(standard_name="time", long_name="acquisition time of the epoch (UTC)")
    ds["distance"].attrs.update(long_name="M3C2 distance along the normal", units="same as the coordinates")
    ds["lod"].attrs.update(long_name="level of detection")
    ds["status"].attrs.update(flag_values=list(range(6)), flag_meanings=" ".join(_status_names()))
    comp = (_compressor(),)
    enc = {name: {"chunks": (cc, int(epoch_chunk)), "compressors": comp} for name in EPOCH_COLUMNS}
    for name, (dtype, fill) in INT_FILL.items():
        enc[name]["_FillValue"] = dtype(fill)
    for name in CORE_COLUMNS:
        enc[name] = {"chunks": (cc,), "compressors": comp}
    enc["time"] = {"units": TIME_UNITS, "calendar": "proleptic_gregorian", "dtype": "int64", "chunks": (256,)}
    for name in ("source", "time_source", "source_size", "source_mtime_ns", "points"):
        enc[name] = {"chunks": (256,)}
    ds.to_zarr(str(path), mode="w", encoding=enc, consolidated=True, zarr_format=3)


def _status_names():
    from ..result import STATUS_NAMES
    return STATUS_NAMES


def open_group(path: Path, mode="r"):
    """The store's root group as committed (consolidated metadata)."""
    _, zarr = require_extra()
    if not (Path(path) / "zarr.json").is_file():
        raise StoreError(f"{path}: not a series store (no zarr.json); create one with m3c2 series REFERENCE EPOCH... -o {path}")
    try:
        group = zarr.open_consolidated(str(path), mode=mode)
    except Exception as e:
        raise StoreError(f"{path}: the store was never committed ({e}); create it again") from None
    if group.attrs.get("format") != FORMAT:
        raise StoreError(f"{path}: not an m3c2kit series store (format {group.attrs.get('format')!r})")
    return group


def committed_epochs(path: Path) -> int:
    return int(open_group(path)["time"].shape[0])


def attributes(path: Path) -> dict:
    return dict(open_group(path).attrs)


def epoch_info(path: Path) -> dict:
    """Per committed epoch: source, size, mtime, time (datetime64[us]), time_source."""
    g = open_group(path)
    n = g["time"].shape[0]
    info = {name: np.asarray(g[name][:n]) for name in EPOCH_INFO}
    info["time"] = np.where(info["time"] == NAT, np.datetime64("NaT"), info["time"].astype("datetime64[us]"))
    return info


def append(path: Path, index: int, columns: dict, info: dict) -> None:
    """Writes epoch `index` (= the committed count) and commits it (see the module docstring)."""
    append_batch(path, index, [(columns, info)])


def epoch_chunk(path: Path) -> int:
    """Epochs per chunk of the store's (core, epoch) arrays."""
    return int(open_group(path)["distance"].chunks[1])


def append_batch(path: Path, index: int, batch: list) -> None:
    """Writes the epochs index, index + 1, ... of `batch` ((columns, info) pairs; index = the
    committed count) and commits them together (the module docstring): one resize and one block
    write per array, one consolidation. A block that starts and ends on chunk boundaries writes
    whole chunks, never reading back what it replaces."""
    if not batch:
        return
    _, zarr = require_extra()
    group = zarr.open_group(str(path), mode="r+", use_consolidated=False)
    end = index + len(batch)
    for name in EPOCH_COLUMNS:
        array = group[name]
        if array.shape[1] != end:
            array.resize((array.shape[0], end))
        array[:, index:end] = np.column_stack([encode(name, columns[name]) for columns, _ in batch])
    for name in ("smoothed_distance", "object"):  # derived variables (analysis.DERIVED): not for these epochs
        if name in group and group[name].shape[1] != end:
            group[name].resize((group[name].shape[0], end))
    for name in EPOCH_INFO:
        array = group[name]
        if array.shape[0] != end:
            array.resize((end,))
        values = []
        for _, info in batch:
            value = info[name]
            if name == "time":
                value = NAT if value is None or np.isnat(value) else np.datetime64(value, "us").astype(np.int64)
            values.append(value)
        array[index:end] = np.asarray(values, dtype=np.dtypes.StringDType() if name in TEXT_INFO else np.int64)
    zarr.consolidate_metadata(str(path))


def encode(name: str, values: np.ndarray) -> np.ndarray:
    if name in INT_FILL:
        dtype, fill = INT_FILL[name]
        return np.where(np.isnan(values), fill, values).astype(dtype)
    if name == "status":
        return np.asarray(values, dtype=np.uint8)
    return np.asarray(values, dtype=np.float64)


def open_dataset(path: Path):
    """xarray.open_zarr of the store as committed."""
    xr, _ = require_extra()
    open_group(path)  # a clear error for a path that is not a committed store
    return xr.open_zarr(str(path))


def canonical(settings: dict) -> str:
    return json.dumps(settings, sort_keys=True, default=str)
