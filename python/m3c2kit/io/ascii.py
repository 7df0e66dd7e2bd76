"""Delimited text point clouds (.xyz .txt .csv .asc .pts .neu): reading and writing.

Reading looks at the first lines to find the layout, then loads the body with one
``np.loadtxt`` call (about 0.2 s per 100k lines of 8 columns):

* the first *data line* is the first line with at least three numeric values; blank lines
  and ``#`` comments are skipped everywhere, ``//`` comments too unless the data lines hold
  double-quoted values;
* its delimiter is the first of ``;``, tab, ``,`` it contains, else runs of whitespace;
* the last non-blank line before it is the *header* if none of its names is a number (a
  leading ``//`` or ``#`` is dropped, names may be quoted, and the header may use another
  delimiter than the data); a lone number there (the point count of .pts files) is skipped;
* x, y, z are the columns named X, Y, Z (any case) by the header, else the first three numeric
  columns, or ``columns=(i, j, k)`` (0-based) when given;
* every other numeric column becomes a float64 field, named by the header or ``col<j>``
  (0-based); columns that are not numbers in the first data lines are ignored.

Writing: a header line of names, then one line per point, comma-separated for .csv and
space-separated otherwise; numbers use Python's shortest round-trip repr, so float64 values
read back bit-identical.
"""
from __future__ import annotations

import csv
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..base.errors import CloudReadError, CloudWriteError, UsageError
from .atomic import atomic_output
from .cloud import Cloud
from .guard import read_errors, write_errors

__all__ = ["read", "write", "EXTENSIONS"]

EXTENSIONS = (".xyz", ".txt", ".csv", ".asc", ".pts", ".neu")
_SAMPLE_BYTES = 1 << 20  # layout detection looks at most at the first MiB ...
_SAMPLE_DATA_LINES = 200  # ... and at most at this many data lines
_COMMENTS = ("#", "//")
_QUOTES = "\"'"


@dataclass
class _Layout:
    delimiter: str | None  # None: runs of whitespace
    skip: int  # lines before the first data line
    names: list[str]  # header names ([] without a header)
    numeric: list[int]  # indices of the columns that hold numbers
    n_columns: int
    quoted: bool  # the data lines contain double quotes


def _is_number(token: str) -> bool:
    try:
        float(token)
    except ValueError:
        return False
    return True


def _delimiter_of(line: str) -> str | None:
    for d in (";", "\t", ","):
        if d in line:
            return d
    return None


def _split(line: str, delimiter: str | None) -> list[str]:
    tokens = line.split(delimiter) if delimiter else line.split()
    return [t.strip().strip(_QUOTES).strip() for t in tokens]


def _strip_comment_marker(line: str) -> str | None:
    for marker in _COMMENTS:
        if line.startswith(marker):
            return line[len(marker):].strip()
    return None


def _header_names(line: str) -> list[str] | None:
    """Column names if `line` is a header (no name is a number), else None."""
    body = _strip_comment_marker(line)
    body = line if body is None else body
    delimiter = _delimiter_of(body)
    if delimiter is None:
        names = body.split()
    else:
        names = [n.strip() for n in next(csv.reader([body], delimiter=delimiter, skipinitialspace=True))]
    names = [n.strip(_QUOTES).strip() for n in names]
    while names and not names[-1]:  # a trailing delimiter is not an extra column
        names.pop()
    if not names or any(_is_number(n) for n in names if n):
        return None
    return names


def _detect_layout(path: Path) -> _Layout:
    with open(path, "rb") as f:
        sample = f.read(_SAMPLE_BYTES)
    if b"\0" in sample:
        raise CloudReadError(f"{path}: binary content; not a text point cloud")
    # Split exactly where np.loadtxt's text-mode file will (universal newlines), so that the
    # line index of the first data line is its skiprows; str.splitlines() also splits on \f etc.
    lines = re.split(r"\r\n|\r|\n", sample.decode("utf-8-sig", "replace"))
    if len(sample) == _SAMPLE_BYTES or lines[-1] == "":
        lines.pop()  # possibly cut in the middle, or the empty rest after the final newline
    first = previous = None
    data: list[list[str]] = []
    at: list[int] = []  # line index of each data row
    delimiter = None
    quoted = False
    for i, raw in enumerate(lines):
        line = raw.strip()
        if not line:
            continue
        if first is None:
            d = _delimiter_of(line)
            tokens = _split(line, d)
            if sum(map(_is_number, tokens)) >= 3 and not line.startswith(_COMMENTS):
                first, delimiter = i, d
            else:
                previous = line
                continue
        if line.startswith(_COMMENTS):
            continue
        quoted = quoted or '"' in line
        data.append(_split(line, delimiter))
        at.append(i)
        if len(data) >= _SAMPLE_DATA_LINES:
            break
    if first is None:
        hint = "not a text point cloud?"
        if any(";" in line and re.search(r"\d,\d", line) for line in lines[:50]):
            hint = "decimal commas are not supported; use '.' as the decimal separator"
        raise CloudReadError(f"{path}: no line with three numbers (x y z) in its first "
                             f"{len(lines)} lines; {hint}")
    width = min(len(t) for t in data)  # ragged extra columns in a few lines are ignored
    if width < 3:  # e.g. a file cut in the middle of its last line
        k = min(range(len(data)), key=lambda j: len(data[j]))
        raise CloudReadError(f"{path}: line {at[k] + 1} has only {width} value{'s' * (width != 1)}, fewer than "
                             f"x, y, z (truncated file?)")
    numeric = [j for j in range(width) if all(_is_number(row[j]) for row in data)]
    names = _header_names(previous) if previous is not None else None
    return _Layout(delimiter, first, names or [], numeric, width, quoted)


def _xyz_columns(path, layout: _Layout, columns) -> tuple[int, int, int]:
    if columns is not None:
        try:
            cols = tuple(int(c) for c in columns)
        except (TypeError, ValueError):
            raise UsageError(f"columns must be three column indices, got {columns!r}") from None
        if len(cols) != 3 or len(set(cols)) != 3 or min(cols) < 0:
            raise UsageError(f"columns must be three distinct 0-based column indices, got {columns!r}")
        for c in cols:
            if c not in layout.numeric:
                raise UsageError(f"{path}: column {c} is not a numeric column (numeric columns: "
                                 f"{', '.join(map(str, layout.numeric))})")
        return cols  # type: ignore[return-value]
    lowered = [n.lower() for n in layout.names]
    found = {axis: [j for j, n in enumerate(lowered) if n == axis] for axis in "xyz"}
    if any(found.values()):
        if all(len(found[a]) == 1 for a in "xyz"):
            cols = tuple(found[a][0] for a in "xyz")
            missing = [c for c in cols if c not in layout.numeric]
            if not missing:
                return cols  # type: ignore[return-value]
            raise CloudReadError(f"{path}: header column {missing[0]} ({layout.names[missing[0]]!r}) "
                                 f"does not hold numbers")
        described = ", ".join(f"{a.upper()}: {len(found[a])}" for a in "xyz")
        raise CloudReadError(f"{path}: the header names X, Y, Z ambiguously ({described} columns); "
                             f"pass columns=(i, j, k) to choose")
    if len(layout.numeric) < 3:
        raise CloudReadError(f"{path}: fewer than three numeric columns")
    return tuple(layout.numeric[:3])  # type: ignore[return-value]


def _field_names(layout: _Layout, used: list[int]) -> list[str]:
    names = []
    for j in used:
        name = layout.names[j] if j < len(layout.names) and layout.names[j] else f"col{j}"
        names.append(name if name not in names else f"{name}_{j}")
    return names


def read(path: Path, columns: tuple[int, int, int] | None = None) -> Cloud:
    """Reads a delimited text cloud; see the module docstring for the layout rules."""
    with read_errors(path):
        layout = _detect_layout(path)
        xyz_cols = _xyz_columns(path, layout, columns)
        others = [j for j in layout.numeric if j not in xyz_cols]
        usecols = list(xyz_cols) + others
        # np.loadtxt takes either several comment markers or a quote character, not both.
        quoting = {"comments": "#", "quotechar": '"'} if layout.quoted else {"comments": list(_COMMENTS)}
        with open(path, encoding="utf-8-sig", errors="replace") as f:
            table = np.loadtxt(f, dtype=np.float64, delimiter=layout.delimiter, skiprows=layout.skip,
                               usecols=usecols, ndmin=2, **quoting)
    xyz = np.ascontiguousarray(table[:, :3])
    names = _field_names(layout, others)
    fields = {name: np.ascontiguousarray(table[:, 3 + k]) for k, name in enumerate(names)}
    delimiter = {None: "whitespace", "\t": "tab"}.get(layout.delimiter, layout.delimiter)
    return Cloud(xyz, fields, path=Path(path), format="ASCII",
                 meta={"delimiter": delimiter, "header": bool(layout.names), "columns": list(xyz_cols)})


# ----------------------------------------------------------------------------------------- write

_CHUNK = 65536


def _text_column(values: np.ndarray) -> list[str]:
    values = np.asarray(values)
    if values.dtype == np.bool_:
        values = values.astype(np.uint8)
    # tolist() gives Python ints/floats (float32 widened exactly); repr is the shortest text
    # that reads back to the same double.
    return list(map(repr, values.tolist()))


def write(path: Path, xyz: np.ndarray, fields: dict[str, np.ndarray], like: Cloud | None = None) -> None:
    """Writes a header line ``x<sep>y<sep>z<sep><field names>`` and one line per point, losslessly
    (see the module docstring). `like` is accepted for symmetry and unused: text has no CRS."""
    sep = "," if Path(path).suffix.lower() == ".csv" else " "
    names = ["x", "y", "z", *fields]
    for name in fields:
        if not name or sep in name or any(c.isspace() or c in "\"'" for c in name):
            raise CloudWriteError(f"{path}: field name {name!r} cannot be written as a text column name")
        if name.lower() in ("x", "y", "z"):
            raise CloudWriteError(f"{path}: field name {name!r} is reserved for coordinates")
    columns = [xyz[:, 0], xyz[:, 1], xyz[:, 2], *(np.asarray(v) for v in fields.values())]
    for name, values in zip(names, columns):
        if np.asarray(values).dtype.kind not in "biuf":
            raise CloudWriteError(f"{path}: field {name!r} has type {values.dtype}, not a number")
    with write_errors(path), atomic_output(path) as tmp, open(tmp, "w", encoding="ascii", newline="\n") as out:
        out.write(sep.join(names) + "\n")
        for start in range(0, len(xyz), _CHUNK):
            text = [_text_column(c[start:start + _CHUNK]) for c in columns]
            out.write("\n".join(map(sep.join, zip(*text))))
            out.write("\n")
