"""Out-of-core access to point clouds, for tiled runs (docs/scaling.md).

Reading: :class:`PointSource` gives a cloud's coordinates chunk by chunk **in file order** (the
order :func:`m3c2kit.io.read_cloud` returns them in), or only the points inside an axis-aligned box,
still in file order:

* LAS/LAZ: ``laspy.open(path).chunk_iterator(n)``; coordinates are the same scaled doubles as
  the in-memory reader's (``X * scale + offset``, computed by laspy the same way).
* COPC: the same chunked pass, and box queries through ``laspy.CopcReader.query(bounds)``, which
  decompresses only the octree nodes that meet the box. laspy sorts those nodes by their byte
  offset before decompressing them, and a COPC file is a LAZ file whose chunks are exactly its
  octree nodes, so the points come out in the relative order of a whole-file read (checked in
  tests/python/run/test_tiling.py).
* ``.npy``: ``np.load(mmap_mode="r")`` and slices.
* Any other format (text, PLY, E57): read whole with :func:`read_cloud` and sliced.

Writing: :class:`TableWriter` writes the output table in row chunks to a temporary file renamed
when complete (:func:`atomic_output`), producing the same bytes as
:func:`m3c2kit.io.write_cloud_table` for CSV/text and LAS/LAZ. Other formats (PLY) are gathered in
memory and written with :func:`write_cloud_table` at the end.
"""
from __future__ import annotations

import contextlib
from pathlib import Path
from typing import Iterator

import numpy as np

from ..base.errors import CloudReadError, CloudWriteError
from ..base.fault_hook import checkpoint as fault_checkpoint
from .arrays import bounds
from .atomic import atomic_output
from .cloud import Cloud
from .files import read_cloud, write_cloud_table
from .guard import read_errors, write_errors
from .quantised import Quantised
from .registry import extension_of, format_for

__all__ = ["PointSource", "TableWriter", "DEFAULT_CHUNK"]

DEFAULT_CHUNK = 1 << 20


class PointSource:
    """One input cloud, read lazily. ``kind`` is ``"las"``, ``"copc"``, ``"npy"`` or ``"memory"``."""

    def __init__(self, path, *, drop_nonfinite: bool = False, cloud: Cloud | None = None):
        self.path = Path(path)
        self.drop_nonfinite = drop_nonfinite
        self._cloud = cloud
        self._like: Cloud | None = None
        fmt = format_for(self.path)
        ext = extension_of(self.path)
        if cloud is not None:
            self.kind = "memory"
        elif fmt is not None and fmt.name == "LAS/LAZ" and self.path.is_file():
            from .las_header import check_las_file
            with read_errors(self.path):
                layout = check_las_file(self.path)
            self.kind = "copc" if layout.copc else "las"
        elif ext == ".npy" and self.path.is_file():
            self.kind = "npy"
            self._npy_check()
        else:
            self.kind = "memory"
            self._cloud = read_cloud(self.path, drop_nonfinite=drop_nonfinite)

    # ------------------------------------------------------------------------------ metadata
    @property
    def cloud(self) -> Cloud | None:
        """The whole cloud when it was read into memory, else None."""
        return self._cloud

    def like(self) -> Cloud:
        """A Cloud without points carrying what a writer copies: LAS scale, offset and CRS; the
        same object at every call, so that a CRS assigned to it (--crs) is the run's."""
        if self._like is None:
            self._like = self._read_like()
        return self._like

    def _read_like(self) -> Cloud:
        if self._cloud is not None:
            c = self._cloud
            return Cloud(np.empty((0, 3)), {}, c.crs, c.scale, c.offset, c.scan_positions, c.path,
                         c.units_hint, c.format, dict(c.meta), 0, c._crs_vlrs)
        if self.kind in ("las", "copc"):
            import laspy
            from .las import _read_crs
            with read_errors(self.path), laspy.open(self.path) as reader:
                header = reader.header
                crs, units, vlrs = _read_crs(header)
            return Cloud(np.empty((0, 3)), {}, crs=crs, scale=tuple(map(float, header.scales)),
                         offset=tuple(map(float, header.offsets)), path=self.path, units_hint=units,
                         format="COPC" if self.kind == "copc" else "LAS", _crs_vlrs=vlrs)
        return Cloud(np.empty((0, 3)), {}, path=self.path, format="NPY")

    def point_count(self) -> int | None:
        """Points in the file (before dropping non-finite ones), when cheap to know."""
        if self._cloud is not None:
            return len(self._cloud)
        if self.kind in ("las", "copc"):
            import laspy
            with read_errors(self.path), laspy.open(self.path) as reader:
                return int(reader.header.point_count)
        return int(self._npy_array().shape[0])

    # ------------------------------------------------------------------------------- reading
    def _npy_array(self):
        return np.load(self.path, mmap_mode="r", allow_pickle=False)

    def _npy_check(self) -> None:
        with read_errors(self.path):
            a = self._npy_array()
        if a.dtype.names is None:
            if a.ndim != 2 or a.shape[1] != 3 or a.dtype.kind not in "iuf":
                raise CloudReadError(f"{self.path}: expected an (N, 3) numeric array, got shape {a.shape} of {a.dtype}")
        else:
            by_lower = {n.lower(): n for n in a.dtype.names}
            if a.ndim != 1 or any(c not in by_lower for c in "xyz"):
                raise CloudReadError(f"{self.path}: expected a 1-D structured array with x, y, z fields")

    def _npy_chunk(self, a, start: int, stop: int) -> np.ndarray:
        part = a[start:stop]
        if a.dtype.names is None:
            return np.ascontiguousarray(part, dtype=np.float64)
        by_lower = {n.lower(): n for n in a.dtype.names}
        # Exactly what npy.read does: column_stack, then float64.
        return np.column_stack([part[by_lower[c]] for c in "xyz"]).astype(np.float64)

    def _raw_chunks(self, size: int) -> Iterator[np.ndarray]:
        if self._cloud is not None:
            xyz = self._cloud.xyz
            for start in range(0, len(xyz), size):
                yield xyz[start:start + size]
        elif self.kind in ("las", "copc"):
            import laspy

            from . import laz_threads
            with read_errors(self.path), laspy.open(self.path, laz_backend=laz_threads.backend()) as reader:
                for points in reader.chunk_iterator(size):
                    yield _xyz_of(points)
        else:
            a = self._npy_array()
            for start in range(0, a.shape[0], size):
                yield self._npy_chunk(a, start, start + size)

    def chunks(self, size: int = DEFAULT_CHUNK) -> Iterator[np.ndarray]:
        """(n, 3) float64 chunks in file order; non-finite points dropped if asked, else an error."""
        for xyz in self._raw_chunks(size):
            finite = self._finite_rows(xyz)
            if finite is not None:
                xyz = xyz[finite]
            if len(xyz):
                yield xyz
        fault_checkpoint("reading")  # a testing aid (m3c2kit.base.fault_hook): the whole file streamed

    def _finite_rows(self, xyz: np.ndarray) -> np.ndarray | None:
        """The mask of a streamed chunk's finite rows to keep (--drop-nonfinite), None when all
        are kept (a cloud read whole was checked by read_cloud); else an error naming the file."""
        if self._cloud is not None:
            return None
        finite = np.isfinite(xyz).all(axis=1)
        if finite.all():
            return None
        if not self.drop_nonfinite:
            raise CloudReadError(f"{self.path}: some points have non-finite (NaN or infinite) "
                                 f"coordinates; use --drop-nonfinite to drop them")
        return finite

    def records(self, size: int = DEFAULT_CHUNK, fields=()) -> Iterator[tuple[np.ndarray, dict]]:
        """As chunks(), with the per-point `fields` (read_cloud's names: LAS dimensions, a
        multi-valued one as NAME_K, PLY properties, text columns) that the file has: (xyz, {name:
        values}) chunks in file order, non-finite points dropped from both."""
        fields = tuple(fields)
        for xyz, values in self._raw_records(size, fields):
            finite = self._finite_rows(xyz)
            if finite is not None:
                xyz = xyz[finite]
                values = {k: v[finite] for k, v in values.items()}
            if len(xyz):
                yield xyz, values
        fault_checkpoint("reading")  # as chunks()

    def _raw_records(self, size: int, fields: tuple) -> Iterator[tuple[np.ndarray, dict]]:
        if self._cloud is not None:
            xyz, have = self._cloud.xyz, self._cloud.fields
            for start in range(0, len(xyz), size):
                yield xyz[start:start + size], {k: np.asarray(have[k])[start:start + size] for k in fields if k in have}
        elif self.kind in ("las", "copc"):
            import laspy
            with read_errors(self.path), laspy.open(self.path) as reader:
                names = set(reader.header.point_format.dimension_names)
                for points in reader.chunk_iterator(size):
                    yield _xyz_of(points), {k: v for k in fields if (v := _las_field(points, names, k)) is not None}
        else:
            a = self._npy_array()
            have = set(a.dtype.names or ())
            for start in range(0, a.shape[0], size):
                part = a[start:start + size]
                yield self._npy_chunk(a, start, start + size), {k: np.asarray(part[k]) for k in fields if k in have}

    def attribute_records(self, size: int = DEFAULT_CHUNK) -> Iterator[tuple[np.ndarray, dict]]:
        """(xyz, fields) chunks in file order with every per-point field, named, typed and valued
        as m3c2kit.io.read_cloud gives them (LAS: m3c2kit.io.las's fields of each chunk, no_data
        as NaN): the attributes a written table carries for the core points that are these points."""
        if self.kind not in ("las", "copc"):
            if self._cloud is not None:
                yield from self.records(size, tuple(self._cloud.fields))
            else:
                yield from self.records(size, self._npy_fields())
            return
        import laspy

        from . import las, laz_threads
        with read_errors(self.path), laspy.open(self.path, laz_backend=laz_threads.backend()) as reader:
            for points in reader.chunk_iterator(size):
                xyz = _xyz_of(points)
                values = las._fields(laspy.LasData(header=reader.header, points=points))
                finite = self._finite_rows(xyz)
                if finite is not None:
                    xyz, values = xyz[finite], {k: v[finite] for k, v in values.items()}
                if len(xyz):
                    yield xyz, values
        fault_checkpoint("reading")  # as chunks()

    def _npy_fields(self) -> tuple:
        """The fields m3c2kit.io.npy.read keeps: numeric scalar ones besides x, y, z."""
        a = self._npy_array()
        names = a.dtype.names or ()
        by_lower = {n.lower(): n for n in names}
        coords = {by_lower[c] for c in "xyz" if c in by_lower}
        return tuple(n for n in names if n not in coords and a.dtype[n].kind in "biuf" and a.dtype[n].shape == ())

    def query_box(self, lo, hi, size: int = DEFAULT_CHUNK) -> np.ndarray:
        """The points with lo <= p <= hi (each axis, inclusive), in file order."""
        lo, hi = np.asarray(lo, float), np.asarray(hi, float)
        if self.kind == "copc":
            return self._copc_query(lo, hi)
        parts = [xyz[_in_box(xyz, lo, hi)] for xyz in self.chunks(size)]
        return np.concatenate(parts) if parts else np.empty((0, 3))

    def _copc_query(self, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        import laspy
        from laspy.copc import Bounds
        with read_errors(self.path), laspy.CopcReader.open(self.path) as reader:
            scales, offsets = np.asarray(reader.header.scales), np.asarray(reader.header.offsets)
            # Pad by two quanta (laspy rounds the box to integer coordinates) and clip to the
            # int32 range so the conversion cannot wrap; the exact test is ours, below.
            imin = offsets + (-(2 ** 31) + 2) * scales
            imax = offsets + (2 ** 31 - 3) * scales
            qlo = np.clip(lo - 2 * scales, imin, imax)
            qhi = np.clip(hi + 2 * scales, imin, imax)
            points = reader.query(bounds=Bounds(mins=qlo, maxs=qhi))
            xyz = _xyz_of(points)
        return xyz[_in_box(xyz, lo, hi)]


def _las_field(points, names: set, name: str):
    """Field `name` of a chunk of LAS points as m3c2kit.io.las reads it (NAME_K: column K of a
    multi-valued dimension), or None."""
    if name in names and name not in ("X", "Y", "Z"):
        values = np.asarray(points[name])
        return values if values.ndim == 1 else None
    base, _, k = name.rpartition("_")
    if base in names and k.isdigit():
        values = np.asarray(points[base])
        if values.ndim == 2 and int(k) < values.shape[1]:
            return np.ascontiguousarray(values[:, int(k)])
    return None


def _xyz_of(points) -> np.ndarray:
    xyz = np.empty((len(points), 3), dtype=np.float64)
    xyz[:, 0], xyz[:, 1], xyz[:, 2] = points.x, points.y, points.z
    return xyz


def _in_box(xyz: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    return ((xyz[:, 0] >= lo[0]) & (xyz[:, 0] <= hi[0]) & (xyz[:, 1] >= lo[1]) & (xyz[:, 1] <= hi[1])
            & (xyz[:, 2] >= lo[2]) & (xyz[:, 2] <= hi[2]))


# ------------------------------------------------------------------------------------- writing

class TableWriter:
    """Writes an output table chunk by chunk; same bytes as write_cloud_table for .csv/.txt/.xyz/.asc
    and .las/.laz. Use as a context manager: the file appears only when the block completes.

    For LAS without a scale/offset in `like`, pass `xyz_min` and `xyz_max` (the minimum and
    maximum of every row's x, y, z) so that the scale and offset are the ones the in-memory
    writer would choose (las.choose_scale_offset), with the same QuantisationWarning.
    """

    def __init__(self, path, *, like: Cloud | None = None, xyz_min=None, xyz_max=None):
        self.path = Path(path)
        fmt = format_for(self.path, writing=True)
        if fmt is None or fmt.write is None:
            raise CloudWriteError(f"{path}: cannot write {extension_of(self.path)!r} files")
        self.mode = "las" if fmt.quantises else ("text" if fmt.name == "ASCII" else "memory")
        self.like = like
        self.xyz_min = xyz_min
        self.xyz_max = xyz_max
        # [largest error, largest |coordinate|, all float32, lo, hi] when the scale is derived
        self._quantised = None
        self._stack = contextlib.ExitStack()
        self._parts: list = []
        self._started = False
        self.rows = 0

    def __enter__(self) -> "TableWriter":
        if self.mode != "memory":
            self._tmp = self._stack.enter_context(atomic_output(self.path))
        return self

    def __exit__(self, exc_type, exc, tb):
        try:
            if exc_type is None:
                if not self._started:
                    self._start_empty()
                if self.mode == "las":
                    with write_errors(self.path):
                        self._extra_bytes_statistics()
                        self._las_writer.close()
                    self._out.close()
                    self._warn_if_quantised()
                elif self.mode == "text":
                    self._out.close()
                else:
                    self._write_memory()
            else:
                for name in ("_las_writer", "_out"):
                    obj = getattr(self, name, None)
                    if obj is not None:
                        with contextlib.suppress(Exception):
                            obj.close()
        finally:
            return self._stack.__exit__(exc_type, exc, tb)

    def write(self, xyz: np.ndarray, fields: dict[str, np.ndarray]) -> None:
        """Appends rows (xyz (n, 3) and one 1-D array per field, same order of fields every call)."""
        if not self._started:
            self._start(fields)
        self.rows += len(xyz)
        if self.mode == "memory":
            self._parts.append((np.array(xyz), {k: np.array(v) for k, v in fields.items()}))
        elif self.mode == "text":
            self._write_text(xyz, fields)
        else:
            self._write_las(xyz, fields)

    # -- text: the layout of ascii.write
    def _start(self, fields) -> None:
        self._started = True
        if self.mode == "text":
            self._sep = "," if self.path.suffix.lower() == ".csv" else " "
            for name in fields:
                if not name or self._sep in name or any(c.isspace() or c in "\"'" for c in name):
                    raise CloudWriteError(f"{self.path}: field name {name!r} cannot be written as a text column name")
            self._out = open(self._tmp, "w", encoding="ascii", newline="\n")
            self._out.write(self._sep.join(["x", "y", "z", *fields]) + "\n")
        elif self.mode == "las":
            self._start_las(fields)

    def _start_empty(self) -> None:
        if self.mode == "memory":
            return
        raise CloudWriteError(f"{self.path}: no rows were written")

    def _write_text(self, xyz, fields) -> None:
        from .ascii import _CHUNK, _text_column
        columns = [xyz[:, 0], xyz[:, 1], xyz[:, 2], *(np.asarray(v) for v in fields.values())]
        with write_errors(self.path):
            for start in range(0, len(xyz), _CHUNK):
                text = [_text_column(c[start:start + _CHUNK]) for c in columns]
                self._out.write("\n".join(map(self._sep.join, zip(*text))))
                self._out.write("\n")

    # -- LAS: the header of las.write, points through laspy's chunked writer
    def _start_las(self, fields) -> None:
        import laspy
        from . import las, laz_threads
        rgb = all(c in fields for c in ("red", "green", "blue"))
        header = laspy.LasHeader(version="1.4", point_format=7 if rgb else 6)
        self._standard = set(header.point_format.dimension_names) - {"X", "Y", "Z"}
        self._extra = las._plan_extra_dims(self.path, fields, self._standard)
        with write_errors(self.path):
            if self._extra:
                header.add_extra_dims(las.extra_bytes_params(self._extra))
        like = self.like
        if like is not None and like.scale is not None and like.offset is not None:
            scale, offset = tuple(like.scale), tuple(like.offset)
        elif (self.xyz_min is not None and self.xyz_max is not None and np.isfinite(self.xyz_min).all()
              and np.isfinite(self.xyz_max).all()):
            scale, offset = las.choose_scale_offset(self.xyz_min, self.xyz_max)
            las.refuse_coarse_scale(self.path, scale, self.xyz_min, self.xyz_max)
            self._quantised = [0.0, 0.0, True, np.full(3, np.inf), np.full(3, -np.inf)]
        elif self.xyz_min is not None and np.isfinite(self.xyz_min).all():
            raise CloudWriteError(f"{self.path}: a LAS scale for these coordinates needs their maximum too "
                                  f"(TableWriter(xyz_max=...))")
        else:
            scale, offset = (las._DEFAULT_SCALE,) * 3, (0.0, 0.0, 0.0)
        self._scale, self._offset = scale, offset
        header.scales, header.offsets = np.array(scale), np.array(offset)
        las._add_crs(header, like)
        self._header = header
        self._first_points = None
        self._out = open(self._tmp, "wb+")
        with write_errors(self.path):
            compress = self.path.suffix.lower() == ".laz"
            self._las_writer = laspy.LasWriter(self._out, header=header, do_compress=compress, closefd=False,
                                               laz_backend=laz_threads.backend() if compress else None)

    def _warn_if_quantised(self) -> None:
        from . import las
        if self._quantised is None:
            return
        error, magnitude, float32, lo, hi = self._quantised
        if error > las.quantisation_tolerance(magnitude, float32):
            import warnings
            from ..base.errors import QuantisationWarning
            span = float(np.max(hi - np.asarray(self._offset)))
            warnings.warn(las.quantisation_message(self.path, error, self._scale, span),
                          QuantisationWarning, stacklevel=3)

    def _extra_bytes_statistics(self) -> None:
        # laspy records min/max of extra-bytes dimensions on every write_points call, but (laspy
        # 2.x) it reads only the first point of each call (pts[..., i] on a 1-D field). A single
        # in-memory write therefore stores the first row's values; reproduce that exactly, and
        # keep laspy's own running statistics when it computes true ones.
        if self._first_points is None or not _laspy_eb_stats_first_point_only():
            return
        for vlr in self._las_writer.header.vlrs.get("ExtraBytesVlr"):
            vlr.partial_reset()
            vlr.grow(self._first_points)

    def _write_las(self, xyz, fields) -> None:
        import laspy
        from . import las
        xyz = np.asarray(xyz, dtype=np.float64)
        ints = las._quantise(self.path, xyz, self._scale, self._offset)
        if self._quantised is not None and len(xyz):
            q = self._quantised
            q[0] = max(q[0], las.quantisation_error(xyz, ints, self._scale, self._offset))
            q[1] = max(q[1], float(np.max(np.abs(xyz))))
            q[2] = q[2] and las.is_float32(xyz)
            lo, hi = bounds(xyz)
            q[3], q[4] = np.minimum(q[3], lo), np.maximum(q[4], hi)
        with write_errors(self.path):
            points = laspy.ScaleAwarePointRecord.zeros(len(xyz), header=self._header)
            points.X, points.Y, points.Z = ints[:, 0], ints[:, 1], ints[:, 2]
            extra = {name: t for name, t, *_ in self._extra}
            for name, values in fields.items():
                if isinstance(values, Quantised):
                    points.array[name] = values.encoded()
                    continue
                dtype = points[name].dtype if name in self._standard else extra[name]
                points[name] = las._exact_cast(self.path, name, values, dtype)
            if self._first_points is None and len(points):
                self._first_points = points[:1]
            self._las_writer.write_points(points)

    # -- anything else: gather, then the ordinary writer
    def _write_memory(self) -> None:
        if self._parts:
            xyz = np.concatenate([p[0] for p in self._parts])
            names = list(self._parts[0][1])
            fields = {n: np.concatenate([p[1][n] for p in self._parts]) for n in names}
        else:
            xyz, fields = np.empty((0, 3)), {}
        write_cloud_table(self.path, xyz, fields, like=self.like)


_EB_PROBE: list = []


def _laspy_eb_stats_first_point_only() -> bool:
    """Whether this laspy's extra-bytes min/max looks only at each call's first point."""
    if not _EB_PROBE:
        import laspy
        header = laspy.LasHeader(version="1.4", point_format=6)
        header.add_extra_dims([laspy.ExtraBytesParams(name="probe", type=np.uint8)])
        points = laspy.ScaleAwarePointRecord.zeros(2, header=header)
        points["probe"] = np.array([5, 2], dtype=np.uint8)
        header.partial_reset()
        header.grow(points)
        struct = header.vlrs.get("ExtraBytesVlr")[0].extra_bytes_structs[0]
        _EB_PROBE.append(int(struct._raw_min()[0]) == 5)
    return _EB_PROBE[0]

