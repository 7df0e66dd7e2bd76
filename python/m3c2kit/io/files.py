"""Reading, describing and writing point-cloud files, dispatched on the file extension."""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..base.errors import CloudReadError, CloudWriteError, UsageError
from ..base.fault_hook import checkpoint as fault_checkpoint
from .arrays import bounds as column_bounds
from .cloud import Cloud
from .input_file import check_input_file, path_argument
from .guard import available_memory, format_bytes, read_errors
from .las_header import check_las_file
from .quantised import Quantised
from .registry import SUPPORTED_READ, SUPPORTED_WRITE, extension_of, format_for, sniff

__all__ = ["read_cloud", "write_cloud_table", "info"]


def _open_checked(path: Path, columns) -> Cloud:
    """Checks that `path` is a readable, non-empty file whose content matches its extension,
    then reads it with the extension's reader. Clouds may be empty or hold non-finite points."""
    # A missing file, a directory, a FIFO, socket or device (reading could block forever) or a
    # name too long: refused where every input file is opened.
    check_input_file(path, error=CloudReadError, directory_note="not a point-cloud file")
    fmt = format_for(path)
    if fmt is None:
        raise CloudReadError(f"{path}: unknown point-cloud file extension {extension_of(path)!r} "
                             f"(supported: {' '.join(SUPPORTED_READ)})")
    try:
        with open(path, "rb") as f:
            head = f.read(16)
    except OSError as e:
        raise CloudReadError(f"{path}: cannot open: {e.strerror or e}") from None
    if not head:
        raise CloudReadError(f"{path}: is empty (0 bytes)")
    found = sniff(head)
    if found is not None and found != fmt.name:
        raise CloudReadError(f"{path}: the content is {found}, not {fmt.name} as the extension "
                             f"{extension_of(path)!r} says")
    _check_read_memory(path, fmt)
    if columns is not None:
        if not fmt.takes_columns:
            raise UsageError(f"{path}: column selection applies to text files only")
        return fmt.read(path, columns=columns)
    return fmt.read(path)


#: Bytes of memory a read takes per point beyond the file's own record: the float64 x, y, z.
XYZ_BYTES_PER_POINT = 24


def estimated_read_bytes(path: Path, fmt=None) -> int:
    """A lower bound of the memory reading `path` takes: for LAS/LAZ the header's point count
    times (24 bytes of float64 x, y, z + the point record length); for other formats the file
    size (a text, PLY or .npy file holds at least as many bytes as its points need)."""
    fmt = fmt or format_for(path)
    if fmt is not None and fmt.name == "LAS/LAZ":
        with read_errors(path):
            layout = check_las_file(path)
        return layout.point_count * (XYZ_BYTES_PER_POINT + layout.record_length)
    return path.stat().st_size


def _check_read_memory(path: Path, fmt, available: int | None = None) -> None:
    available = available_memory() if available is None else available
    if available is None:
        return
    needed = estimated_read_bytes(path, fmt)
    if needed > available:
        raise CloudReadError(f"{path}: reading it needs at least {format_bytes(needed)} of memory but only "
                             f"{format_bytes(available)} is available; process the clouds in tiles "
                             f"(--tile-size) or thin the file first")


#: read_cloud's drop_nonfinite on the command line: its error advises this flag, so every command
#: that reads clouds offers it (before, roughness, c2c, classify, ... advised a flag they lacked).
DROP_NONFINITE_FLAG = "--drop-nonfinite"


def add_drop_nonfinite_option(parser) -> None:
    """Adds DROP_NONFINITE_FLAG (``args.drop_nonfinite``) to an argparse parser."""
    parser.add_argument(DROP_NONFINITE_FLAG, action="store_true", help="drop points with NaN/Inf coordinates")


def read_cloud(path: str | os.PathLike, *, columns: tuple[int, int, int] | None = None,
               drop_nonfinite: bool = False) -> Cloud:
    """Reads any supported point-cloud file (see ``SUPPORTED_READ``) into a :class:`Cloud`.

    `columns` (text files only) picks the 0-based x, y, z columns. Points with a NaN or
    infinite coordinate make this raise, unless `drop_nonfinite`, which drops them and records
    how many in ``cloud.dropped_nonfinite``.

    Raises CloudReadError (message ``"{path}: {problem}"``) for a missing, empty, unreadable,
    unknown, mismatched, corrupt or truncated file, and for a file without points; UsageError
    for a bad `columns`.
    """
    path = path_argument("path", path)  # None or a number: a TypeError naming the argument
    cloud = _open_checked(path, columns)
    if len(cloud) == 0:
        raise CloudReadError(f"{path}: contains no points")
    bad = 0
    # A NaN or an infinity makes the sum one, so a finite sum proves every coordinate finite, 25
    # times faster than testing each (1M points: 0.7 against 17 ms); only a sum that is not
    # finite (or overflowed) has its points tested one by one.
    if not np.isfinite(np.sum(cloud.xyz)):
        finite = np.isfinite(cloud.xyz).all(axis=1)
        bad = int(len(finite) - np.count_nonzero(finite))
    if bad:
        # Every point non-finite: dropping them leaves nothing, so the advice would be no help.
        if bad == len(cloud):
            raise CloudReadError(f"{path}: contains no points with finite coordinates "
                                 f"({bad} non-finite)")
        if not drop_nonfinite:
            raise CloudReadError(f"{path}: {bad} of {len(cloud)} points have non-finite (NaN or "
                                 f"infinite) coordinates; use {DROP_NONFINITE_FLAG} to drop them")
        cloud = cloud.select(finite)
        cloud.dropped_nonfinite = bad
    fault_checkpoint("reading")  # a testing aid (m3c2kit.base.fault_hook)
    return cloud


def info(path: str | os.PathLike) -> dict:
    """A summary of a point-cloud file, read in full (header bounds are not trusted: some
    writers get them wrong).

    Keys: ``path``, ``format``, ``version`` (LAS, else None), ``point_format`` (LAS, else None),
    ``point_count``, ``nonfinite_count``, ``bounds`` (``{"min": [x, y, z], "max": [x, y, z]}``
    over the finite points, None if there are none), ``crs``, ``units_hint``, ``fields``
    (names), ``scale`` and ``offset`` (LAS, else None), ``scan_count`` (E57, else None).
    Unlike :func:`read_cloud`, a file without points is described, not rejected.
    """
    path = path_argument("path", path)  # None or a number: a TypeError naming the argument
    cloud = _open_checked(path, None)
    finite = np.isfinite(cloud.xyz).all(axis=1)
    points = cloud.xyz[finite]
    bounds = None
    if len(points):
        lo, hi = column_bounds(points)
        bounds = {"min": lo.tolist(), "max": hi.tolist()}
    return {
        "path": str(path),
        "format": cloud.format,
        "version": cloud.meta.get("version"),
        "point_format": cloud.meta.get("point_format"),
        "point_count": len(cloud),
        "nonfinite_count": int(len(finite) - np.count_nonzero(finite)),
        "bounds": bounds,
        "crs": cloud.crs,
        "units_hint": cloud.units_hint,
        "fields": list(cloud.fields),
        "scale": list(cloud.scale) if cloud.scale is not None else None,
        "offset": list(cloud.offset) if cloud.offset is not None else None,
        "scan_count": cloud.meta.get("scan_count"),
    }


def writable_format(path):
    """The format that writes the point-cloud file `path`, or a CloudWriteError naming it: a
    command asks before any work (convert read the whole input, warned, then failed)."""
    if Path(path).is_dir():  # before the extension: a folder has none ("cannot write '' files")
        raise CloudWriteError(f"{path}: is a directory")
    fmt = format_for(Path(path), writing=True)
    if fmt is None or fmt.write is None:
        ext = extension_of(Path(path))
        what = "has no extension to name its format" if not ext else f"cannot write {ext!r} files"
        raise CloudWriteError(f"{path}: {what} (supported: {' '.join(SUPPORTED_WRITE)})")
    return fmt


def write_cloud_table(path: str | os.PathLike, xyz: np.ndarray, fields: dict[str, np.ndarray], *,
                      like: Cloud | None = None) -> None:
    """Writes points and per-point columns to `path`, format chosen by extension
    (``SUPPORTED_WRITE``), atomically: on any error nothing is left at `path`.

    `xyz` is (N, 3); every field is 1-D of length N. `like` (typically the cloud the points came
    from) supplies the LAS scale, offset and CRS. Raises CloudWriteError
    (``"{path}: {problem}"``).
    """
    path = path_argument("path", path)
    try:
        xyz = np.asarray(xyz, dtype=np.float64)
    except (TypeError, ValueError):
        raise TypeError(f"xyz must be an (N, 3) array of numbers, got {type(xyz).__name__}") from None
    if xyz.ndim != 2 or xyz.shape[1] != 3:
        raise CloudWriteError(f"{path}: points must have shape (N, 3), got {xyz.shape}")
    if not isinstance(fields, dict):
        raise TypeError(f"fields must be a dict of name -> per-point array, got {type(fields).__name__}")
    # A Quantised column (LAS: scaled integers, m3c2kit.io.quantised) is checked through its values.
    fields = {str(name): values if isinstance(values, Quantised) else np.asarray(values)
              for name, values in fields.items()}
    for name, values in fields.items():
        shape = np.shape(values.values) if isinstance(values, Quantised) else values.shape
        if shape != (len(xyz),):
            raise CloudWriteError(f"{path}: field {name!r} has shape {shape}, expected ({len(xyz)},)")
    fmt = writable_format(path)
    if not fmt.quantises:  # only LAS declares a scale and no_data: elsewhere the values themselves
        fields = {k: v.values.astype(np.float32) if isinstance(v, Quantised) else v for k, v in fields.items()}
    fmt.write(Path(path), xyz, fields, like)
