"""Import of a py4dgeo SpatiotemporalAnalysis archive (its zip format, segmentation file format
version as written by py4dgeo 0.x-1.x): core points (corepoints.zip, an Epoch archive holding
cloud.laz), the reference's timestamp (reference_epoch.zip, metadata.json), timestamps.json
(time deltas from the reference), distances and uncertainties (.npz when compressed, .npy
otherwise) and, when present, smoothed_distances. py4dgeo keeps no M3C2 parameters, normals or
reasons: the store says so (attribute `imported_from`), `add` refuses it, and `status` is
derived from the counts (3: n1 = 0, 4: n2 = 0, 5: no LOD, 0: computed)."""
from __future__ import annotations

import datetime as dt
import io
import json
import tempfile
import zipfile
from pathlib import Path

import numpy as np

from ..errors import CloudReadError, UsageError
from . import store as st


def _read_array(zf: zipfile.ZipFile, name: str):
    for candidate, loader in ((f"{name}.npz", lambda b: np.load(b)["arr_0"]), (f"{name}.npy", np.load)):
        if candidate in zf.namelist():
            return loader(io.BytesIO(zf.read(candidate)))
    return None


def _epoch_archive(zf: zipfile.ZipFile, name: str, archive: Path):
    if name not in zf.namelist():
        raise CloudReadError(f"{archive}: no {name}: not a py4dgeo analysis archive, or an empty one")
    inner = zipfile.ZipFile(io.BytesIO(zf.read(name)))
    metadata = json.loads(inner.read("metadata.json")) if "metadata.json" in inner.namelist() else {}
    cloud = None
    if "cloud.laz" in inner.namelist():
        import laspy
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "cloud.laz"
            path.write_bytes(inner.read("cloud.laz"))
            las = laspy.read(path)
            cloud = np.column_stack([las.x, las.y, las.z]).astype(np.float64)
    elif "cloud.npy" in inner.namelist():
        cloud = np.load(io.BytesIO(inner.read("cloud.npy")))
    return cloud, metadata


def _timestamp(text):
    if not text:
        return None
    try:
        return dt.datetime.fromisoformat(str(text))
    except ValueError:
        return None


def import_archive(archive: Path, output: Path) -> int:
    st.require_extra()
    archive, output = Path(archive), Path(output)
    if output.exists():
        raise UsageError(f"{output} exists; choose another -o")
    try:
        zf = zipfile.ZipFile(archive)
    except (OSError, zipfile.BadZipFile) as e:
        raise CloudReadError(f"{archive}: not a zip archive ({e})") from None
    with zf:
        if "SEGMENTATION_FILE_FORMAT" not in zf.namelist():
            raise CloudReadError(f"{archive}: no SEGMENTATION_FILE_FORMAT: not a py4dgeo analysis archive")
        version = zf.read("SEGMENTATION_FILE_FORMAT").decode().strip()
        core, _ = _epoch_archive(zf, "corepoints.zip", archive)
        ref_time = None
        if "reference_epoch.zip" in zf.namelist():
            _, ref_meta = _epoch_archive(zf, "reference_epoch.zip", archive)
            ref_time = _timestamp(ref_meta.get("timestamp"))
        deltas = json.loads(zf.read("timestamps.json")) if "timestamps.json" in zf.namelist() else []
        distances = _read_array(zf, "distances")
        uncertainties = _read_array(zf, "uncertainties")
        smoothed = _read_array(zf, "smoothed_distances")
    if distances is None or core is None:
        raise CloudReadError(f"{archive}: no distances or core points to import")
    n_core, n_epochs = distances.shape
    if len(core) != n_core:
        raise CloudReadError(f"{archive}: {len(core)} core points but distances for {n_core}")
    nan = np.full((n_core, 3), np.nan)
    normals = {"normal": nan, "normal_scale": nan[:, 0], "roughness": nan[:, 0]}
    attrs = {"format": st.FORMAT, "format_version": st.FORMAT_VERSION, "Conventions": "CF-1.8",
             "title": "M3C2 time series imported from py4dgeo", "parameters": st.canonical({}),
             "imported_from": f"py4dgeo analysis archive {archive.resolve()} (segmentation format {version})",
             "reference": "", "reference_sha256": "", "reference_time": "" if ref_time is None else ref_time.isoformat(),
             "core_points": "py4dgeo corepoints.zip (LAZ-quantised by py4dgeo)",
             "history": f"{dt.datetime.now(dt.timezone.utc).isoformat(timespec='seconds')} m3c2 series import"}
    st.create(output, core, normals, attrs, core_chunk=16384, epoch_chunk=8)
    for k in range(n_epochs):
        d = distances[:, k].astype(np.float64)
        u = uncertainties[:, k] if uncertainties is not None else None
        lod = u["lodetection"].astype(np.float64) if u is not None else np.full(n_core, np.nan)
        n1 = u["num_samples1"].astype(np.float64) if u is not None else np.full(n_core, np.nan)
        n2 = u["num_samples2"].astype(np.float64) if u is not None else np.full(n_core, np.nan)
        status = np.where(np.isfinite(d), np.where(np.isfinite(lod), 0, 5), np.where(n1 == 0, 3, np.where(n2 == 0, 4, 1)))
        significant = np.where(np.isnan(lod), np.nan, (np.abs(d) > lod).astype(float))
        columns = {"distance": d, "lod": lod, "significant": significant, "n1": n1, "n2": n2,
                   "sigma1": u["spread1"].astype(np.float64) if u is not None else np.full(n_core, np.nan),
                   "sigma2": u["spread2"].astype(np.float64) if u is not None else np.full(n_core, np.nan),
                   "status": status.astype(np.uint8)}
        time = None
        if ref_time is not None and k < len(deltas):
            time = np.datetime64(ref_time.replace(tzinfo=None) + dt.timedelta(**deltas[k]), "us")
        st.append(output, k, columns, {"time": time, "source": f"{archive.name}#epoch{k}", "source_size": 0,
                                       "source_mtime_ns": 0, "time_source": "py4dgeo", "points": -1})
    if smoothed is not None and smoothed.shape == distances.shape:
        from .analysis import SMOOTHED, _new_variable
        _, zarr = st.require_extra()
        _, array = _new_variable(output, SMOOTHED, np.float64, np.nan,
                                 {"long_name": "py4dgeo's smoothed_distances", "epochs": int(n_epochs)})
        array[:, :] = smoothed.astype(np.float64)
        zarr.consolidate_metadata(str(output))
    return n_epochs
