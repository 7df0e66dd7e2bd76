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
        if point_format > _LAST_POINT_FORMAT:
            raise ValueError(f"unknown LAS point format {point_format} (header byte {format_byte}; LAS 1.4 defines 0 "
                             f"to {_LAST_POINT_FORMAT}): a damaged header or not a LAS file")
        _check_scales(struct.unpack_from("<3d", head, 131))

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

        data_end = _point_data_end(head, minor, header_size, offset, size)
        if compressed:
            _check_laszip(laszip)
            _check_laz_point_count(f, count, offset, data_end, laszip)
    if not compressed and record_length:
        _check_las_point_count(count, offset, data_end, record_length)
    return LasLayout(f"{major}.{minor}", point_format, count, compressed, copc, record_length)


#: LAS 1.4 R15, Table 7: point data record formats 0 to 10.
_LAST_POINT_FORMAT = 10


def _check_scales(scales) -> None:
    """Each axis's scale factor must be finite and non-zero: a z scale of 0 read every z as the
    offset, without a word (issue 42)."""
    for axis, scale in zip("xyz", scales):
        if not (abs(scale) > 0.0 and abs(scale) < float("inf")):
            raise ValueError(f"malformed LAS header: its {axis} scale factor is {scale!r}: every {axis} would read "
                             f"as the offset")


def _point_data_end(head: bytes, minor: int, header_size: int, offset: int, size: int) -> int:
    """Where the point records end: at the internal waveform data (LAS 1.3+, global encoding
    bit 1) or the first extended VLR (1.4) when they follow the points, else at the file's end."""
    end = size
    encoding, = struct.unpack_from("<H", head, 6)
    if minor >= 3 and header_size >= 235 and len(head) >= 235 and encoding & 0b10:
        waveform, = struct.unpack_from("<Q", head, 227)
        if offset <= waveform < end:
            end = waveform
    if minor >= 4 and header_size >= 247 and len(head) >= 247:
        evlr_start, evlr_count = struct.unpack_from("<QI", head, 235)
        if evlr_count and offset <= evlr_start < end:
            end = evlr_start
    return end


def _check_las_point_count(count: int, offset: int, end: int, record_length: int) -> None:
    """Uncompressed points are `record_length` bytes each from `offset` to `end`: fewer records
    than the header's count is a truncated file, more a header that hides points (laspy reads
    only the counted ones: points lost without a word)."""
    available = (end - offset) // record_length
    if available < count:
        raise ValueError(f"truncated: the header declares {count} points but the file holds "
                         f"only {available}")
    if available > count:
        raise ValueError(f"the header declares {count} points but the file holds {available} point "
                         f"records of {record_length} bytes (bytes {offset} to {end}): the header's point "
                         f"count is wrong and {available - count} points would be lost; rewrite the file "
                         f"with a correct header (e.g. `pdal translate` or `lasinfo -repair`)")


def _check_laz_point_count(f, count: int, offset: int, end: int, laszip: bytes) -> None:
    """LASzip's chunk table (LAZ spec: an int64 at the point data start, -1 when written at the
    file's end, points to `version u32, number of chunks u32, ...`) bounds the points of a file
    with fixed-size chunks: (chunks - 1) * chunk size < points <= chunks * chunk size. A header
    outside the bounds is refused before any decompression: a LAZ claiming 10^8 points in 545 KB
    took 7.9 s and 2.7 GB to fail in lazrs; one counting fewer points would lose the rest."""
    chunk_size, = struct.unpack_from("<I", laszip, 12) if len(laszip) >= 16 else (0,)
    if chunk_size in (0, 0xFFFFFFFF):
        return  # variable-size chunks (COPC): the counts are inside the compressed table
    f.seek(offset)
    raw = f.read(8)
    if len(raw) != 8:
        raise ValueError(f"truncated: the LAZ point data at byte {offset} is cut off")
    table, = struct.unpack("<q", raw)
    if table == -1 and end >= offset + 16:
        f.seek(end - 8)
        table, = struct.unpack("<q", f.read(8))
    if not offset + 8 <= table <= end - 8:
        return  # no chunk table (a file being written, or lost): lazrs reads the chunks in order
    f.seek(table)
    version, chunks = struct.unpack("<II", f.read(8))
    if version != 0:
        return
    if chunks * chunk_size < count:
        raise ValueError(f"the header declares {count} points but the file holds {chunks} LASzip chunks of "
                         f"at most {chunk_size} points (at most {chunks * chunk_size} points in "
                         f"{end - offset} bytes of point data): a corrupt header or a truncated file")
    if count <= (chunks - 1) * chunk_size:
        raise ValueError(f"the header declares {count} points but the file holds {chunks} LASzip chunks of "
                         f"{chunk_size} points (more than {(chunks - 1) * chunk_size} points): the header's "
                         f"point count is wrong and points would be lost; rewrite the file with a correct "
                         f"header (e.g. `pdal translate` or `lasinfo -repair`)")


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
