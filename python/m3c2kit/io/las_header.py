"""Sanity checks on a LAS/LAZ file's raw header, run before laspy sees the file.

They exist because laspy trusts the header: a garbage VLR count makes it loop (practically)
forever, a truncated uncompressed file silently yields fewer points, and lazrs panics on
LASzip's old point-wise compressor. Each check turns such a file into one clear message.
"""
from __future__ import annotations

import os
import struct
from dataclasses import dataclass

__all__ = ["LasLayout", "check_las_file"]

_MIN_HEADER = 227  # LAS 1.0-1.2 header size; later versions only append fields
_VLR_HEADER = 54
_EVLR_HEADER = 60
_LASZIP_USER = b"laszip encoded"
_LASZIP_RECORD = 22204
_COPC_USER = b"copc"
# LASzip compressor ids: 0 none, 1 point-wise, 2 point-wise chunked, 3 layered chunked.
_CHUNKED = (2, 3)


@dataclass(frozen=True)
class LasLayout:
    """What the raw header says, after the checks passed."""

    version: str
    point_format: int
    point_count: int
    compressed: bool
    copc: bool
    record_length: int = 0  # bytes per point record (uncompressed)


def _read_exact(f, size: int) -> bytes:
    data = f.read(size)
    if len(data) != size:
        raise ValueError("truncated header")
    return data


def check_las_file(path: os.PathLike | str) -> LasLayout:
    """Checks the header and the VLR directory of a LAS/LAZ file; raises ValueError with a
    description of the first problem (the caller prefixes the path)."""
    size = os.path.getsize(path)
    with open(path, "rb") as f:
        head = f.read(375)
        if head[:4] != b"LASF":
            raise ValueError("not a LAS/LAZ file (no 'LASF' signature)")
        if len(head) < _MIN_HEADER:
            raise ValueError(f"truncated LAS header ({len(head)} bytes, at least {_MIN_HEADER} needed)")
        major, minor = head[24], head[25]
        header_size, = struct.unpack_from("<H", head, 94)
        offset, n_vlrs = struct.unpack_from("<II", head, 96)
        format_byte, record_length = struct.unpack_from("<BH", head, 104)
        legacy_count, = struct.unpack_from("<I", head, 107)
        if major != 1 or minor > 4:
            raise ValueError(f"unsupported LAS version {major}.{minor}")
        if not _MIN_HEADER <= header_size <= min(size, offset):
            raise ValueError(f"malformed LAS header: header size {header_size}, point data offset "
                             f"{offset}, file size {size}")
        if offset > size:
            raise ValueError(f"truncated: point data should start at byte {offset} but the file "
                             f"has {size} bytes")
        count = legacy_count
        if minor >= 4 and header_size >= 255 and len(head) >= 255:
            count64, = struct.unpack_from("<Q", head, 247)
            count = count64 or legacy_count
        compressed = bool(format_byte & 0x80)
        point_format = format_byte & 0x3F

        f.seek(header_size)
        vlr_bytes = offset - header_size
        if n_vlrs * _VLR_HEADER > vlr_bytes:
            raise ValueError(f"malformed LAS header: it declares {n_vlrs} VLRs but only {vlr_bytes} "
                             f"bytes lie between the header and the point data")
        laszip = None
        copc = False
        pos = header_size
        for i in range(n_vlrs):
            if pos + _VLR_HEADER > offset:
                raise ValueError(f"malformed LAS header: it declares {n_vlrs} VLRs but only {i} fit "
                                 f"before the point data (byte {offset})")
            f.seek(pos)
            vlr = _read_exact(f, _VLR_HEADER)
            user = vlr[2:18].rstrip(b"\0")
            record_id, length = struct.unpack_from("<HH", vlr, 18)
            if user == _LASZIP_USER and record_id == _LASZIP_RECORD:
                laszip = f.read(min(length, 34))
            elif user == _COPC_USER and record_id == 1:
                copc = True
            pos += _VLR_HEADER + length
        if pos > offset:
            raise ValueError(f"malformed LAS header: its VLRs run past the point data offset ({offset})")
        if minor >= 4 and header_size >= 247 and len(head) >= 247:
            _check_evlrs(f, size, *struct.unpack_from("<QI", head, 235))

    if compressed:
        _check_laszip(laszip)
    elif count and record_length:
        available = (size - offset) // record_length
        if available < count:
            raise ValueError(f"truncated: the header declares {count} points but the file holds "
                             f"only {available}")
    return LasLayout(f"{major}.{minor}", point_format, count, compressed, copc, record_length)


def _check_evlrs(f, size: int, start: int, count: int) -> None:
    # laspy ignores a cut-off EVLR section, but a file that lost its tail is a damaged copy.
    pos = start
    for i in range(count):
        if pos + _EVLR_HEADER > size:
            raise ValueError(f"truncated: the header declares {count} extended VLRs, the file ends "
                             f"inside number {i + 1}")
        f.seek(pos + 20)
        length, = struct.unpack("<Q", _read_exact(f, 8))
        pos += _EVLR_HEADER + length
    if count and pos > size:
        raise ValueError(f"truncated: the file ends inside its extended VLRs ({size} of {pos} bytes)")


def _check_laszip(record: bytes | None) -> None:
    if record is None or len(record) < 4:
        raise ValueError("compressed LAZ data without a valid LASzip VLR")
    compressor, coder = struct.unpack_from("<HH", record, 0)
    if coder != 0:
        raise ValueError(f"corrupt LAZ: unknown LASzip coder {coder}")
    if compressor == 1:
        raise ValueError("LAZ written with LASzip's point-wise (non-chunked) compressor, which is "
                         "not supported; re-compress it (e.g. `laszip` or `pdal translate`)")
    if compressor not in _CHUNKED:
        raise ValueError(f"corrupt LAZ: unknown LASzip compressor type {compressor}")
