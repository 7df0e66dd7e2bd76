"""Import of a py4dgeo SpatiotemporalAnalysis archive (its zip format, segmentation file format
version as written by py4dgeo 0.x-1.x): core points (corepoints.zip, an Epoch archive holding
cloud.laz), the reference's timestamp (reference_epoch.zip, metadata.json), timestamps.json
(time deltas from the reference), distances and uncertainties (.npz when compressed, .npy
otherwise) and, when present, smoothed_distances. py4dgeo keeps no M3C2 parameters, normals or
reasons: the store says so (attribute `imported_from`), `add` refuses it, and `status` is
derived from the counts (3: n1 = 0, 4: n2 = 0, 5: no LOD, 0: computed).

An archive is untrusted input (issue 31): every member is checked before it is used, and what a
member may make us allocate is bounded before it is read (its declared size, an array's shape
against the bytes that hold it), so a malformed archive is one error naming the archive, the
member and the problem. The store is built in a private folder renamed onto -o at the end
(io.atomic.staged_directory): a failed or killed import leaves no half store."""
from __future__ import annotations

import datetime as dt
import hashlib
import io
import json
import math
import tempfile
import zipfile
from pathlib import Path

import numpy as np

from ..base.errors import CloudReadError, M3C2Error, printable
from ..io.atomic import staged_directory
from ..io.guard import available_memory, format_bytes
from . import lock as lock_mod
from . import store as st

#: The SEGMENTATION_FILE_FORMAT versions this reader knows (py4dgeo's
#: PY4DGEO_SEGMENTATION_FILE_FORMAT_VERSION, 0 in every release so far).
KNOWN_FORMATS = ("0",)
#: py4dgeo's uncertainties record (py4dgeo.m3c2.DistanceUncertainty), as stored.
UNCERTAINTY_FIELDS = ("lodetection", "spread1", "num_samples1", "spread2", "num_samples2")
#: Most bytes one member may declare when no memory figure is known; otherwise half of what is
#: available: the import holds the arrays in memory, a zip bomb's declared size is refused first.
MEMBER_LIMIT_UNKNOWN_MEMORY = 8 << 30


class ArchiveError(CloudReadError):
    """A malformed py4dgeo archive: the message names the archive, the member and the problem."""


def _member_limit() -> int:
    memory = available_memory()
    return MEMBER_LIMIT_UNKNOWN_MEMORY if memory is None else max(memory // 2, 1 << 20)


class _Archive:
    """A zip archive whose members are read with their declared size bounded; errors name
    `label` (ARCHIVE, or "ARCHIVE: corepoints.zip" for an inner archive)."""

    def __init__(self, source, label: str):
        self.label = label
        try:
            self.zf = zipfile.ZipFile(source)
        except (OSError, EOFError, ValueError, zipfile.BadZipFile, zipfile.LargeZipFile) as e:
            problem = e.strerror if isinstance(e, OSError) and e.strerror else str(e) or type(e).__name__
            raise ArchiveError(f"{label}: not a zip archive ({printable(problem)})") from None
        self.names = set(self.zf.namelist())

    def error(self, member: str, problem: str) -> ArchiveError:
        return ArchiveError(f"{self.label}: {member}: {problem}")

    def size(self, member: str) -> int:
        return self.zf.getinfo(member).file_size

    def read(self, member: str) -> bytes:
        declared, limit = self.size(member), _member_limit()
        if declared > limit:
            raise self.error(member, f"declares {format_bytes(declared)} uncompressed, more than the "
                                     f"{format_bytes(limit)} an import may hold (a zip bomb?)")
        try:
            return self.zf.read(member)
        except (OSError, EOFError, ValueError, RuntimeError, NotImplementedError, zipfile.BadZipFile) as e:
            raise self.error(member, f"cannot be read ({printable(str(e) or type(e).__name__)})") from None

    def json(self, member: str):
        try:
            return json.loads(self.read(member).decode("utf-8"))
        except (UnicodeDecodeError, ValueError, RecursionError) as e:
            raise self.error(member, f"not valid JSON ({printable(str(e).splitlines()[0] if str(e) else e)})") \
                from None

    def array(self, name: str):
        """The array stored as NAME.npz (py4dgeo's compressed form) or NAME.npy, or None."""
        if f"{name}.npz" in self.names:
            inner = _Archive(io.BytesIO(self.read(f"{name}.npz")), f"{self.label}: {name}.npz")
            member = "arr_0.npy"
            if member not in inner.names:
                raise self.error(f"{name}.npz", f"holds no arr_0.npy (it holds {', '.join(sorted(inner.names))})")
            return inner._npy(member)
        if f"{name}.npy" in self.names:
            return self._npy(f"{name}.npy")
        return None

    def _npy(self, member: str) -> np.ndarray:
        """A .npy member whose header (dtype, shape) agrees with its size before it is read."""
        fmt = np.lib.format
        try:
            with self.zf.open(member) as f:
                version = fmt.read_magic(f)
                header = fmt.read_array_header_1_0 if version == (1, 0) else fmt.read_array_header_2_0
                shape, fortran, dtype = header(f)
                if dtype.hasobject:
                    raise self.error(member, "holds Python objects (a pickle), which are never loaded")
                expected = math.prod(shape) * dtype.itemsize
                if expected != self.size(member) - f.tell():
                    raise self.error(member, f"its header declares a {dtype} array of shape {shape} "
                                             f"({format_bytes(expected)}) but the member holds "
                                             f"{format_bytes(self.size(member) - f.tell())} of data")
                if expected > _member_limit():
                    raise self.error(member, f"declares {format_bytes(expected)}, more than the "
                                             f"{format_bytes(_member_limit())} an import may hold")
                data = f.read(expected)
        except M3C2Error:
            raise
        except (OSError, EOFError, ValueError, RuntimeError, TypeError, SyntaxError, zipfile.BadZipFile) as e:
            raise self.error(member, f"not a valid NumPy array ({printable(str(e) or type(e).__name__)})") from None
        if len(data) != expected:
            raise self.error(member, "truncated")
        array = np.frombuffer(data, dtype=dtype)
        return array.reshape(shape[::-1]).T if fortran else array.reshape(shape)


def _epoch_archive(archive: _Archive, member: str, *, cloud: bool):
    """(cloud or None, metadata) of a py4dgeo Epoch archive inside the analysis archive."""
    inner = _Archive(io.BytesIO(archive.read(member)), f"{archive.label}: {member}")
    metadata = inner.json("metadata.json") if "metadata.json" in inner.names else {}
    if not isinstance(metadata, dict):
        raise inner.error("metadata.json", f"expected a JSON object, got {type(metadata).__name__}")
    if not cloud:
        return None, metadata
    if "cloud.laz" in inner.names:
        xyz = _laz_points(inner, "cloud.laz")
    elif "cloud.npy" in inner.names:
        xyz = inner._npy("cloud.npy")
        if xyz.ndim != 2 or xyz.shape[1] != 3 or xyz.dtype.kind not in "fiu":
            raise inner.error("cloud.npy", f"expected an N x 3 array of coordinates, got {xyz.dtype} {xyz.shape}")
    else:
        raise inner.error("cloud.laz", "missing: no point cloud (cloud.laz or cloud.npy) in the epoch archive")
    xyz = np.asarray(xyz, dtype=np.float64)
    bad = int((~np.isfinite(xyz)).any(axis=1).sum())
    if bad:
        raise inner.error("cloud", f"{bad} of {len(xyz)} points have non-finite (NaN or infinite) coordinates")
    return xyz, metadata


def _laz_points(inner: _Archive, member: str) -> np.ndarray:
    """The x, y, z of a LAZ member, read by the package's reader (its header checks bound what a
    forged point count allocates); its errors name the member, not the temporary copy."""
    from ..io import read_cloud
    data = inner.read(member)
    with tempfile.TemporaryDirectory(prefix="m3c2-import-") as tmp:
        path = Path(tmp) / member
        path.write_bytes(data)
        try:
            return read_cloud(path).xyz
        except M3C2Error as e:
            raise inner.error(member, str(e).replace(f"{path}: ", "", 1).replace(str(path), member)) from None


def _timestamp(archive: _Archive, text):
    if not text:
        return None
    try:
        return dt.datetime.fromisoformat(str(text))
    except ValueError:
        raise archive.error("reference_epoch.zip: metadata.json",
                            f"timestamp {printable(text)!r} is not an ISO date and time") from None


def _deltas(archive: _Archive, n_epochs: int) -> list[dt.timedelta] | None:
    """timestamps.json: one {days, seconds, microseconds} per epoch (datetime.timedelta's fields)."""
    if "timestamps.json" not in archive.names:
        return None
    deltas = archive.json("timestamps.json")
    if not isinstance(deltas, list):
        raise archive.error("timestamps.json", f"expected a list of time deltas, got {type(deltas).__name__}")
    if len(deltas) != n_epochs:
        raise archive.error("timestamps.json", f"{len(deltas)} time deltas for {n_epochs} epochs of distances")
    out = []
    for k, d in enumerate(deltas):
        if not isinstance(d, dict) or not d or set(d) - {"days", "seconds", "microseconds"} or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in d.values()):
            raise archive.error("timestamps.json", f"entry {k} is not a time delta of finite days, seconds and "
                                                   f"microseconds: {printable(json.dumps(d))[:80]}")
        try:
            out.append(dt.timedelta(**d))
        except OverflowError:
            raise archive.error("timestamps.json", f"entry {k} is out of range: {printable(json.dumps(d))[:80]}") \
                from None
    return out


def _check_float(archive: _Archive, member: str, values: np.ndarray, shape, *, inf_ok=False) -> np.ndarray:
    if values.dtype.kind != "f" or values.ndim != 2 or values.shape != shape:
        raise archive.error(member, f"expected a float array of shape {shape} (core points x epochs), "
                                    f"got {values.dtype} {values.shape}")
    values = values.astype(np.float64)
    if not inf_ok and np.isinf(values).any():
        raise archive.error(member, f"{int(np.isinf(values).sum())} infinite values (only NaN marks no result)")
    return values


def _uncertainties(archive: _Archive, shape) -> dict | None:
    u = archive.array("uncertainties")
    if u is None:
        return None
    names = u.dtype.names or ()
    missing = [f for f in UNCERTAINTY_FIELDS if f not in names]
    if missing or u.shape != shape:
        raise archive.error("uncertainties", f"expected py4dgeo's records ({', '.join(UNCERTAINTY_FIELDS)}) of shape "
                                             f"{shape}, got fields ({', '.join(names)}) of shape {u.shape}")
    out = {}
    for name in UNCERTAINTY_FIELDS:
        column = u[name]
        if column.dtype.kind not in "fiu" or column.dtype.shape:
            raise archive.error("uncertainties", f"field {name} is {column.dtype}, not a number")
        column = column.astype(np.float64)
        if np.isinf(column).any() or (name.startswith(("num_", "spread")) and (column < 0).any()):
            raise archive.error("uncertainties", f"field {name} holds infinite or negative values")
        out[name] = column
    return out


def read_archive(path: Path) -> dict:
    """Everything an import needs from the archive, checked (ArchiveError otherwise)."""
    if not path.exists():
        raise ArchiveError(f"{path}: no such file")
    if not path.is_file():  # a folder, or a FIFO that would block the open
        raise ArchiveError(f"{path}: not a regular file")
    archive = _Archive(path, str(path))
    with archive.zf:
        if "SEGMENTATION_FILE_FORMAT" not in archive.names:
            raise ArchiveError(f"{path}: no SEGMENTATION_FILE_FORMAT: not a py4dgeo analysis archive")
        version = archive.read("SEGMENTATION_FILE_FORMAT").decode("utf-8", "replace").strip()
        if version not in KNOWN_FORMATS:
            raise archive.error("SEGMENTATION_FILE_FORMAT", f"format version {printable(version)[:40]!r} is not one "
                                                            f"this m3c2kit reads ({', '.join(KNOWN_FORMATS)})")
        for member in ("corepoints.zip",):
            if member not in archive.names:
                raise ArchiveError(f"{path}: no {member}: not a py4dgeo analysis archive, or an empty one")
        distances = archive.array("distances")
        if distances is None:
            raise ArchiveError(f"{path}: no distances (distances.npz or .npy): no epoch to import")
        if distances.ndim != 2:
            raise archive.error("distances", f"expected a 2-D array (core points x epochs), got shape "
                                             f"{distances.shape}")
        shape = distances.shape
        distances = _check_float(archive, "distances", distances, shape)
        core, _ = _epoch_archive(archive, "corepoints.zip", cloud=True)
        if len(core) != shape[0]:
            raise archive.error("corepoints.zip", f"{len(core)} core points but distances for {shape[0]}")
        ref_time = None
        if "reference_epoch.zip" in archive.names:
            _, ref_meta = _epoch_archive(archive, "reference_epoch.zip", cloud=False)
            ref_time = _timestamp(archive, ref_meta.get("timestamp"))
        deltas = _deltas(archive, shape[1])
        uncertainties = _uncertainties(archive, shape)
        smoothed = archive.array("smoothed_distances")
        if smoothed is not None:
            smoothed = _check_float(archive, "smoothed_distances", smoothed, shape)
    times = None
    if ref_time is not None and deltas is not None:
        try:
            times = [np.datetime64(ref_time.replace(tzinfo=None) + d, "us") for d in deltas]
        except OverflowError:
            raise archive.error("timestamps.json", "a time delta takes the epoch outside the years 1-9999") from None
    return {"version": version, "core": core, "distances": distances, "uncertainties": uncertainties,
            "smoothed": smoothed, "ref_time": ref_time, "times": times}


def _epoch_columns(data: dict, k: int) -> dict:
    d = data["distances"][:, k]
    u = {name: values[:, k] for name, values in data["uncertainties"].items()} if data["uncertainties"] else None
    missing = np.full(len(d), np.nan)
    lod = u["lodetection"] if u else missing
    n1 = u["num_samples1"] if u else missing
    n2 = u["num_samples2"] if u else missing
    status = np.where(np.isfinite(d), np.where(np.isfinite(lod), 0, 5), np.where(n1 == 0, 3, np.where(n2 == 0, 4, 1)))
    significant = np.where(np.isnan(lod), np.nan, (np.abs(d) > lod).astype(float))
    return {"distance": d, "lod": lod, "significant": significant, "n1": n1, "n2": n2,
            "sigma1": u["spread1"] if u else missing, "sigma2": u["spread2"] if u else missing,
            "status": status.astype(np.uint8)}


def _content_digest(columns: dict) -> str:
    """The epoch's content hash: SHA-256 of its imported columns (it has no file of its own)."""
    digest = hashlib.sha256()
    for name in st.EPOCH_COLUMNS:
        digest.update(np.ascontiguousarray(columns[name]).tobytes())
    return digest.hexdigest()


def import_archive(archive: Path, output: Path) -> int:
    """Writes the store `output` from a py4dgeo analysis archive; returns the epochs imported."""
    st.require_extra()
    archive, output = Path(archive), Path(output)
    data = read_archive(archive)  # every check before anything is created
    held = None
    try:
        with staged_directory(output) as folder:
            _write_store(Path(folder), data, archive)
            # Taken as create takes it: held from inside the private folder until the store is
            # published, so no writer can start on it before the import has finished. Where the
            # lock cannot move with the folder (series/lock.py), none: the store appears whole.
            if lock_mod.moves_with_folder():
                held = lock_mod.acquire(Path(folder), "import", output)
    finally:
        if held is not None:
            held.release()
    return data["distances"].shape[1]


def _write_store(folder: Path, data: dict, archive: Path) -> None:
    core = data["core"]
    n_core, n_epochs = data["distances"].shape
    nan = np.full((n_core, 3), np.nan)
    normals = {"normal": nan, "normal_scale": nan[:, 0], "roughness": nan[:, 0]}
    ref_time = data["ref_time"]
    attrs = {"format": st.FORMAT, "format_version": st.FORMAT_VERSION, "Conventions": "CF-1.8",
             "title": "M3C2 time series imported from py4dgeo", "parameters": st.canonical({}),
             "imported_from": f"py4dgeo analysis archive {archive.resolve()} (segmentation format {data['version']})",
             "reference": "", "reference_sha256": "", "reference_time": "" if ref_time is None else ref_time.isoformat(),
             "core_points": "py4dgeo corepoints.zip (LAZ-quantised by py4dgeo)",
             "history": f"{dt.datetime.now(dt.timezone.utc).isoformat(timespec='seconds')} m3c2 series import"}
    st.create(folder, core, normals, attrs, core_chunk=16384, epoch_chunk=8)
    chunk = st.epoch_chunk(folder)
    # Nobody sees the store before it is published, so commits are only for memory: whole epoch
    # chunks, as many as a series' batch may hold (one commit per epoch: 1,431 epochs in 90 s).
    from .batch import Batch
    epoch_bytes = n_core * 8 * len(st.EPOCH_COLUMNS)  # at most 8 bytes per value
    per_commit = max(1, Batch.MAX_BYTES // max(1, epoch_bytes * chunk)) * chunk
    for begin in range(0, n_epochs, per_commit):
        batch = []
        for k in range(begin, min(n_epochs, begin + per_commit)):
            columns = _epoch_columns(data, k)
            info = {"time": data["times"][k] if data["times"] else None, "source": f"{archive.name}#epoch{k}",
                    "source_size": 0, "source_mtime_ns": 0, "time_source": "py4dgeo", "points": -1,
                    "source_sha256": _content_digest(columns)}
            batch.append((columns, info))
        st.append_batch(folder, begin, batch)
    if data["smoothed"] is not None:
        _import_smoothed(folder, data["smoothed"], n_epochs)


def _import_smoothed(store: Path, smoothed: np.ndarray, n_epochs: int) -> None:
    from .analysis import SMOOTHED
    from .view import new_variable
    _, array = new_variable(store, SMOOTHED, np.float64, np.nan,
                            {"long_name": "py4dgeo's smoothed_distances", "epochs": int(n_epochs)})
    array[:, :] = smoothed
    st.commit(store)
