"""Which module reads and writes which file extension, and what a file's first bytes say it is."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from . import ascii, e57, las, npy, ply

__all__ = ["Format", "FORMATS", "SUPPORTED_READ", "SUPPORTED_WRITE", "format_for", "quantises", "keeps_crs", "sniff"]


@dataclass(frozen=True)
class Format:
    """One file format: its reader, its writer (None if read-only), whether the reader takes
    ``columns=(i, j, k)``, and whether the format `quantises`: stores coordinates and measured
    columns as scaled integers (LAS: m3c2kit.io.quantised), keeps only the compact columns unless
    --all-fields and takes column names with spaces (m3c2kit.io.fields.typed_columns)."""

    name: str
    extensions: tuple[str, ...]
    read: Callable
    write: Callable | None = None
    takes_columns: bool = False
    quantises: bool = False
    keeps_crs: bool = False  # the writer stores a CRS (LAS: WKT or GeoTIFF keys)


FORMATS: tuple[Format, ...] = (
    Format("LAS/LAZ", (".las", ".laz", ".copc.laz"), las.read, las.write, quantises=True, keeps_crs=True),
    Format("E57", (".e57",), e57.read),
    Format("PLY", (".ply",), ply.read, ply.write),
    Format("ASCII", ascii.EXTENSIONS, ascii.read, ascii.write, takes_columns=True),
    Format("NPY", (".npy",), npy.read),
)

SUPPORTED_READ: tuple[str, ...] = tuple(ext for f in FORMATS for ext in f.extensions)
# Text output is always delimited columns with a header; .pts (count line) and .neu are read-only.
SUPPORTED_WRITE: tuple[str, ...] = (".las", ".laz", ".ply", ".csv", ".txt", ".xyz", ".asc")


def extension_of(path: Path) -> str:
    """The registered extension `path` ends with, longest first (``.copc.laz`` before ``.laz``),
    lower-cased; else its last suffix."""
    name = path.name.lower()
    for ext in sorted(SUPPORTED_READ, key=len, reverse=True):
        if name.endswith(ext):
            return ext
    return path.suffix.lower()


def format_for(path: Path, *, writing: bool = False) -> Format | None:
    """The format registered for `path`'s extension, or None."""
    ext = extension_of(path)
    if writing and ext not in SUPPORTED_WRITE:
        return None
    for f in FORMATS:
        if ext in f.extensions:
            return f
    return None


def keeps_crs(path) -> bool:
    """Whether the output file `path` is written in a format that stores a CRS."""
    fmt = format_for(Path(path), writing=True)
    return fmt is not None and fmt.keeps_crs


def quantises(path) -> bool:
    """Whether the output file `path` is written in a format that quantises (Format.quantises):
    the one place that decides how a table's columns are stored for it."""
    fmt = format_for(Path(path), writing=True)
    return fmt is not None and fmt.quantises


_MAGIC = ((b"LASF", "LAS/LAZ"), (b"ASTM-E57", "E57"), (b"\x93NUMPY", "NPY"), (b"ply\n", "PLY"),
          (b"ply\r\n", "PLY"), (b"ply \n", "PLY"), (b"ply \r\n", "PLY"))


def sniff(head: bytes) -> str | None:
    """The format a file's first bytes identify, or None (text, or unknown binary)."""
    for magic, name in _MAGIC:
        if head.startswith(magic):
            return name
    return None
