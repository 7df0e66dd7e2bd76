"""PLY point clouds: a numpy reader for ascii / binary_little_endian / binary_big_endian, and a
binary_little_endian writer.

Reading keeps the ``vertex`` element: x, y, z (any numeric type) become float64 coordinates,
every other scalar vertex property becomes a field of its declared type. Other elements (faces,
edges, ...) are skipped, including list properties of elements stored before the vertices.
List properties inside the vertex element are not supported and say so.

ASCII bodies are read one element instance per line, which is what every known writer does.
"""
from __future__ import annotations

import io
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..base.errors import CloudReadError, CloudWriteError
from .atomic import atomic_output
from .cloud import Cloud
from .guard import read_errors, write_errors

__all__ = ["read", "write"]

_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}
_ENCODINGS = {"ascii": None, "binary_little_endian": "<", "binary_big_endian": ">"}
_MAX_HEADER = 1 << 20  # a PLY header is a few hundred bytes; refuse to scan a binary blob forever


@dataclass
class _Property:
    name: str
    type: str  # numpy type code without byte order, e.g. "f4"
    list_types: tuple[str, str] | None = None  # (count type, item type) of a list property


@dataclass
class _Element:
    name: str
    count: int
    properties: list[_Property] = field(default_factory=list)


def _fail(path, problem: str) -> CloudReadError:
    return CloudReadError(f"{path}: {problem}")


def _ply_type(path, name: str) -> str:
    try:
        return _TYPES[name]
    except KeyError:
        raise _fail(path, f"unknown PLY property type {name!r}") from None


def _parse_header(path, f) -> tuple[str, list[_Element], int]:
    """(encoding, elements, byte offset of the body)."""
    if f.readline(16).rstrip() != b"ply":
        raise _fail(path, "not a PLY file (first line is not 'ply')")
    encoding = None
    elements: list[_Element] = []
    while True:
        raw = f.readline(4096)
        if not raw:
            raise _fail(path, "truncated PLY header (no 'end_header')")
        if f.tell() > _MAX_HEADER:
            raise _fail(path, "PLY header longer than 1 MiB; not a PLY file?")
        words = raw.decode("ascii", "replace").split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        key = words[0]
        if key == "end_header":
            break
        if key == "format" and len(words) >= 2:
            if words[1] not in _ENCODINGS:
                raise _fail(path, f"unsupported PLY format {words[1]!r}")
            encoding = words[1]
        elif key == "element" and len(words) == 3 and re.fullmatch(r"\d+", words[2]):
            elements.append(_Element(words[1], int(words[2])))
        elif key == "property" and elements and len(words) == 3:
            elements[-1].properties.append(_Property(words[2], _ply_type(path, words[1])))
        elif key == "property" and elements and len(words) == 5 and words[1] == "list":
            elements[-1].properties.append(
                _Property(words[4], "", (_ply_type(path, words[2]), _ply_type(path, words[3]))))
        else:
            raise _fail(path, f"malformed PLY header line {' '.join(words)!r}")
    if encoding is None:
        raise _fail(path, "PLY header has no 'format' line")
    return encoding, elements, f.tell()


def read(path: Path) -> Cloud:
    """Reads the vertex element of a PLY file (see the module docstring)."""
    with read_errors(path), open(path, "rb") as f:
        encoding, elements, body = _parse_header(path, f)
        names = [e.name for e in elements]
        if "vertex" not in names:
            raise _fail(path, "PLY file has no 'vertex' element")
        vertex = elements[names.index("vertex")]
        props = [p.name for p in vertex.properties]
        for axis in "xyz":
            if axis not in props:
                raise _fail(path, f"PLY vertex element has no '{axis}' property (properties: {', '.join(props)})")
        if any(p.list_types for p in vertex.properties):
            raise _fail(path, "list properties in the PLY vertex element are not supported")
        if len(set(props)) != len(props):
            raise _fail(path, "duplicate property names in the PLY vertex element")
        before = elements[: names.index("vertex")]
        if encoding == "ascii":
            table = _read_ascii(path, f, before, vertex)
        else:
            table = _read_binary(path, f, _ENCODINGS[encoding], before, vertex)
    xyz = np.empty((vertex.count, 3))
    for k, axis in enumerate("xyz"):
        xyz[:, k] = table[axis]
    fields = {p.name: np.ascontiguousarray(table[p.name]).astype(p.type)
              for p in vertex.properties if p.name not in ("x", "y", "z")}
    return Cloud(xyz, fields, path=Path(path), format="PLY", meta={"encoding": encoding})


def _read_ascii(path, f, before: list[_Element], vertex: _Element) -> dict[str, np.ndarray]:
    text = io.TextIOWrapper(f, encoding="ascii", errors="replace")
    for element in before:
        for _ in range(element.count):
            if not text.readline():
                raise _fail(path, f"truncated: PLY file ends inside element {element.name!r}")
    n_props = len(vertex.properties)
    values = np.loadtxt(text, dtype=np.float64, ndmin=2, max_rows=vertex.count) if vertex.count else None
    if values is None or values.size == 0:
        values = np.empty((0, n_props))
    if len(values) < vertex.count:
        raise _fail(path, f"truncated: PLY header declares {vertex.count} vertices, the file has {len(values)}")
    if values.shape[1] != n_props:
        raise _fail(path, f"PLY vertex lines have {values.shape[1]} values, the header declares {n_props} properties")
    return {p.name: values[:, k] for k, p in enumerate(vertex.properties)}


def _skip_binary(path, f, order: str, element: _Element) -> None:
    if not any(p.list_types for p in element.properties):
        f.seek(element.count * sum(np.dtype(p.type).itemsize for p in element.properties), 1)
        return
    # Variable-length rows: walk them (elements stored before the vertices are rare and small).
    for _ in range(element.count):
        for p in element.properties:
            if p.list_types is None:
                f.seek(np.dtype(p.type).itemsize, 1)
                continue
            count_type = np.dtype(order + p.list_types[0])
            raw = f.read(count_type.itemsize)
            if len(raw) != count_type.itemsize:
                raise _fail(path, f"truncated: PLY file ends inside element {element.name!r}")
            f.seek(int(np.frombuffer(raw, count_type)[0]) * np.dtype(p.list_types[1]).itemsize, 1)


def _read_binary(path, f, order: str, before: list[_Element], vertex: _Element) -> np.ndarray:
    for element in before:
        _skip_binary(path, f, order, element)
    dtype = np.dtype([(p.name, order + p.type) for p in vertex.properties])
    data = f.read(dtype.itemsize * vertex.count)
    if len(data) < dtype.itemsize * vertex.count:
        raise _fail(path, f"truncated: PLY header declares {vertex.count} vertices, the file holds "
                          f"{len(data) // dtype.itemsize}")
    return np.frombuffer(data, dtype=dtype, count=vertex.count)


# ----------------------------------------------------------------------------------------- write

_WRITE_TYPES = {"i1": "char", "u1": "uchar", "i2": "short", "u2": "ushort", "i4": "int", "u4": "uint",
                "f4": "float", "f8": "double"}


def _column_type(path, name: str, values: np.ndarray) -> tuple[np.ndarray, str]:
    """Values in a type PLY has (bool -> uchar; 64-bit integers -> int/uint if they fit, else
    double if exact) and that type's PLY name."""
    if values.dtype == np.bool_:
        values = values.astype(np.uint8)
    code = values.dtype.str[1:]
    if code in _WRITE_TYPES:
        return values, _WRITE_TYPES[code]
    if values.dtype.kind in "iu":
        for target in ("i4", "u4", "f8"):
            cast = values.astype(target)
            if np.array_equal(cast.astype(values.dtype), values):
                return cast, _WRITE_TYPES[target]
    if values.dtype.kind == "f":  # float16 / longdouble
        return values.astype("f8"), "double"
    raise CloudWriteError(f"{path}: field {name!r} has type {values.dtype}, which PLY cannot store")


def write(path: Path, xyz: np.ndarray, fields: dict[str, np.ndarray], like: Cloud | None = None) -> None:
    """Writes binary_little_endian PLY: x, y, z as double, then one property per field in its
    own type (see :func:`_column_type`). `like` is accepted for symmetry and unused: PLY has no CRS."""
    columns: list[tuple[str, np.ndarray, str]] = []
    for name, values in fields.items():
        if not name or any(c.isspace() for c in name) or not name.isascii():
            raise CloudWriteError(f"{path}: PLY property names must be ASCII without spaces, got {name!r}")
        if name in ("x", "y", "z"):
            raise CloudWriteError(f"{path}: field name {name!r} is reserved for coordinates")
        values, ply_type = _column_type(path, name, np.asarray(values))
        columns.append((name, values, ply_type))
    header = ["ply", "format binary_little_endian 1.0", "comment written by m3c2",
              f"element vertex {len(xyz)}", "property double x", "property double y", "property double z"]
    header += [f"property {ply_type} {name}" for name, _, ply_type in columns]
    header.append("end_header")
    dtype = np.dtype([("x", "<f8"), ("y", "<f8"), ("z", "<f8")]
                     + [(name, "<" + values.dtype.str[1:]) for name, values, _ in columns])
    table = np.empty(len(xyz), dtype=dtype)
    table["x"], table["y"], table["z"] = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    for name, values, _ in columns:
        table[name] = values
    with write_errors(path), atomic_output(path) as tmp, open(tmp, "wb") as out:
        out.write(("\n".join(header) + "\n").encode("ascii"))
        out.write(table.view(np.uint8).data)  # not tofile(): its short write raises an OSError without errno
