"""The epochs of a series as the user names them (files, globs or a list file with timestamps)
and each epoch's acquisition time: the list file's, else the file's metadata (LAS GPS time or
creation date, E57 acquisition start), else none (the epoch's order then orders it)."""
from __future__ import annotations

import datetime as dt
import glob
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..base.errors import UsageError
from ..io.input_file import check_input_file, read_small_text
from ..base.optional import require

#: GPS time 0 (1980-01-06 UTC); LAS "adjusted standard GPS time" is GPS seconds - 1e9.
GPS_EPOCH = dt.datetime(1980, 1, 6)
ADJUSTED_GPS_OFFSET = 1e9
#: GPS time runs ahead of UTC by the leap seconds since 1980 (18 s since 2017-01-01).
GPS_UTC_LEAP_SECONDS = 18


#: The kind of small input a list file of epochs is (io.input_file.SMALL_FILE_LIMITS).
LIST_FILE = "epoch list file"


@dataclass(frozen=True)
class Epoch:
    path: Path
    time: np.datetime64 | None = None  # UTC, microseconds; None: unknown
    time_source: str = "order"          # list | las-gps-time | las-creation-date | e57 | order


def parse_time(text: str, where: str) -> np.datetime64:
    """An ISO 8601 time (UTC unless it says otherwise) as datetime64[us]; a UsageError naming `where`.
    The one reader of a time a user or a store gives (epoch lists, reference_time, --reference-time)."""
    try:
        value = dt.datetime.fromisoformat(text.strip().replace("Z", "+00:00"))
    except ValueError:
        raise UsageError(f"{where}: {text!r} is not an ISO 8601 time (e.g. 2024-05-01T12:00:00)") from None
    if value.tzinfo is not None:
        value = value.astimezone(dt.timezone.utc).replace(tzinfo=None)
    return np.datetime64(value, "us")


def microseconds(text: str, where: str) -> int:
    """parse_time() as microseconds since 1970-01-01 (the store's time unit)."""
    return int(parse_time(text, where).astype(np.int64))


def _list_text(path: Path) -> str:
    """A list file's text, read safely (a regular file, bounded: io.input_file)."""
    return read_small_text(path, LIST_FILE, label=f"the epoch list {path}")


def _is_list_file(path: Path) -> bool:
    """A text file whose entry lines start with a path, not a number (an ASCII point cloud's lines
    start with x). Whether the files exist is read_list_file's to say: a list naming one missing
    file was read as a point cloud, with a message about x y z columns (issue 42)."""
    if path.suffix.lower() not in (".txt", ".csv", ".list", ".lst", ".tsv") or not path.is_file():
        return False
    try:
        lines = [l for l in _list_text(path).splitlines() if l.strip() and not l.lstrip().startswith("#")]
    except UsageError:  # not text, or too large for a list: then it is an epoch file, read as one
        return False
    return bool(lines) and all(not _is_number(_split(l)[0]) for l in lines[:50])


def _is_number(text: str) -> bool:
    try:
        float(text.split()[0] if text.split() else text)
    except ValueError:
        return False
    return True


def _split(line: str) -> list[str]:
    parts = [p.strip() for p in (line.split(",") if "," in line else line.split(None, 1))]
    return [p for p in parts if p]


def read_list_file(path: Path) -> list[Epoch]:
    out = []
    for number, line in enumerate(_list_text(path).splitlines(), 1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        parts = _split(line)
        file = path.parent / parts[0]
        if not (file.exists() or file.is_symlink()):
            raise UsageError(f"{path}:{number}: the epoch {parts[0]} does not exist ({file})")
        check_input_file(file, label=f"{path}:{number}: the epoch {parts[0]}")  # a FIFO or folder: never read
        time = parse_time(parts[1], f"{path}:{number}") if len(parts) > 1 else None
        out.append(Epoch(file, time, "list") if time is not None else metadata_epoch(file))
    return out


def resolve(arguments) -> list[Epoch]:
    """The epochs named by `arguments`, in the order given (a glob expands sorted)."""
    out: list[Epoch] = []
    for arg in arguments:
        path = Path(arg)
        if not path.exists() and any(c in str(arg) for c in "*?["):
            matches = sorted(glob.glob(str(arg)))
            if not matches:
                raise UsageError(f"the epoch pattern {arg!r} matches no file")
            out += [metadata_epoch(Path(m)) for m in matches]
        elif _is_list_file(path):
            out += read_list_file(path)
        elif not (path.exists() or path.is_symlink()):
            raise UsageError(f"the epoch {arg} does not exist")
        else:
            check_input_file(path, label=f"the epoch {arg}")  # a FIFO, device or folder: refused, never read
            out.append(metadata_epoch(path))
    if not out:
        raise UsageError("no epoch given")
    return out


def metadata_epoch(path: Path) -> Epoch:
    suffix = "".join(path.suffixes[-2:]).lower() if path.suffix.lower() == ".laz" else path.suffix.lower()
    try:
        if suffix in (".las", ".laz", ".copc.laz"):
            found = _las_time(path)
        elif suffix == ".e57":
            found = _e57_time(path)
        else:
            found = None
    except Exception:  # an unreadable header is reported by the reader, with its own message
        found = None
    return Epoch(path, *found) if found else Epoch(path)


def _las_time(path: Path):
    import laspy
    with laspy.open(path) as reader:
        header = reader.header
        adjusted = bool(int(header.global_encoding.value) & 1)
        if adjusted and "gps_time" in header.point_format.dimension_names and header.point_count:
            first = next(reader.chunk_iterator(min(header.point_count, 100_000)))
            gps = float(np.min(first.gps_time)) + ADJUSTED_GPS_OFFSET
            when = GPS_EPOCH + dt.timedelta(seconds=gps - GPS_UTC_LEAP_SECONDS)
            return np.datetime64(when, "us"), "las-gps-time"
        if header.creation_date is not None:
            return np.datetime64(dt.datetime.combine(header.creation_date, dt.time()), "us"), "las-creation-date"
    return None


def _e57_time(path: Path):
    pye57 = require("pye57", extra="e57", purpose="reading .e57 files")
    e57 = pye57.E57(str(path))
    try:
        scan = e57.root["data3D"][0]
        if scan.isDefined("acquisitionStart"):
            gps = float(scan["acquisitionStart"]["dateTimeValue"].value())
            return np.datetime64(GPS_EPOCH + dt.timedelta(seconds=gps - GPS_UTC_LEAP_SECONDS), "us"), "e57"
    finally:
        e57.close()
    return None
