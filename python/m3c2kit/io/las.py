"""LAS / LAZ / COPC reading and LAS / LAZ writing through laspy (lazrs backend for LAZ).

Reading: every LAS 1.0-1.4 point format; coordinates are the scaled doubles (laspy's
``las.x/y/z``); every other dimension becomes a field (array-valued extra bytes are split into
``name_0, name_1, ...``). COPC files are read whole, as plain LAZ.

Writing: LAS 1.4, point format 6 (7 when the fields hold red, green and blue). A field whose
name is a standard dimension of that format goes into it (its values must fit exactly);
every other field becomes an extra-bytes dimension of its own numeric type (bool as uint8,
other types as float64).
"""
from __future__ import annotations

import math
import warnings
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..base.errors import CloudReadError, CloudWriteError, QuantisationWarning
from .quantised import Quantised
from .arrays import bounds
from .atomic import atomic_output
from .cloud import Cloud
from .crs import geokey_crs, geokey_units, looks_like_wkt, wkt_units
from . import laz_threads
from .guard import read_errors, write_errors
from .las_header import check_las_file

if TYPE_CHECKING:
    import laspy

__all__ = ["read", "write"]

# laspy is imported where it is used, not here: it imports pyproj and requests (about a third of
# a second), which `import m3c2kit`, `m3c2 --help` and runs without LAS files never need.

_PROJECTION_USER = "LASF_Projection"
_WKT_RECORD = 2112
_GEOTIFF_RECORDS = (34735, 34736, 34737)
_DEFAULT_SCALE = 0.001  # only for a cloud without finite coordinates (nothing to derive it from)
_INT32 = (-(2**31), 2**31 - 1)


def read(path: Path) -> Cloud:
    """Reads a .las/.laz/.copc.laz file; see the module docstring for what is kept."""
    import laspy

    with read_errors(path):
        layout = check_las_file(path)
        with laspy.open(path, laz_backend=laz_threads.backend()) as reader:
            header = reader.header
            las = reader.read()
    n = len(las.points)
    if n != header.point_count:
        raise CloudReadError(f"{path}: truncated or corrupt: the header declares {header.point_count} "
                             f"points but {n} could be read")
    xyz = _scaled_xyz(las, header)
    crs, units, crs_vlrs = _read_crs(header)
    fmt = "COPC" if layout.copc else ("LAZ" if layout.compressed else "LAS")
    return Cloud(xyz, _fields(las), crs=crs, scale=tuple(map(float, header.scales)),
                 offset=tuple(map(float, header.offsets)), path=Path(path), units_hint=units, format=fmt,
                 meta={"version": f"{header.version.major}.{header.version.minor}",
                       "point_format": int(header.point_format.id),
                       "creation_date": header.creation_date},  # a datetime.date, or None
                 _crs_vlrs=crs_vlrs)


def _scaled_xyz(las: laspy.LasData, header: laspy.LasHeader) -> np.ndarray:
    """The (n, 3) float64 coordinates, C-contiguous as the engine takes them, computed straight
    into their columns: stored integer * scale + offset, the very operations (and bits) of laspy's
    ``las.x``, without its temporary array per axis (issue 19: no copies between reading and the
    engine; the engine gets this array itself, m3c2kit.io.arrays.as_coordinates)."""
    xyz = np.empty((len(las.points), 3), dtype=np.float64)
    for axis, name in enumerate("XYZ"):
        column = xyz[:, axis]
        np.multiply(las.points[name], header.scales[axis], out=column)
        np.add(column, header.offsets[axis], out=column)
    return xyz


def _no_data(header: laspy.LasHeader) -> dict[str, float]:
    """The declared no_data value of each one-element extra-bytes dimension (laspy keeps the
    declaration in the record but does not apply it)."""
    out = {}
    for vlr in header.vlrs.get("ExtraBytesVlr"):
        for struct in vlr.extra_bytes_structs:
            if struct.data_type != 0 and struct.options & struct.NO_DATA_BIT_MASK and struct.num_elements() == 1:
                out[struct.name.rstrip(b"\0").decode("ascii", "replace")] = struct.no_data[0]
    return out


def _fields(las: laspy.LasData) -> dict[str, np.ndarray]:
    fields: dict[str, np.ndarray] = {}
    no_data = _no_data(las.header)
    for name in las.point_format.dimension_names:
        if name in ("X", "Y", "Z"):
            continue
        values = np.asarray(las[name])
        if name in no_data:  # NaN where the stored value is the declared no_data (io/quantised.py)
            values = values.astype(np.float64)
            values[las.points.array[name] == no_data[name]] = np.nan
        if values.ndim == 1:
            fields[name] = values
        else:
            for k in range(values.shape[1]):
                fields[f"{name}_{k}"] = np.ascontiguousarray(values[:, k])
    return fields


def _vlr_bytes(vlr) -> bytes:
    if hasattr(vlr, "record_data_bytes"):
        return bytes(vlr.record_data_bytes())
    return bytes(vlr.record_data)


def _read_crs(header: laspy.LasHeader) -> tuple[str | None, str | None, tuple]:
    """(crs, units_hint, raw LASF_Projection VLRs) of a LAS header."""
    records = list(header.vlrs) + list(header.evlrs or [])
    raw = tuple((v.user_id, v.record_id, v.description, _vlr_bytes(v)) for v in records
                if v.user_id == _PROJECTION_USER and v.record_id in (_WKT_RECORD, *_GEOTIFF_RECORDS))
    # The file's own WKT text is kept as written (m3c2kit.io.crs compares CRSs through pyproj).
    # LASF_Projection 2112 is the standard WKT record; libLAS wrote the same text under its own
    # user id, so that is the fallback.
    wkt = None
    for user in (_PROJECTION_USER, "liblas"):
        for v in records:
            if v.user_id == user and v.record_id == _WKT_RECORD:
                text = _vlr_bytes(v).split(b"\0", 1)[0].decode("utf-8", "replace").strip()
                if looks_like_wkt(text):
                    wkt = text
                    break
        if wkt:
            break
    keys = _geokeys(records)
    # GeoTIFF keys only: their EPSG code, else (user-defined keys) what pyproj makes of them.
    # laspy's parse_crs() reads LASF_Projection records only: without one there is nothing for
    # pyproj to parse, and its import (0.06 s) is spared.
    projection = any(v.user_id == _PROJECTION_USER for v in records)
    crs = wkt or geokey_crs(keys) or (_pyproj_wkt(header) if projection else None)
    units = (wkt_units(wkt) if wkt else None) or geokey_units(keys) or (wkt_units(crs) if crs else None)
    return crs, units, raw


def _pyproj_wkt(header: laspy.LasHeader) -> str | None:
    # parse_crs() needs pyproj (optional); it also understands GeoTIFF keys.
    try:
        import pyproj  # noqa: F401
    except ImportError:
        return None
    try:
        crs = header.parse_crs()
    except Exception:  # a broken CRS record must not make the points unreadable
        return None
    return crs.to_wkt() if crs is not None else None


def _geokeys(records) -> dict[int, int]:
    for v in records:
        if v.user_id == _PROJECTION_USER and v.record_id == 34735 and hasattr(v, "geo_keys"):
            return {int(k.id): int(k.value_offset) for k in v.geo_keys if k.tiff_tag_location == 0}
    return {}


# ----------------------------------------------------------------------------------------- write

def write(path: Path, xyz: np.ndarray, fields: dict[str, np.ndarray], like: Cloud | None) -> None:
    """Writes LAS 1.4 (LAZ when `path` ends in .laz) atomically; see the module docstring.

    Coordinates use `like`'s scale and offset when it has them, else choose_scale_offset's (the
    finest decimal scale at which int32 holds the data; a QuantisationWarning when it rounds
    the coordinates by more than their float64 resolution). Coordinates that do not fit (int32 after scaling) or are not finite raise
    CloudWriteError; nothing is ever wrapped or clamped. `like`'s CRS is copied: its WKT as a
    WKT VLR (global-encoding WKT bit set), else its raw GeoTIFF key VLRs.
    """
    import laspy

    n = len(xyz)
    rgb = all(c in fields for c in ("red", "green", "blue"))
    header = laspy.LasHeader(version="1.4", point_format=7 if rgb else 6)
    standard = set(header.point_format.dimension_names) - {"X", "Y", "Z"}
    extra = _plan_extra_dims(path, fields, standard)
    with write_errors(path):
        if extra:
            header.add_extra_dims(extra_bytes_params(extra))
    scale, offset = _scale_offset(xyz, like)
    if not _has_scale(like) and len(xyz) and np.isfinite(xyz).all():
        refuse_coarse_scale(path, scale, *bounds(xyz))
    ints = _quantise(path, xyz, scale, offset)
    header.scales, header.offsets = np.array(scale), np.array(offset)
    _add_crs(header, like)
    with write_errors(path):
        points = laspy.ScaleAwarePointRecord.zeros(n, header=header)
        las = laspy.LasData(header=header, points=points)
        las.X, las.Y, las.Z = ints[:, 0], ints[:, 1], ints[:, 2]
        types = {name: t for name, t, *_ in extra}
        for name, values in fields.items():
            if isinstance(values, Quantised):
                las.points.array[name] = values.encoded()
            else:
                las[name] = _exact_cast(path, name, values, las[name].dtype if name in standard else types[name])
        # laspy picks compression from a path's suffix (the temporary has none): pass a stream.
        with atomic_output(path) as tmp, open(tmp, "wb+") as out:
            compress = Path(path).suffix.lower() == ".laz"
            las.write(out, do_compress=compress, laz_backend=laz_threads.backend() if compress else None)
    if not _has_scale(like) and n:
        warn_if_quantised(path, xyz, ints, scale, offset)  # once written: a failed write says only why


def _plan_extra_dims(path, fields: dict, standard: set[str]) -> list[tuple]:
    """(name, type, scale, no_data) of each field that is not a standard dimension (scale and
    no_data None unless the field is a :class:`~m3c2kit.io.quantised.Quantised` column)."""
    plan = []
    for name, values in fields.items():
        if name in standard:
            continue
        if name.lower() in ("x", "y", "z"):
            raise CloudWriteError(f"{path}: field name {name!r} is reserved for coordinates in LAS")
        try:
            encoded = name.encode("ascii")
        except UnicodeEncodeError:
            raise CloudWriteError(f"{path}: LAS extra-bytes names must be ASCII, got {name!r}") from None
        if not 0 < len(encoded) <= 32:
            raise CloudWriteError(f"{path}: LAS extra-bytes names must be 1 to 32 characters, got {name!r}")
        if isinstance(values, Quantised):
            plan.append((name, values.dtype, values.scale, values.no_data))
        else:
            plan.append((name, _extra_type(np.asarray(values).dtype), None, None))
    return plan


def extra_bytes_params(plan: list[tuple]) -> list:
    """laspy's ExtraBytesParams for a :func:`_plan_extra_dims` plan."""
    import laspy

    out = []
    for name, dtype, scale, no_data in plan:
        kw = {}
        if scale is not None:
            kw.update(scales=np.array([scale]), offsets=np.array([0.0]))
        if no_data is not None:
            kw.update(no_data=np.array([no_data]))
        out.append(laspy.ExtraBytesParams(name=name, type=dtype, **kw))
    return out


#: Extra-bytes types LAS defines (LAS 1.4 R15, Table 24): a field keeps its own numeric type
#: (m3c2kit.io.fields chooses float32 / uint32 / uint8 for the M3C2 columns); bool is uint8.
_EXTRA_TYPES = {np.dtype(t) for t in (np.uint8, np.int8, np.uint16, np.int16, np.uint32, np.int32,
                                      np.uint64, np.int64, np.float32, np.float64)}


def _extra_type(dtype: np.dtype) -> np.dtype:
    if dtype == np.bool_:
        return np.dtype(np.uint8)
    return dtype if dtype in _EXTRA_TYPES else np.dtype(np.float64)


def _has_scale(like: Cloud | None) -> bool:
    return like is not None and like.scale is not None and like.offset is not None


def _scale_offset(xyz: np.ndarray, like: Cloud | None):
    if _has_scale(like):
        return tuple(like.scale), tuple(like.offset)
    if len(xyz) == 0 or not np.isfinite(xyz).all():
        return (_DEFAULT_SCALE,) * 3, (0.0, 0.0, 0.0)
    return choose_scale_offset(*bounds(xyz))


def choose_scale_offset(lo, hi) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """LAS scale and offset for coordinates within [lo, hi] (per axis) that have no LAS scale
    of their own (ASCII, PLY, E57, .npy inputs; computed positions).

    offset = floor(lo) per axis; one decimal scale for x, y and z: the finest power of ten at
    which int32 holds every axis's span from its offset, but not finer than the float64
    resolution of the values (np.spacing of the largest magnitude: a finer scale stores nothing
    more). A laboratory scan (a few centimetres) gets 1e-10 or 1e-9, a 1 km survey at UTM
    coordinates 1e-6, a 30 km one 1e-4. The fixed 0.001 used before wrote a laboratory scan's
    2,000 core points at one position and cut survey coordinates below a millimetre silently.
    """
    lo, hi = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
    offset = np.floor(lo)
    span = float(np.max(hi - offset))
    magnitude = float(np.max(np.maximum(np.abs(lo), np.abs(hi))))
    if magnitude == 0.0:
        return (_DEFAULT_SCALE,) * 3, tuple(map(float, offset))
    finest = max(span / _INT32[1], float(np.spacing(magnitude)))
    exponent = math.ceil(math.log10(finest))
    scale = float(f"1e{exponent}")
    if span / scale > _INT32[1]:  # log10 rounding at an exact power of ten
        scale = float(f"1e{exponent + 1}")
    return (scale,) * 3, tuple(map(float, offset))


#: The coarsest LAS scale m3c2 chooses (one unit of the coordinates per int32 step): a coarser one
#: means coordinates spanning over 2.1e9 units, which LAS cannot hold without moving points by
#: more than a unit (issue 42: ±1e300 was written at a scale of 1e291, every other point moved to 0).
COARSEST_SCALE = 1.0


def refuse_coarse_scale(path, scale, lo, hi) -> None:
    """A CloudWriteError when coordinates within [lo, hi] need a scale coarser than COARSEST_SCALE."""
    if scale[0] > COARSEST_SCALE:
        lo, hi = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
        raise CloudWriteError(f"{path}: LAS cannot store these coordinates (x {lo[0]:.6g}..{hi[0]:.6g}, y "
                              f"{lo[1]:.6g}..{hi[1]:.6g}, z {lo[2]:.6g}..{hi[2]:.6g}): their span needs int32 steps "
                              f"of {scale[0]:g} units, moving every point by up to half that; write .ply, .csv or "
                              f".txt, which keep float64")


def quantisation_error(xyz: np.ndarray, ints: np.ndarray, scale, offset) -> float:
    """The largest distance, on any axis, between a coordinate and its stored LAS value."""
    if len(xyz) == 0:
        return 0.0
    stored = ints * np.asarray(scale) + np.asarray(offset)
    return float(np.max(np.abs(stored - xyz)))


def is_float32(xyz: np.ndarray) -> bool:
    """Whether every coordinate is a float32 value (a PLY or E57 cloud stored in float32)."""
    with np.errstate(over="ignore", invalid="ignore"):
        return bool(np.array_equal(xyz.astype(np.float32).astype(np.float64), xyz))


def quantisation_tolerance(magnitude: float, float32: bool) -> float:
    """Rounding that loses nothing the values resolve: a few steps of their own float type at
    the largest magnitude (float32 data resolve far less than float64's 1e-16 relative)."""
    step = np.spacing(np.float32(magnitude)) if float32 else np.spacing(magnitude)
    return 4.0 * float(step)


def warn_if_quantised(path, xyz: np.ndarray, ints: np.ndarray, scale, offset) -> None:
    """A QuantisationWarning when storing `xyz` at `scale` moves a coordinate by more than the
    values resolve (quantisation_tolerance): int32 cannot hold their span at a finer scale."""
    error = quantisation_error(xyz, ints, scale, offset)
    if error > quantisation_tolerance(float(np.max(np.abs(xyz))), is_float32(xyz)):
        span = float(np.max(bounds(xyz)[1] - np.asarray(offset)))
        warnings.warn(quantisation_message(path, error, scale, span), QuantisationWarning, stacklevel=3)


def quantisation_message(path, error: float, scale, span: float) -> str:
    return (f"{path}: LAS stores the coordinates at scale {scale[0]:g}, the finest at which its int32 "
            f"counts span {span:.6g} from the offset: they move by up to {error:.3g}; write .ply, .csv or "
            f".txt for full float64 precision")


def _quantise(path, xyz: np.ndarray, scale, offset) -> np.ndarray:
    bad = int((~np.isfinite(xyz)).any(axis=1).sum())
    if bad:
        raise CloudWriteError(f"{path}: LAS cannot store non-finite coordinates ({bad} points)")
    q = np.rint((xyz - np.asarray(offset)) / np.asarray(scale))
    for axis, name in enumerate("xyz"):
        if len(q) and (q[:, axis].min() < _INT32[0] or q[:, axis].max() > _INT32[1]):
            lo = offset[axis] + _INT32[0] * scale[axis]
            hi = offset[axis] + _INT32[1] * scale[axis]
            raise CloudWriteError(
                f"{path}: {name} coordinates [{xyz[:, axis].min()!r}, {xyz[:, axis].max()!r}] do not fit "
                f"LAS scale {scale[axis]!r} and offset {offset[axis]!r} (representable range "
                f"[{lo!r}, {hi!r}])")
    return q.astype(np.int32)


def _exact_cast(path, name: str, values: np.ndarray, dtype) -> np.ndarray:
    values = np.asarray(values)
    dtype = np.dtype(dtype)
    if values.dtype == dtype:
        return values
    with np.errstate(invalid="ignore", over="ignore"):
        cast = values.astype(dtype)
        same = cast.astype(values.dtype) == values
        if dtype.kind == "f":
            same |= np.isnan(values) if values.dtype.kind == "f" else False
    if not np.all(same):
        raise CloudWriteError(f"{path}: field {name!r} ({values.dtype}) does not fit the LAS {dtype} "
                              f"dimension exactly")
    return cast


def _add_crs(header: laspy.LasHeader, like: Cloud | None) -> None:
    import laspy

    if like is None:
        return
    if looks_like_wkt(like.crs):
        header.vlrs.append(laspy.vlrs.known.WktCoordinateSystemVlr(like.crs))
        header.global_encoding.wkt = True
        return
    # No WKT: copy the GeoTIFF keys verbatim (LAS 1.4 prefers WKT for point formats 6+, but
    # dropping the only CRS record would be worse).
    for user, record, description, data in like._crs_vlrs:
        if user == _PROJECTION_USER and record in _GEOTIFF_RECORDS:
            header.vlrs.append(laspy.VLR(user, record, description, data))
