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
import os
from dataclasses import dataclass, field

import numpy as np

from .. import engine
from . import registration_inputs
from ..base.errors import UsageError
from ..io.input_file import parse_json, read_small_text

__all__ = ["UNCERTAINTIES", "EpInputs", "Carried", "carried", "shared_inputs", "moved_compared", "unmoved_compared", "precision_array", "scan_position_ids", "load_scan_positions",
           "load_matrix", "parse_reduction_point", "inputs_for", "compute", "precision_names", "transform_matrix",
           "alignment_covariance", "ROTATION_TOLERANCE", "COVARIANCE_TOLERANCE"]

UNCERTAINTIES = ("eq1", "pm", "ep")
_TABLE_KEYS = ("sigma_range", "sigma_scan", "sigma_yaw")
# The kinds of the small files read here; their size limits: io.input_file.SMALL_FILE_LIMITS.
SCAN_POSITIONS_KIND, MATRIX_KIND, REDUCTION_POINT_KIND = "scan-position file", "matrix file", "reduction-point file"


def precision_names(names: str | tuple) -> tuple:
    """``--precision-fields`` 'SX,SY,SZ' as three distinct field names (one field read as two
    axes' precisions would make up an isotropic precision the file does not hold)."""
    wanted = tuple(n.strip() for n in names.split(",")) if isinstance(names, str) else tuple(names)
    if len(wanted) != 3 or not all(wanted):
        raise UsageError(f"--precision-fields needs three field names SX,SY,SZ, got {names!r}")
    if len(set(wanted)) != 3:
        raise UsageError(f"--precision-fields needs three distinct field names SX,SY,SZ (one per axis), got "
                         f"{','.join(wanted)!r}")
    return wanted


def precision_array(fields: dict, names: str | tuple = "sx,sy,sz", *, what: str = "cloud") -> np.ndarray:
    """(N, 3) float64 precisions sx, sy, sz from a cloud's ``fields`` (``names``: 'SX,SY,SZ')."""
    wanted = precision_names(names)
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
    if not str(sid).isascii() or not str(sid).isdigit() or len(str(sid)) > 8:  # '²' is a digit int() refuses
        raise UsageError(f"{source}: ids must be integers in [0, 2^24], got {str(sid)[:20]!r}")
    if "origin" not in entry and poses is not None and 1 <= int(sid) <= len(poses):
        entry = {**entry, "origin": list(poses[int(sid) - 1])}  # the E57 scan's pose
    for key in ("origin", *_TABLE_KEYS):
        if key not in entry:
            raise UsageError(f"{source}: scan position {sid} has no {key!r}")
    origin = entry["origin"]
    if not isinstance(origin, (list, tuple)) or len(origin) != 3:
        raise UsageError(f"{source}: scan position {sid}: origin must have 3 coordinates")
    try:
        row = [float(int(sid)), *map(float, origin), float(entry["sigma_range"]),
               float(entry.get("sigma_range_ppm", 0.0)), float(entry["sigma_scan"]), float(entry["sigma_yaw"])]
    except (TypeError, ValueError, OverflowError) as e:
        raise UsageError(f"{source}: scan position {sid}: {e}") from None
    return _checked_row(row, f"{source}: scan position {sid}")


#: The scan-position table's columns after the id (load_scan_positions), as its messages name them.
_ROW_COLUMNS = ("origin x", "origin y", "origin z", "sigma_range", "sigma_range_ppm", "sigma_scan", "sigma_yaw")


def _checked_row(row: list, what: str) -> list:
    """A table row whose origin is finite and whose standard deviations are finite and >= 0 (the
    engine then asks the sigmas it needs to be > 0)."""
    for name, value in zip(_ROW_COLUMNS, row[1:]):
        if not np.isfinite(value):
            raise UsageError(f"{what}: {name} must be finite, got {value!r}")
        if name.startswith("sigma") and value < 0:
            raise UsageError(f"{what}: {name} is a standard deviation and must be >= 0, got {value!r}")
    if not (0 <= row[0] <= 2**24 and float(row[0]).is_integer()):
        raise UsageError(f"{what}: ids must be integers in [0, 2^24]")
    return row


def _unique_ids(table: np.ndarray, source: str) -> np.ndarray:
    # Two rows for one id: which scanner a point was measured from would be a guess.
    ids, counts = np.unique(table[:, 0], return_counts=True)
    if np.any(counts > 1):
        raise UsageError(f"{source}: scan position {int(ids[counts > 1][0])} is listed more than once")
    return table


def load_scan_positions(path, poses=None) -> np.ndarray:
    """The scan-position table (K, 8): id, origin x, y, z, sigma_range, sigma_range_ppm, sigma_scan,
    sigma_yaw. JSON as py4dgeo's sps.json ``{"1": {"origin": [x, y, z], "sigma_range": ..,
    "sigma_scan": .., "sigma_yaw": ..}, ...}`` (optional "sigma_range_ppm"), or CSV with a header
    ``id,x,y,z,sigma_range,sigma_scan,sigma_yaw[,sigma_range_ppm]``. Angles in radians.

    ``poses`` (an E57 cloud's ``scan_positions``, one row per scan): an entry without an origin
    (JSON: no "origin"; CSV: x, y, z empty) takes the pose of scan `id` (E57 scans counted from 1,
    as the reader's ``scan_index`` field), so that the file only gives the sigmas."""
    source = str(path)
    label = f"--scan-positions {source}"
    text = read_small_text(path, SCAN_POSITIONS_KIND, label=label, encoding="utf-8-sig")
    rows = []
    if text.lstrip().startswith("{"):
        table = parse_json(text, SCAN_POSITIONS_KIND, label=label)
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
        for number, rec in enumerate(reader, 2):
            if None in rec or None in rec.values():  # csv's marks of a row longer or shorter than the header
                raise UsageError(f"--scan-positions {source}: line {number} has {'more' if None in rec else 'fewer'} "
                                 f"values than the header")
            rec = {k.strip(): v for k, v in rec.items()}
            if not str(rec["id"]).strip().isdigit():
                raise UsageError(f"--scan-positions {source}: ids must be integers, got {rec['id']!r}")
            entry = {**{k: rec[k] for k in _TABLE_KEYS}, "sigma_range_ppm": rec.get("sigma_range_ppm") or 0.0}
            if any(str(rec[c] or "").strip() for c in "xyz") or poses is None:
                entry["origin"] = [rec["x"], rec["y"], rec["z"]]
            rows.append(_row(rec["id"].strip(), entry, source, poses))
    if not rows:
        raise UsageError(f"--scan-positions {source}: no scan position")
    return _unique_ids(np.ascontiguousarray(np.array(rows, dtype=np.float64).reshape(-1, 8)), source)


def load_matrix(path, shape: tuple[int, int], option: str, also: tuple[int, int] | None = None) -> np.ndarray:
    """A matrix of `shape` (or `also`) from a CSV / whitespace-separated text file (``--transform``:
    3x4 or 4x4, ``--alignment-covariance``: 12x12)."""
    text = read_small_text(path, MATRIX_KIND, label=f"{option} {path}")
    try:
        rows = [[float(v) for v in line.replace(",", " ").split()] for line in text.splitlines() if line.strip()]
        m = np.array(rows, dtype=np.float64)
    except ValueError as e:
        raise UsageError(f"{option} {path}: not a numeric matrix ({e})") from None
    if m.shape != shape and m.shape != also:
        raise UsageError(f"{option} {path}: expected a {_shapes(shape, also)} matrix, got "
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
        if os.path.lexists(text):  # the path of a file holding X,Y,Z (a FIFO or device is refused there)
            text = read_small_text(text, REDUCTION_POINT_KIND, label=f"--reduction-point {text}")
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
        for row in table:
            _checked_row(list(row), f"{option}: scan position {row[0]:g}")
        return _unique_ids(table, option)
    return load_scan_positions(value, poses)


def _shapes(shape, also) -> str:
    return "x".join(map(str, shape)) + ("" if also is None else " or " + "x".join(map(str, also)))


def _matrix(value, shape, option: str, also=None) -> np.ndarray:
    if isinstance(value, (np.ndarray, list, tuple)):
        try:
            m = np.asarray(value, dtype=np.float64)
        except (TypeError, ValueError) as e:
            raise UsageError(f"{option}: not a numeric matrix ({e})") from None
        if m.shape != shape and m.shape != also:
            raise UsageError(f"{option}: expected a {_shapes(shape, also)} matrix, got shape {m.shape}")
        return np.ascontiguousarray(m)
    return load_matrix(value, shape, option, also)


#: How far a transformation's 3x3 part may be from a rotation: the largest entry of |R^T R - I|.
#: A 12-parameter registration is not exactly rigid (py4dgeo's M3C2-EP example tfM: 5e-4); a
#: shear or scale beyond this is not the rigid-body motion M3C2-EP propagates.
ROTATION_TOLERANCE = 5e-3
#: How negative a covariance's eigenvalue may be, relative to its largest: the rounding of a
#: covariance written as text (rank-deficient ones, as a 12x12 Cxx of a 6-parameter motion, sit at 0).
COVARIANCE_TOLERANCE = 1e-6


def _where(option: str, value) -> str:
    """How messages name a matrix: the option and its file, or the option for an array."""
    return option if isinstance(value, (np.ndarray, list, tuple)) else f"{option} {value}"


def transform_matrix(value) -> np.ndarray:
    """``--transform``: a 3x4 [R | t], or a 4x4 whose last row is 0 0 0 1, with finite values and R a
    rotation (orthonormal within ROTATION_TOLERANCE, determinant > 0: not a reflection)."""
    where = _where("--transform", value)
    m = _matrix(value, (3, 4), "--transform", also=(4, 4))
    if m.shape == (4, 4):
        if not np.array_equal(m[3], [0.0, 0.0, 0.0, 1.0]):
            raise UsageError(f"{where}: the last row of a 4x4 transformation must be 0 0 0 1, got "
                             f"{' '.join(f'{v:g}' for v in m[3])}")
        m = m[:3]
    if not np.all(np.isfinite(m)):
        raise UsageError(f"{where}: non-finite value")
    r = m[:, :3]
    with np.errstate(over="ignore", invalid="ignore"):  # entries near 1e308: R^T R overflows, refused below
        off = float(np.max(np.abs(r.T @ r - np.eye(3))))
    if not off <= ROTATION_TOLERANCE:
        raise UsageError(f"{where}: the 3x3 part is not a rotation (R^T R differs from the identity by {off:.3g}, "
                         f"more than {ROTATION_TOLERANCE:g}: a scale or shear); M3C2-EP takes a rigid-body "
                         "transformation")
    det = float(np.linalg.det(r))
    if not det > 0:
        raise UsageError(f"{where}: the 3x3 part is a reflection (determinant {det:.6g}), not a rotation")
    return np.ascontiguousarray(m)


def alignment_covariance(value) -> np.ndarray:
    """``--alignment-covariance``: the 12x12 Cxx, finite, symmetric and positive semidefinite (no
    eigenvalue below -COVARIANCE_TOLERANCE times the largest): a variance of a combination of
    parameters is never negative, and the engine would take its square root."""
    where = _where("--alignment-covariance", value)
    c = _matrix(value, (12, 12), "--alignment-covariance")
    bad = np.argwhere(~np.isfinite(c))
    if len(bad):
        raise UsageError(f"{where}: non-finite value {c[tuple(bad[0])]} at row {bad[0][0] + 1}, column {bad[0][1] + 1}")
    asym = np.argwhere(c != c.T)
    if len(asym):
        i, j = asym[0]
        raise UsageError(f"{where}: the covariance is not symmetric: row {i + 1}, column {j + 1} is {c[i, j]:.6g} "
                         f"but row {j + 1}, column {i + 1} is {c[j, i]:.6g}")
    if np.any(np.diag(c) < 0):
        i = int(np.argmax(np.diag(c) < 0))
        raise UsageError(f"{where}: negative variance {c[i, i]:.6g} on the diagonal (row {i + 1})")
    eig = np.linalg.eigvalsh(c)
    if not np.all(np.isfinite(eig)):  # values near 1e308: the eigenvalues overflow, and NaN passed the test below
        raise UsageError(f"{where}: the covariance's values are too large: its eigenvalues overflow the float range")
    if eig[0] < -COVARIANCE_TOLERANCE * max(eig[-1], 0.0):
        raise UsageError(f"{where}: the covariance is not positive semidefinite: eigenvalue {eig[0]:.6g} (the "
                         f"largest is {eig[-1]:.6g}; at most {COVARIANCE_TOLERANCE:g} of it below 0 is rounding)")
    return c


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
        wanted = precision_names(values.get("precision_fields") or "sx,sy,sz")
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
    transform = values.get("transform")  # --transform-applied without it: m3c2kit.settings.needs
    red = np.zeros(3) if values.get("reduction_point") is None else parse_reduction_point(values["reduction_point"])
    # m3c2 register's T.json: its motion and covariance at EP's reduction point (run/registration_inputs.py)
    registered = registration_inputs.registration_of(transform, "--transform")
    kw = dict(scan_positions1=table1, scan_positions2=table2,
              transform=np.eye(3, 4) if transform is None else transform_matrix(
                  transform if registered is None else registration_inputs.ep_transform(registered, red)),
              reduction_point=red, transform_applied=bool(values.get("transform_applied", False)))
    if values.get("alignment_covariance") is not None:
        covariance = registration_inputs.registration_of(values["alignment_covariance"], "--alignment-covariance")
        kw["alignment_covariance"] = alignment_covariance(
            values["alignment_covariance"] if covariance is None
            else registration_inputs.ep_alignment_covariance(covariance, red))
    return kw


def moved_compared(shared: dict, xyz: np.ndarray) -> np.ndarray:
    """Where the engine sees compared points (EP with a transformation not yet applied:
    p' = red + R (p - red) + t, src/uncertainty/uncertainty.cpp), for choosing a tile's points; the engine
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
                  transform=transform_matrix(ep.transform),
                  reduction_point=np.ascontiguousarray(ep.reduction_point, dtype=np.float64),
                  transform_applied=bool(ep.transform_applied))
        if ep.alignment_covariance is not None:
            kw["alignment_covariance"] = alignment_covariance(ep.alignment_covariance)
    return engine.compute(np.ascontiguousarray(reference, dtype=np.float64),
                          np.ascontiguousarray(compared, dtype=np.float64),
                          np.ascontiguousarray(core_points, dtype=np.float64), params,
                          None if core_normals is None else np.ascontiguousarray(core_normals, dtype=np.float64),
                          threads=threads, progress=progress, covariances=covariances, **kw)
