"""Inputs of the per-point uncertainty models (``uncertainty`` = ``pm`` or ``ep``) and the one
call into the engine that takes them (docs/algorithm.md §6.5).

M3C2-PM (James et al. 2017) reads three precision fields per cloud (``--precision-fields``,
default ``sx,sy,sz``: LAS extra bytes, PLY properties or ASCII columns, through the readers'
``fields``). M3C2-EP (Winiwarter et al. 2021) reads a scan-position id per point
(``--scan-position-field``, default ``point_source_id``), a scan-position table
(``--scan-positions``: py4dgeo's ``sps.json`` or a CSV), the compared epoch's 3x4 transformation
(``--transform``), its 12x12 alignment covariance (``--alignment-covariance``) and the reduction
point (``--reduction-point``).

:func:`inputs_for` turns a run's resolved settings and the clouds' fields into the engine's
keyword arrays (m3c2kit.api.compare passes them to m3c2kit.engine.compute); :func:`compute` is
the same engine call for arrays already at hand (tests, validation/). The engine call goes
through the facade (m3c2kit.engine), which translates its errors.
"""
from __future__ import annotations

import csv
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import engine
from .errors import UsageError

__all__ = ["UNCERTAINTIES", "EpInputs", "Carried", "carried", "shared_inputs", "moved_compared", "unmoved_compared", "precision_array", "scan_position_ids", "load_scan_positions",
           "load_matrix", "parse_reduction_point", "inputs_for", "compute"]

UNCERTAINTIES = ("eq1", "pm", "ep")
_TABLE_KEYS = ("sigma_range", "sigma_scan", "sigma_yaw")


def precision_array(fields: dict, names: str | tuple = "sx,sy,sz", *, what: str = "cloud") -> np.ndarray:
    """(N, 3) float64 precisions sx, sy, sz from a cloud's ``fields`` (``names``: 'SX,SY,SZ')."""
    wanted = [n.strip() for n in names.split(",")] if isinstance(names, str) else list(names)
    if len(wanted) != 3 or not all(wanted):
        raise UsageError(f"--precision-fields needs three field names SX,SY,SZ, got {names!r}")
    missing = [n for n in wanted if n not in fields]
    if missing:
        raise UsageError(f"{what}: no precision field {', '.join(missing)} (its fields: {', '.join(fields) or 'none'})")
    return np.ascontiguousarray(np.column_stack([np.asarray(fields[n], dtype=np.float64) for n in wanted]))


def scan_position_ids(fields: dict, name: str = "point_source_id", *, what: str = "cloud") -> np.ndarray:
    """(N,) uint32 scan-position ids from a cloud's field ``name`` (integers >= 0)."""
    if name not in fields:
        raise UsageError(f"{what}: no scan-position field {name!r} (its fields: {', '.join(fields) or 'none'})")
    values = np.asarray(fields[name])
    as_float = values.astype(np.float64)
    if values.size and (not np.all(np.isfinite(as_float)) or np.any(as_float < 0) or np.any(as_float != np.round(as_float))
                        or np.any(as_float > 2**24)):
        raise UsageError(f"{what}: scan-position field {name!r} must hold integers in [0, 2^24]")
    return np.ascontiguousarray(values.astype(np.uint32))


def _row(sid, entry: dict, source: str, poses=None) -> list[float]:
    if "origin" not in entry and poses is not None and 1 <= int(sid) <= len(poses):
        entry = {**entry, "origin": list(poses[int(sid) - 1])}  # the E57 scan's pose
    for key in ("origin", *_TABLE_KEYS):
        if key not in entry:
            raise UsageError(f"{source}: scan position {sid} has no {key!r}")
    origin = entry["origin"]
    if len(origin) != 3:
        raise UsageError(f"{source}: scan position {sid}: origin must have 3 coordinates")
    try:
        return [float(int(sid)), *map(float, origin), float(entry["sigma_range"]),
                float(entry.get("sigma_range_ppm", 0.0)), float(entry["sigma_scan"]), float(entry["sigma_yaw"])]
    except (TypeError, ValueError) as e:
        raise UsageError(f"{source}: scan position {sid}: {e}") from None


def load_scan_positions(path, poses=None) -> np.ndarray:
    """The scan-position table (K, 8): id, origin x, y, z, sigma_range, sigma_range_ppm, sigma_scan,
    sigma_yaw. JSON as py4dgeo's sps.json ``{"1": {"origin": [x, y, z], "sigma_range": ..,
    "sigma_scan": .., "sigma_yaw": ..}, ...}`` (optional "sigma_range_ppm"), or CSV with a header
    ``id,x,y,z,sigma_range,sigma_scan,sigma_yaw[,sigma_range_ppm]``. Angles in radians.

    ``poses`` (an E57 cloud's ``scan_positions``, one row per scan): an entry without an origin
    (JSON: no "origin"; CSV: x, y, z empty) takes the pose of scan `id` (E57 scans counted from 1,
    as the reader's ``scan_index`` field), so that the file only gives the sigmas."""
    source = str(path)
    try:
        text = Path(path).read_text()
    except OSError as e:
        raise UsageError(f"--scan-positions {source}: {e.strerror or e}") from None
    rows = []
    if text.lstrip().startswith("{"):
        try:
            table = json.loads(text)
        except json.JSONDecodeError as e:
            raise UsageError(f"--scan-positions {source}: not valid JSON ({e})") from None
        for sid, entry in table.items():
            if not str(sid).isdigit() or not isinstance(entry, dict):
                raise UsageError(f"--scan-positions {source}: keys must be integer ids and values objects, got {sid!r}")
            rows.append(_row(sid, entry, source, poses))
    else:
        reader = csv.DictReader(text.splitlines())
        need = {"id", "x", "y", "z", *_TABLE_KEYS}
        if reader.fieldnames is None or not need <= {f.strip() for f in reader.fieldnames}:
            raise UsageError(f"--scan-positions {source}: a CSV needs the header "
                             "id,x,y,z,sigma_range,sigma_scan,sigma_yaw[,sigma_range_ppm]")
        for rec in reader:
            rec = {k.strip(): v for k, v in rec.items()}
            if not str(rec["id"]).strip().isdigit():
                raise UsageError(f"--scan-positions {source}: ids must be integers, got {rec['id']!r}")
            entry = {**{k: rec[k] for k in _TABLE_KEYS}, "sigma_range_ppm": rec.get("sigma_range_ppm") or 0.0}
            if any(str(rec[c] or "").strip() for c in "xyz") or poses is None:
                entry["origin"] = [rec["x"], rec["y"], rec["z"]]
            rows.append(_row(rec["id"].strip(), entry, source, poses))
    if not rows:
        raise UsageError(f"--scan-positions {source}: no scan position")
    return np.ascontiguousarray(np.array(rows, dtype=np.float64).reshape(-1, 8))


def load_matrix(path, shape: tuple[int, int], option: str) -> np.ndarray:
    """A matrix of `shape` from a CSV / whitespace-separated text file (``--transform``: 3x4,
    ``--alignment-covariance``: 12x12)."""
    try:
        text = Path(path).read_text()
    except OSError as e:
        raise UsageError(f"{option} {path}: {e.strerror or e}") from None
    try:
        rows = [[float(v) for v in line.replace(",", " ").split()] for line in text.splitlines() if line.strip()]
        m = np.array(rows, dtype=np.float64)
    except ValueError as e:
        raise UsageError(f"{option} {path}: not a numeric matrix ({e})") from None
    if m.shape != shape:
        raise UsageError(f"{option} {path}: expected a {shape[0]}x{shape[1]} matrix, got "
                         f"{'x'.join(map(str, m.shape)) if m.ndim == 2 else 'ragged rows'}")
    if not np.all(np.isfinite(m)):
        raise UsageError(f"{option} {path}: non-finite value")
    return np.ascontiguousarray(m)


def parse_reduction_point(value) -> np.ndarray:
    """``--reduction-point X,Y,Z`` (or a file holding three numbers, as redPoint.csv)."""
    if isinstance(value, (list, tuple, np.ndarray)):
        parts = list(value)
    else:
        text = str(value)
        if Path(text).is_file():
            text = Path(text).read_text()
        parts = text.replace(",", " ").split()
    try:
        point = np.array([float(v) for v in parts], dtype=np.float64)
    except ValueError:
        raise UsageError(f"--reduction-point must be X,Y,Z (three numbers), got {value!r}") from None
    if point.shape != (3,) or not np.all(np.isfinite(point)):
        raise UsageError(f"--reduction-point must be X,Y,Z (three finite numbers), got {value!r}")
    return point


@dataclass
class EpInputs:
    """M3C2-EP's inputs beyond the clouds (tables as load_scan_positions returns them)."""
    scan_positions1: np.ndarray
    scan_positions2: np.ndarray
    scan_position1: np.ndarray  # uint32 id per reference point
    scan_position2: np.ndarray  # uint32 id per compared point
    transform: np.ndarray = field(default_factory=lambda: np.eye(3, 4))
    alignment_covariance: np.ndarray | None = None
    reduction_point: np.ndarray = field(default_factory=lambda: np.zeros(3))
    transform_applied: bool = False


def _fields(cloud, what: str, option: str) -> dict:
    fields = getattr(cloud, "fields", None)
    if fields is None:
        raise UsageError(f"{option} reads per-point fields of the {what} cloud: give it as a file or an "
                         "m3c2kit.io.Cloud (read_cloud), not a bare array")
    return fields


def _table_or_file(value, poses, option: str) -> np.ndarray:
    if isinstance(value, np.ndarray):
        table = np.ascontiguousarray(value, dtype=np.float64)
        if table.ndim != 2 or table.shape[1] != 8:
            raise UsageError(f"{option}: an array table must be (K, 8): id, x, y, z, sigma_range, "
                             "sigma_range_ppm, sigma_scan, sigma_yaw")
        return table
    return load_scan_positions(value, poses)


def _matrix(value, shape, option: str) -> np.ndarray:
    if isinstance(value, (np.ndarray, list, tuple)):
        m = np.asarray(value, dtype=np.float64)
        if m.shape != shape:
            raise UsageError(f"{option}: expected a {shape[0]}x{shape[1]} matrix, got shape {m.shape}")
        return np.ascontiguousarray(m)
    return load_matrix(value, shape, option)


@dataclass(frozen=True)
class Carried:
    """A per-point engine input a cloud carries (and that a tiled run partitions with its points):
    the engine keyword (``precision1``, ``scan_position2``, ...), the cloud's field names it is
    read from, and its kind (``precision``: (N, 3) float64; ``scan_position``: (N,) uint32)."""
    keyword: str
    names: tuple
    kind: str
    option: str

    @property
    def column(self) -> tuple:
        """The column of a structured spill record: (keyword, dtype[, shape])."""
        return (self.keyword, np.float64, (3,)) if self.kind == "precision" else (self.keyword, np.uint32)

    def values(self, fields: dict, what: str) -> np.ndarray:
        """This input from a cloud's (or a chunk's) fields; the checks and conversion of the
        in-memory run, elementwise, so that a chunk gives the same bits as the whole cloud."""
        if self.kind == "precision":
            return precision_array(fields, self.names, what=what)
        return scan_position_ids(fields, self.names[0], what=what)

    def filler(self, table: np.ndarray | None) -> np.ndarray:
        """The value of a stand-in point (a tile's empty cloud): zero precision, a known id."""
        if self.kind == "precision":
            return np.zeros((1, 3))
        return np.asarray([int(table[0, 0])], dtype=np.uint32)


def carried(values: dict) -> dict:
    """The per-point inputs of each cloud ({"reference": [Carried, ...], "compared": [...]})
    for a run with these resolved settings."""
    kind = values.get("uncertainty", "eq1")
    if kind == "pm":
        names = values.get("precision_fields") or "sx,sy,sz"
        wanted = tuple(n.strip() for n in names.split(",")) if isinstance(names, str) else tuple(names)
        if len(wanted) != 3 or not all(wanted):
            raise UsageError(f"--precision-fields needs three field names SX,SY,SZ, got {names!r}")
        return {name: [Carried(f"precision{k}", wanted, "precision", "--uncertainty pm")]
                for k, name in ((1, "reference"), (2, "compared"))}
    if kind == "ep":
        field_name = values.get("scan_position_field") or "point_source_id"
        return {name: [Carried(f"scan_position{k}", (field_name,), "scan_position", "--scan-position-field")]
                for k, name in ((1, "reference"), (2, "compared"))}
    return {"reference": [], "compared": []}


def shared_inputs(values: dict, reference, compared) -> dict:
    """The engine's uncertainty keywords that are the same for every point (EP's scan-position
    tables, transformation, alignment covariance, reduction point); `reference` and `compared`
    give the E57 poses (their ``scan_positions``) when they have them."""
    if values.get("uncertainty", "eq1") != "ep":
        return {}
    spec = values.get("scan_positions")
    if spec is None:
        raise UsageError("--uncertainty ep needs --scan-positions FILE (py4dgeo's sps.json or a CSV)")
    files = spec.split(",") if isinstance(spec, str) else [spec]
    if len(files) > 2:
        raise UsageError(f"--scan-positions takes FILE or FILE1,FILE2 (reference, compared), got {spec!r}")
    table1 = _table_or_file(files[0], getattr(reference, "scan_positions", None), "--scan-positions")
    table2 = _table_or_file(files[-1], getattr(compared, "scan_positions", None), "--scan-positions")
    transform = values.get("transform")
    if transform is None and values.get("transform_applied"):
        raise UsageError("--transform-applied needs --transform FILE (the transformation that was applied)")
    kw = dict(scan_positions1=table1, scan_positions2=table2,
              transform=np.eye(3, 4) if transform is None else _matrix(transform, (3, 4), "--transform"),
              reduction_point=np.zeros(3) if values.get("reduction_point") is None
              else parse_reduction_point(values["reduction_point"]),
              transform_applied=bool(values.get("transform_applied", False)))
    if values.get("alignment_covariance") is not None:
        kw["alignment_covariance"] = _matrix(values["alignment_covariance"], (12, 12), "--alignment-covariance")
    return kw


def moved_compared(shared: dict, xyz: np.ndarray) -> np.ndarray:
    """Where the engine sees compared points (EP with a transformation not yet applied:
    p' = red + R (p - red) + t, src/uncertainty.cpp), for choosing a tile's points; the engine
    moves them itself, so the last bits here need not be its own (a tile's box has a margin)."""
    if "transform" not in shared or shared.get("transform_applied"):
        return xyz
    t, red = shared["transform"], shared["reduction_point"]
    return (xyz - red) @ t[:, :3].T + t[:, 3] + red


def unmoved_compared(shared: dict, xyz: np.ndarray) -> np.ndarray:
    """The inverse of moved_compared: a compared point the engine will see at `xyz`."""
    if "transform" not in shared or shared.get("transform_applied"):
        return xyz
    t, red = shared["transform"], shared["reduction_point"]
    return (xyz - red - t[:, 3]) @ np.linalg.inv(t[:, :3]).T + red


def inputs_for(values: dict, reference, compared) -> dict:
    """The engine's uncertainty keyword arrays for a run with these resolved settings
    (m3c2kit.settings.resolve) on these clouds (m3c2kit.io.Cloud: their fields and E57 poses)."""
    per_point = carried(values)
    kw = {}
    for name, cloud in (("reference", reference), ("compared", compared)):
        for c in per_point[name]:
            kw[c.keyword] = c.values(_fields(cloud, name, c.option), f"{name} cloud")
    kw.update(shared_inputs(values, reference, compared))
    return kw


def compute(reference, compared, core_points, params, *, core_normals=None, threads=0, progress=None,
            precision1=None, precision2=None, ep: EpInputs | None = None, covariances=False) -> dict:
    """The engine's compute() with the per-point uncertainty inputs of ``params.uncertainty``."""
    kw = {}
    if precision1 is not None:
        kw.update(precision1=np.ascontiguousarray(precision1, dtype=np.float64),
                  precision2=np.ascontiguousarray(precision2, dtype=np.float64))
    if ep is not None:
        kw.update(scan_positions1=np.ascontiguousarray(ep.scan_positions1, dtype=np.float64),
                  scan_positions2=np.ascontiguousarray(ep.scan_positions2, dtype=np.float64),
                  scan_position1=np.ascontiguousarray(ep.scan_position1, dtype=np.uint32),
                  scan_position2=np.ascontiguousarray(ep.scan_position2, dtype=np.uint32),
                  transform=np.ascontiguousarray(ep.transform, dtype=np.float64),
                  reduction_point=np.ascontiguousarray(ep.reduction_point, dtype=np.float64),
                  transform_applied=bool(ep.transform_applied))
        if ep.alignment_covariance is not None:
            kw["alignment_covariance"] = np.ascontiguousarray(ep.alignment_covariance, dtype=np.float64)
    return engine.compute(np.ascontiguousarray(reference, dtype=np.float64),
                          np.ascontiguousarray(compared, dtype=np.float64),
                          np.ascontiguousarray(core_points, dtype=np.float64), params,
                          None if core_normals is None else np.ascontiguousarray(core_normals, dtype=np.float64),
                          threads=threads, progress=progress, covariances=covariances, **kw)
