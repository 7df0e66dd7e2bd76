"""m3c2kit.io readers: every shared reader file, text layouts, PLY encodings, E57 poses, bad input."""
from __future__ import annotations

import re
import subprocess
import sys
import time
from pathlib import Path

import laspy
import numpy as np
import pye57
import pytest
from child_env import child_env

from m3c2kit.base.errors import CloudReadError, UsageError
from m3c2kit.io import SUPPORTED_READ, info, read_cloud

DATA = Path(__file__).resolve().parents[4] / "shared" / "data"
READERS = DATA / "readers"

# Files under readers/ that must be rejected: relative path -> (why, text the message must hold).
# A file missing here that fails, or listed here that reads, fails the test: update the list
# deliberately.
EXPECTED_REJECTIONS = {
    "laszip-broken/broken_coder.laz": ("LASzip VLR names coder 15 (only 0 exists)", "unknown LASzip coder"),
    "laszip-broken/broken_compressor.laz": ("LASzip VLR names compressor 16", "unknown LASzip compressor"),
    "laszip-broken/broken_size.laz": ("point-wise LAZ (with a corrupt item size)", "point-wise"),
    "laszip-broken/broken_type.laz": ("point-wise LAZ (with an unknown item type)", "point-wise"),
    "laszip-broken/broken_version.laz": ("point-wise LAZ (with a bad item version)", "point-wise"),
    "laszip-broken/COPYING.LASzip.txt": ("licence text", "no line with three numbers"),
    "pdal/LICENSE.PDAL.txt": ("licence text", "no line with three numbers"),
    "pdal/laz/simple-laszip-compressor-version-1.2r0.laz":
        ("LASzip 1.2 point-wise compressor, which lazrs cannot decode", "point-wise"),
    "pdal/las/1.2-with-color-clipped.las": ("header says 1065 points, the file holds 1064", "truncated"),
    "pdal/las/permutations/1.2-no-points.las": ("header says 1065 points, the file has none", "truncated"),
    "pdal/las/bad_vlr_count.las": ("header declares 3 VLRs, 2 fit before the points", "malformed LAS header"),
    "pdal/las/garbage_nVariableLength.las":
        ("header declares 1069128089 VLRs (laspy would loop on it)", "malformed LAS header"),
    "pdal/las/no-points.las": ("a valid LAS with 0 points", "contains no points"),
    "pdal/ply/no_vertex.ply": ("no vertex element", "no 'vertex' element"),
    "pdal/ply/sized_dims.ply": ("vertices have x and y but no z", "no 'z' property"),
    "pdal/ply/unsized_dims.ply": ("vertices have x and y but no z", "no 'z' property"),
    "pdal/text/badheader.txt": ("header X,Y,X: two X columns and no Z", "ambiguously"),
    "pdal/text/text.txt": ("a sentence, not numbers", "no line with three numbers"),
    "e57/libE57Format/self/bad-crc.e57": ("page checksum mismatch", "checksum mismatch"),
    "e57/libE57Format/self/InvalidCVHeader.e57": ("one scan of 0 points", "contains no points"),
    "e57/libE57Format/self/ZeroPoints.e57": ("one scan of 0 points", "contains no points"),
    "e57/libE57Format/self/ZeroPointsInvalid.e57": ("one scan of 0 points, no point section", "contains no points"),
    "e57/libE57Format/self/PinholeImageWithDistortionParameters.e57": ("images only, no scans", "contains no points"),
    "e57/libE57Format/self/empty.e57": ("no scans", "contains no points"),
    "e57/libE57Format/self/test filename äöü.e57": ("no scans (Unicode name)", "contains no points"),
    "e57/libE57Format/self/测试点云.e57": ("no scans (Unicode name)", "contains no points"),
}

# LAS files whose header bounds disagree with their own points (by more than scale/2); for
# these the reader's bounds are checked against the points laspy decodes instead.
HEADER_BOUNDS_WRONG = {
    "laspy/simple1_3.las": "header min/max are off by ~1e8",
    "pdal/las/spurious.las": "header min x is off by ~1 (file made to test that)",
    "pdal/las/utm15.las": "header bounds differ from the single point by 7 mm (scale 0.01)",
    "laszip-broken/5points_14.las": "header min z is 0.82 below the lowest point",
}


def _reader_files() -> list[str]:
    if not READERS.is_dir():
        return []
    return sorted(str(p.relative_to(READERS)) for p in READERS.rglob("*") if p.is_file())


def _is_point_file(rel: str) -> bool:
    name = rel.lower()
    return any(name.endswith(ext) for ext in SUPPORTED_READ)


def _expected_las(path: Path, rel: str, cloud) -> None:
    las = laspy.read(path)
    header = las.header
    assert len(cloud) == header.point_count
    tol = header.scales / 2 + 1e-9 * np.abs(header.maxs)
    if rel in HEADER_BOUNDS_WRONG:
        mins = np.array([las.x.min(), las.y.min(), las.z.min()])
        maxs = np.array([las.x.max(), las.y.max(), las.z.max()])
    else:
        mins, maxs = header.mins, header.maxs
    np.testing.assert_array_less(np.abs(cloud.xyz.min(axis=0) - mins), tol)
    np.testing.assert_array_less(np.abs(cloud.xyz.max(axis=0) - maxs), tol)
    assert cloud.scale == tuple(header.scales) and cloud.offset == tuple(header.offsets)


def _expected_e57(path: Path, cloud) -> None:
    e57 = pye57.E57(str(path))
    expected = 0
    for i in range(e57.scan_count):
        header = e57.get_header(i)
        if header.point_count == 0:
            continue
        valid = header.point_count
        if "cartesianInvalidState" in header.point_fields:
            raw = e57.read_scan_raw(i, ignore_unsupported_fields=True)
            valid = int(np.count_nonzero(raw["cartesianInvalidState"] == 0))
        expected += valid
    assert len(cloud) == expected
    assert cloud.scan_positions.shape == (e57.scan_count, 3)


def _expected_ply(path: Path, cloud) -> None:
    head = path.read_bytes().split(b"end_header", 1)[0].decode("ascii")
    assert len(cloud) == int(re.search(r"element vertex (\d+)", head).group(1))


def _expected_text(path: Path, cloud) -> None:
    number = r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?"
    rows = [line for line in path.read_text(errors="replace").splitlines()
            if len(re.findall(rf"(?:^|[\s,;\"]){number}(?=$|[\s,;\"])", line)) >= 3]
    assert len(cloud) == len(rows)


@pytest.mark.slow
@pytest.mark.parametrize("rel", _reader_files())
def test_every_shared_reader_file(rel):
    path = READERS / rel
    if rel in EXPECTED_REJECTIONS or not _is_point_file(rel):
        needle = EXPECTED_REJECTIONS.get(rel, ("", "unknown point-cloud file extension"))[1]
        with pytest.raises(CloudReadError) as err:
            read_cloud(path)
        assert str(err.value).startswith(f"{path}: ")
        assert needle in str(err.value)
        return
    cloud = read_cloud(path)
    assert cloud.xyz.dtype == np.float64 and cloud.xyz.flags.c_contiguous and cloud.xyz.shape[1] == 3
    assert np.isfinite(cloud.xyz).all()
    assert cloud.path == path
    for name, values in cloud.fields.items():
        assert values.shape == (len(cloud),), name
    suffix = path.suffix.lower()
    if suffix in (".las", ".laz"):
        _expected_las(path, rel, cloud)
    elif suffix == ".e57":
        _expected_e57(path, cloud)
    elif suffix == ".ply":
        _expected_ply(path, cloud)
    else:
        _expected_text(path, cloud)


def test_rejection_list_names_existing_files():
    if not READERS.is_dir():
        pytest.skip("shared data absent")
    missing = [rel for rel in EXPECTED_REJECTIONS if not (READERS / rel).is_file()]
    assert not missing


# ----------------------------------------------------------------- corrupt LAZ: bounded time

_CHILD = """
import sys
from m3c2kit.base.errors import CloudReadError
from m3c2kit.io import read_cloud
try:
    read_cloud(sys.argv[1])
except CloudReadError as e:
    print("REJECTED", e)
else:
    print("READ")
"""


def _read_in_child(path: Path, timeout: float = 60) -> str:
    """Reads `path` in a fresh interpreter, so a hang or a hard crash fails this test only."""
    env = child_env(RUST_BACKTRACE="0")
    done = subprocess.run([sys.executable, "-c", _CHILD, str(path)], capture_output=True, text=True,
                          timeout=timeout, env=env)
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout.strip()


@pytest.mark.slow
@pytest.mark.parametrize("name", ["broken_coder.laz", "broken_compressor.laz", "broken_size.laz",
                                  "broken_type.laz", "broken_version.laz"])
def test_broken_laz_fails_cleanly_in_bounded_time(shared_data, name):
    path = shared_data / "readers" / "laszip-broken" / name
    start = time.monotonic()
    out = _read_in_child(path)
    assert out.startswith(f"REJECTED {path}: ")
    assert time.monotonic() - start < 60


@pytest.mark.slow
@pytest.mark.parametrize("source", ["readers/laspy/simple.laz", "readers/laspy/1_4_w_evlr.laz",
                                    "readers/pdal/copc/1.2-with-color.copc.laz"])
def test_truncated_and_bit_flipped_laz_fail_cleanly(shared_data, tmp_path, source):
    data = (shared_data / source).read_bytes()
    variants = {f"cut{n}": data[:n] for n in (300, 1000, len(data) // 2, len(data) - 9)}
    flipped = bytearray(data)
    flipped[len(data) // 2] ^= 0x10
    variants["flip"] = bytes(flipped)
    for name, content in variants.items():
        path = tmp_path / f"{name}.laz"
        path.write_bytes(content)
        out = _read_in_child(path)
        # A flipped bit inside compressed data may still decode (LAZ has no checksum): the
        # requirement is a clean answer, never a hang or a crash.
        assert out == "READ" or out.startswith(f"REJECTED {path}: "), out
        if name.startswith("cut"):
            assert out.startswith("REJECTED")


def test_pointwise_laz_is_rejected_before_lazrs_panics(shared_data, capfd):
    path = shared_data / "readers" / "pdal" / "laz" / "simple-laszip-compressor-version-1.2r0.laz"
    with pytest.raises(CloudReadError, match="point-wise"):
        read_cloud(path)
    assert "panicked" not in capfd.readouterr().err


# ------------------------------------------------------------------------------ LAS specifics

def test_copc_reads_the_same_points_as_plain_las(shared_data):
    copc = read_cloud(shared_data / "readers" / "laspy" / "simple.copc.laz")
    plain = read_cloud(shared_data / "readers" / "laspy" / "simple.las")
    assert copc.format == "COPC"
    key = lambda xyz: xyz[np.lexsort(xyz.T)]  # noqa: E731  (COPC reorders points)
    np.testing.assert_allclose(key(copc.xyz), key(plain.xyz), atol=0.006)


def test_las_crs_and_units(shared_data):
    both = read_cloud(shared_data / "readers" / "laspy" / "file_with_both_wkt_and_geotiff_vlrs.las")
    assert both.crs.startswith('PROJCS["NAD83_2011_Nebraska_ft"')
    assert both.units_hint == "US survey foot"
    autzen = read_cloud(shared_data / "pairs" / "autzen-bmx" / "autzen-bmx-2010.las")
    assert autzen.crs.startswith("COMPD_CS[")
    assert autzen.units_hint == "metre (horizontal), US survey foot (vertical)"
    liblas = read_cloud(shared_data / "readers" / "laspy" / "autzen_geo_proj.las")
    assert liblas.crs.startswith('PROJCS["NAD83(HARN) / Oregon Lambert (ft)"')
    geotiff_only = read_cloud(shared_data / "readers" / "pdal" / "las" / "test_utm17.las")
    assert geotiff_only.crs == "EPSG:32617" and geotiff_only.units_hint == "metre"
    junk_wkt = read_cloud(shared_data / "readers" / "pdal" / "las" / "warsaw_small.las")
    assert junk_wkt.crs is None  # its WKT record holds just "''"
    assert read_cloud(shared_data / "readers" / "laspy" / "simple.las").crs is None


def test_las_fields_include_extra_bytes(shared_data):
    cloud = read_cloud(shared_data / "readers" / "pdal" / "las" / "1.2-empty-geotiff-vlrs.las")
    assert cloud.fields["Amplitude"].dtype == np.float64  # scaled extra bytes come out scaled
    arrays = read_cloud(shared_data / "readers" / "laspy" / "extrabytes.las")
    assert {"Colors_0", "Colors_1", "Colors_2", "intensity", "Intensity"} <= set(arrays.fields)


def test_las_truncated_copy_is_rejected(shared_data, tmp_path):
    data = (shared_data / "readers" / "laspy" / "simple.las").read_bytes()
    path = tmp_path / "cut.las"
    path.write_bytes(data[: len(data) - 100])
    with pytest.raises(CloudReadError, match=r"truncated: the header declares 1065 points .* only 1062"):
        read_cloud(path)


# ------------------------------------------------------------------------------- bad input

@pytest.mark.parametrize("ext", [".las", ".laz", ".e57", ".ply", ".xyz", ".csv", ".npy"])
def test_empty_file_is_rejected(tmp_path, ext):
    path = tmp_path / f"empty{ext}"
    path.touch()
    with pytest.raises(CloudReadError, match=re.escape(f"{path}: is empty (0 bytes)")):
        read_cloud(path)


def test_missing_directory_and_unknown(tmp_path):
    with pytest.raises(CloudReadError, match="no such file") as err:
        read_cloud(tmp_path / "nope.las")
    assert str(err.value).startswith(str(tmp_path / "nope.las"))
    with pytest.raises(CloudReadError, match="is a directory"):
        read_cloud(tmp_path)
    odd = tmp_path / "cloud.foo"
    odd.write_text("1 2 3\n")
    with pytest.raises(CloudReadError, match="unknown point-cloud file extension '.foo'"):
        read_cloud(odd)


def test_content_not_matching_extension(tmp_path, shared_data):
    text_as_las = tmp_path / "text.las"
    text_as_las.write_text("1 2 3\n4 5 6\n")
    with pytest.raises(CloudReadError, match=r"text.las: not a LAS/LAZ file \(no 'LASF' signature\)"):
        read_cloud(text_as_las)
    las_as_ply = tmp_path / "points.ply"
    las_as_ply.write_bytes((shared_data / "readers" / "laspy" / "simple.las").read_bytes())
    with pytest.raises(CloudReadError, match="the content is LAS/LAZ, not PLY"):
        read_cloud(las_as_ply)
    junk_as_xyz = tmp_path / "junk.xyz"
    junk_as_xyz.write_bytes(bytes(range(256)) * 4)
    with pytest.raises(CloudReadError, match="binary content"):
        read_cloud(junk_as_xyz)
    text_as_e57 = tmp_path / "a.e57"
    text_as_e57.write_text("1 2 3\n")
    with pytest.raises(CloudReadError, match="not an E57 file"):
        read_cloud(text_as_e57)


def test_columns_only_for_text(shared_data):
    with pytest.raises(UsageError, match="text files only"):
        read_cloud(shared_data / "readers" / "laspy" / "simple.las", columns=(0, 1, 2))


# --------------------------------------------------------------------------------- non-finite

def test_nonfinite_coordinates_rejected_with_count_or_dropped(tmp_path):
    path = tmp_path / "nan.xyz"
    path.write_text("x y z w\n1 2 3 10\nnan 2 3 11\n4 5 6 12\n7 inf 9 13\n8 9 -inf 14\n")
    with pytest.raises(CloudReadError) as err:
        read_cloud(path)
    message = str(err.value)
    assert message.startswith(f"{path}: 3 of 5 points") and "--drop-nonfinite" in message
    cloud = read_cloud(path, drop_nonfinite=True)
    assert cloud.dropped_nonfinite == 3
    np.testing.assert_array_equal(cloud.xyz, [[1, 2, 3], [4, 5, 6]])
    np.testing.assert_array_equal(cloud.fields["w"], [10, 12])
    only_nan = tmp_path / "allnan.xyz"
    only_nan.write_text("nan 1 2\n1 nan 2\n")
    with pytest.raises(CloudReadError, match="no points with finite coordinates"):
        read_cloud(only_nan, drop_nonfinite=True)


def test_finite_coordinates_whose_sum_overflows_are_finite(tmp_path):
    # read_cloud tests one sum first: here it is infinite although every coordinate is finite,
    # and the points are then tested one by one (none is dropped, none reported).
    path = tmp_path / "huge.xyz"
    path.write_text("1.5e308 1.5e308 0\n-1e308 1.5e308 1\n2 3 4\n")
    cloud = read_cloud(path)
    assert len(cloud) == 3 and cloud.dropped_nonfinite == 0
    path.write_text("1.5e308 1.5e308 0\n-1e308 1.5e308 nan\n2 3 4\n")
    with pytest.raises(CloudReadError, match="1 of 3 points have non-finite"):
        read_cloud(path)


# ------------------------------------------------------------------------------ text layouts

_XYZ = np.array([[1.5, -2.25, 3.0], [4.0, 5.125, -6.5], [7.0, 8.0, 9.75]])
_W = np.array([10.0, 20.0, 30.0])


def _table_text(sep: str, header: str | None) -> str:
    lines = [] if header is None else [header]
    lines += [sep.join(repr(float(v)) for v in (*p, w)) for p, w in zip(_XYZ, _W)]
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("sep", [",", ";", "\t", " ", "   "])
@pytest.mark.parametrize("header", [None, "X{s}Y{s}Z{s}w", '"X"{s}"Y"{s}"Z"{s}"w"', "//X{s}Y{s}Z{s}w",
                                    "# x{s}y{s}z{s}w"])
def test_text_delimiters_and_headers(tmp_path, sep, header):
    path = tmp_path / "t.txt"
    path.write_text(_table_text(sep, None if header is None else header.format(s=sep)))
    cloud = read_cloud(path)
    np.testing.assert_array_equal(cloud.xyz, _XYZ)
    name = "col3" if header is None else "w"
    np.testing.assert_array_equal(cloud.fields[name], _W)
    assert cloud.format == "ASCII"


def test_text_header_picks_xyz_by_name_in_any_order(tmp_path):
    path = tmp_path / "t.csv"
    path.write_text("intensity,z,Y,x\n5,3,2,1\n6,30,20,10\n")
    cloud = read_cloud(path)
    np.testing.assert_array_equal(cloud.xyz, [[1, 2, 3], [10, 20, 30]])
    np.testing.assert_array_equal(cloud.fields["intensity"], [5, 6])


def test_text_columns_option(tmp_path):
    path = tmp_path / "t.txt"
    path.write_text("a b c d e\n1 2 3 4 5\n6 7 8 9 10\n")
    cloud = read_cloud(path, columns=(4, 2, 0))
    np.testing.assert_array_equal(cloud.xyz, [[5, 3, 1], [10, 8, 6]])
    assert set(cloud.fields) == {"b", "d"}
    for bad in [(0, 1), (0, 0, 1), (0, 1, 9), ("a", 1, 2)]:
        with pytest.raises(UsageError):
            read_cloud(path, columns=bad)


def test_text_quirks(tmp_path):
    crlf = tmp_path / "crlf.csv"
    crlf.write_bytes(b"X,Y,Z\r\n1,2,3\r\n\r\n4, 5, 6\r\n")
    np.testing.assert_array_equal(read_cloud(crlf).xyz, [[1, 2, 3], [4, 5, 6]])
    pts = tmp_path / "scan.pts"  # Leica .pts: a point-count line, then x y z i r g b
    pts.write_text("2\n1 2 3 -100 10 20 30\n4 5 6 -200 40 50 60\n")
    cloud = read_cloud(pts)
    np.testing.assert_array_equal(cloud.xyz, [[1, 2, 3], [4, 5, 6]])
    assert list(cloud.fields) == ["col3", "col4", "col5", "col6"]
    # CloudCompare-style: a quoted header with a trailing comma and fewer names than columns.
    short = tmp_path / "short.txt"
    short.write_text('"X","Y","Z","Intensity",\n1,2,3,4,5,6\n7,8,9,10,11,12\n')
    cloud = read_cloud(short)
    assert list(cloud.fields) == ["Intensity", "col4", "col5"]
    # Header delimiter differs from the data delimiter; a non-numeric column is ignored.
    mixed = tmp_path / "mixed.txt"
    mixed.write_text('"X","Y","Z","label","v"\n1 2 3 tree 0.5\n4 5 6 rock 0.25\n')
    cloud = read_cloud(mixed)
    np.testing.assert_array_equal(cloud.xyz, [[1, 2, 3], [4, 5, 6]])
    assert list(cloud.fields) == ["v"]
    # Comment lines and a UTF-8 byte-order mark.
    bom = tmp_path / "bom.asc"
    bom.write_bytes("\ufeff# exported by hand\n1 2 3\n# mid-file comment\n4 5 6\n".encode())
    np.testing.assert_array_equal(read_cloud(bom).xyz, [[1, 2, 3], [4, 5, 6]])


def test_text_bad_rows_are_errors(tmp_path):
    path = tmp_path / "bad.xyz"
    path.write_text("1 2 3\n4 5 6\n7 8\n")
    with pytest.raises(CloudReadError) as err:
        read_cloud(path)
    assert str(err.value).startswith(f"{path}: ")
    partial = tmp_path / "partial.csv"
    partial.write_text("X,Y,W\n1,2,3\n")
    with pytest.raises(CloudReadError, match="ambiguously"):
        read_cloud(partial)
    two = tmp_path / "two.xyz"
    two.write_text("1 2\n3 4\n")
    with pytest.raises(CloudReadError, match="no line with three numbers"):
        read_cloud(two)


def test_text_reads_100k_lines_with_a_header(tmp_path):
    """Every line of a large text file with a commented header. Its speed is a benchmark's
    (docs/performance.md), not a timed test's: a loaded CI machine failed a 1 s bound."""
    rng = np.random.default_rng(1)
    table = np.column_stack([rng.uniform(0, 1000, (100_000, 3)), rng.integers(0, 255, 100_000)])
    path = tmp_path / "big.xyz"
    np.savetxt(path, table, fmt=["%.3f", "%.3f", "%.3f", "%d"], header="X Y Z Intensity", comments="//")
    cloud = read_cloud(path)
    assert len(cloud) == 100_000
    np.testing.assert_allclose(cloud.xyz, table[:, :3], atol=5e-4)
    np.testing.assert_array_equal(cloud.fields["Intensity"], table[:, 3])


def test_shared_text_pairs(shared_data):
    ttp = read_cloud(shared_data / "pairs" / "toronto-ttp" / "TTP_15.xyz")
    assert len(ttp) == 89_815
    assert list(ttp.fields) == ["Intensity", "ReturnNumber", "NumberOfReturns", "Classification", "gpstime"]
    bmx = read_cloud(shared_data / "pairs" / "autzen-bmx" / "autzen-bmx-largersample.txt")
    assert len(bmx) == 103 and bmx.meta["delimiter"] == ","
    np.testing.assert_array_equal(bmx.xyz[0], [194506.860, 259235.010, 426.540])
    plane = read_cloud(shared_data / "pairs" / "py4dgeo-plane-synthetic" / "plane_horizontal_t1.xyz")
    assert len(plane) == 441 and not plane.fields


# ------------------------------------------------------------------------------------- PLY

def _ply_header(encoding: str, n: int, props: list[tuple[str, str]], before: str = "", after: str = "") -> bytes:
    lines = ["ply", f"format {encoding} 1.0", "comment made by the test", before.strip()]
    lines += [f"element vertex {n}"] + [f"property {t} {name}" for t, name in props]
    lines += [after.strip(), "end_header"]
    return ("\n".join(line for line in lines if line) + "\n").encode()


_PLY_PROPS = [("float", "x"), ("double", "y"), ("int", "z"), ("uchar", "red"), ("short", "s"),
              ("float", "nx")]
_PLY_DTYPE = [("x", "f4"), ("y", "f8"), ("z", "i4"), ("red", "u1"), ("s", "i2"), ("nx", "f4")]


def _ply_rows(n: int = 5) -> np.ndarray:
    rows = np.zeros(n, dtype=_PLY_DTYPE)
    rows["x"] = np.arange(n) * 0.5
    rows["y"] = np.arange(n) * 1e5 + 0.123456789
    rows["z"] = -np.arange(n) * 7
    rows["red"] = np.arange(n) * 50
    rows["s"] = -np.arange(n) * 1000
    rows["nx"] = 0.25
    return rows


@pytest.mark.parametrize("encoding", ["ascii", "binary_little_endian", "binary_big_endian"])
def test_ply_encodings(tmp_path, encoding):
    rows = _ply_rows()
    # A face element with a list property before the vertices, an edge element after them.
    face = "element face 2\nproperty list uchar int vertex_indices"
    edge = "element edge 1\nproperty int vertex1\nproperty int vertex2"
    head = _ply_header(encoding, len(rows), _PLY_PROPS, before=face, after=edge)
    if encoding == "ascii":
        faces = b"3 0 1 2\n4 0 1 2 3\n"
        body = "".join(" ".join(repr(v.item()) for v in row) + "\n" for row in rows).encode() + b"0 1\n"
    else:
        order = "<" if encoding == "binary_little_endian" else ">"
        faces = (np.array([3], "u1").tobytes() + np.array([0, 1, 2], order + "i4").tobytes()
                 + np.array([4], "u1").tobytes() + np.array([0, 1, 2, 3], order + "i4").tobytes())
        body = rows.astype([(n, order + t) for n, t in _PLY_DTYPE]).tobytes()
        body += np.array([0, 1], order + "i4").tobytes()
    path = tmp_path / f"{encoding}.ply"
    path.write_bytes(head + faces + body)
    cloud = read_cloud(path)
    np.testing.assert_array_equal(cloud.xyz, np.column_stack([rows["x"], rows["y"], rows["z"]]).astype(float))
    assert set(cloud.fields) == {"red", "s", "nx"}
    for name in cloud.fields:
        assert cloud.fields[name].dtype == rows.dtype[name]
        np.testing.assert_array_equal(cloud.fields[name], rows[name])
    assert cloud.meta["encoding"] == encoding


def test_ply_truncated_and_malformed(tmp_path):
    rows = _ply_rows(4)
    head = _ply_header("binary_little_endian", 4, _PLY_PROPS)
    cut = tmp_path / "cut.ply"
    cut.write_bytes(head + rows.tobytes()[:-3])
    with pytest.raises(CloudReadError, match="truncated: PLY header declares 4 vertices, the file holds 3"):
        read_cloud(cut)
    short = tmp_path / "short.ply"
    short.write_bytes(_ply_header("ascii", 2, [("float", "x"), ("float", "y"), ("float", "z"), ("int", "i")])
                      + b"1 2 3\n4 5 6\n")
    with pytest.raises(CloudReadError, match="have 3 values, the header declares 4"):
        read_cloud(short)
    no_end = tmp_path / "noend.ply"
    no_end.write_bytes(b"ply\nformat ascii 1.0\nelement vertex 1\n")
    with pytest.raises(CloudReadError, match="no 'end_header'"):
        read_cloud(no_end)
    odd = tmp_path / "odd.ply"
    odd.write_bytes(_ply_header("ascii", 1, [("float", "x"), ("float", "y"), ("float", "z"),
                                             ("list uchar int", "idx")]) + b"1 2 3 1 0\n")
    with pytest.raises(CloudReadError, match="list properties in the PLY vertex element are not supported"):
        read_cloud(odd)


# ------------------------------------------------------------------------------------- E57

def _quaternion_matrix(w: float, x: float, y: float, z: float) -> np.ndarray:
    # Written out here, independently of pye57's pyquaternion-based transform.
    n = np.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / n, x / n, y / n, z / n
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def test_e57_pose_translation_applied(shared_data):
    path = shared_data / "readers" / "e57" / "pye57" / "translationWithoutRotation.e57"
    raw = pye57.E57(str(path)).read_scan_raw(0)
    cloud = read_cloud(path)
    expected = np.column_stack([raw["cartesianX"], raw["cartesianY"], raw["cartesianZ"]]) + [4, 5, 6]
    np.testing.assert_array_equal(cloud.xyz, expected)
    np.testing.assert_array_equal(cloud.scan_positions, [[4, 5, 6]])
    assert cloud.units_hint == "metre" and cloud.format == "E57"


def test_e57_invalid_points_skipped(tmp_path):
    # No shared E57 file flags any point invalid: write one that does (states 0, 1 and 2).
    path = tmp_path / "invalid.e57"
    n = 30
    data = {"cartesianX": np.arange(n, dtype=float), "cartesianY": np.zeros(n), "cartesianZ": np.ones(n),
            "cartesianInvalidState": (np.arange(n) % 3).astype(np.int8)}
    with pye57.E57(str(path), mode="w") as out:
        out.write_scan_raw(data)
    cloud = read_cloud(path)
    np.testing.assert_array_equal(cloud.xyz[:, 0], np.arange(0, n, 3))
    np.testing.assert_array_equal(cloud.scan_positions, [[0, 0, 0]])


def test_e57_multiple_scans_with_poses(tmp_path):
    # The shared E57 files all hold one scan: write a three-scan file with pye57.
    path = tmp_path / "multi.e57"
    rng = np.random.default_rng(3)
    poses = [((1.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0)),
             ((np.cos(0.4), 0.0, 0.0, np.sin(0.4)), (10.0, -5.0, 2.0)),
             ((0.9, 0.1, -0.3, 0.2), (-3.0, 7.5, 1.25))]
    scans = []
    with pye57.E57(str(path), mode="w") as out:
        for k, (rotation, translation) in enumerate(poses):
            n = 50 + k
            data = {"cartesianX": rng.uniform(-5, 5, n), "cartesianY": rng.uniform(-5, 5, n),
                    "cartesianZ": rng.uniform(0, 3, n), "cartesianInvalidState": np.zeros(n, np.int8)}
            data["cartesianInvalidState"][::10] = 1
            out.write_scan_raw(data, name=f"scan {k}", rotation=np.array(rotation),
                               translation=np.array(translation))
    reader = pye57.E57(str(path))
    for k, (rotation, translation) in enumerate(poses):
        raw = reader.read_scan_raw(k)  # the stored (float32-rounded) scanner-frame values
        local = np.column_stack([raw["cartesianX"], raw["cartesianY"], raw["cartesianZ"]])
        local = local[raw["cartesianInvalidState"] == 0]
        scans.append(local @ _quaternion_matrix(*rotation).T + translation)
    cloud = read_cloud(path)
    np.testing.assert_allclose(cloud.xyz, np.concatenate(scans), rtol=0, atol=1e-9)
    np.testing.assert_array_equal(cloud.scan_positions, [t for _, t in poses])
    described = info(path)
    assert described["scan_count"] == 3 and described["point_count"] == len(cloud)


def _write_e57_fields(path: Path, columns: dict[str, np.ndarray], translation=(0.0, 0.0, 0.0)) -> None:
    """One scan with exactly these (double) point fields and a pose, via pye57's libE57
    bindings (pye57's own writer only writes cartesian scans)."""
    import uuid

    from pye57 import libe57

    e57 = pye57.E57(str(path), mode="w")
    imf = e57.image_file
    scan = libe57.StructureNode(imf)
    scan.set("guid", libe57.StringNode(imf, "{%s}" % uuid.uuid4()))
    pose, rotation, shift = (libe57.StructureNode(imf) for _ in range(3))
    for key, value in zip("wxyz", (1.0, 0.0, 0.0, 0.0)):
        rotation.set(key, libe57.FloatNode(imf, value))
    for key, value in zip("xyz", translation):
        shift.set(key, libe57.FloatNode(imf, float(value)))
    pose.set("rotation", rotation)
    pose.set("translation", shift)
    scan.set("pose", pose)
    prototype = libe57.StructureNode(imf)
    for name in columns:
        prototype.set(name, libe57.FloatNode(imf, 0.0, libe57.E57_DOUBLE, -1e9, 1e9))
    points = libe57.CompressedVectorNode(imf, prototype, libe57.VectorNode(imf, True))
    scan.set("points", points)
    e57.data3d.append(scan)
    n = len(next(iter(columns.values())))
    arrays, buffers = e57.make_buffers(list(columns), n)
    for name, values in columns.items():
        arrays[name][:] = values
    writer = points.writer(buffers)
    writer.write(n)
    writer.close()
    e57.close()


def test_e57_spherical_scan_is_converted_and_posed(tmp_path):
    path = tmp_path / "spherical.e57"
    r, azimuth, elevation = np.array([1.0, 2.0, 3.0]), np.array([0.0, np.pi / 2, 0.0]), np.array([0.0, 0.0, np.pi / 2])
    _write_e57_fields(path, {"sphericalRange": r, "sphericalAzimuth": azimuth, "sphericalElevation": elevation},
                      translation=(1.0, 2.0, 3.0))
    cloud = read_cloud(path)
    expected = np.column_stack([r * np.cos(elevation) * np.cos(azimuth), r * np.cos(elevation) * np.sin(azimuth),
                                r * np.sin(elevation)]) + [1, 2, 3]
    np.testing.assert_allclose(cloud.xyz, expected, atol=1e-12)
    np.testing.assert_array_equal(cloud.scan_positions, [[1, 2, 3]])


def test_e57_scan_without_coordinates_is_rejected(tmp_path):
    path = tmp_path / "nocoords.e57"
    _write_e57_fields(path, {"intensity": np.ones(3)})
    with pytest.raises(CloudReadError, match="scan 0 has neither cartesian nor spherical coordinates"):
        read_cloud(path)


# ------------------------------------------------------------------------------------- NPY

def test_npy_plain_and_structured(tmp_path):
    plain = tmp_path / "p.npy"
    np.save(plain, _XYZ.astype(np.float32))
    np.testing.assert_array_equal(read_cloud(plain).xyz, _XYZ.astype(np.float32).astype(float))
    table = np.zeros(3, dtype=[("X", "f8"), ("Y", "f8"), ("Z", "f8"), ("w", "f4")])
    table["X"], table["Y"], table["Z"], table["w"] = _XYZ.T[0], _XYZ.T[1], _XYZ.T[2], _W
    structured = tmp_path / "s.npy"
    np.save(structured, table)
    cloud = read_cloud(structured)
    np.testing.assert_array_equal(cloud.xyz, _XYZ)
    np.testing.assert_array_equal(cloud.fields["w"], _W)
    wrong = tmp_path / "w.npy"
    np.save(wrong, np.zeros((4, 2)))
    with pytest.raises(CloudReadError, match=r"expected an \(N, 3\) numeric array"):
        read_cloud(wrong)


# ------------------------------------------------------------------------------------ info

def test_info(shared_data):
    las = info(shared_data / "readers" / "laspy" / "simple.las")
    assert las["point_count"] == 1065 and las["format"] == "LAS" and las["version"] == "1.2"
    assert las["point_format"] == 3 and "intensity" in las["fields"] and las["scan_count"] is None
    header = laspy.open(shared_data / "readers" / "laspy" / "simple.las").header
    np.testing.assert_allclose(las["bounds"]["min"], header.mins)
    np.testing.assert_allclose(las["bounds"]["max"], header.maxs)
    empty = info(shared_data / "readers" / "pdal" / "las" / "no-points.las")
    assert empty["point_count"] == 0 and empty["bounds"] is None
    e57 = info(shared_data / "readers" / "e57" / "pye57" / "translationWithoutRotation.e57")
    assert e57["scan_count"] == 1 and e57["point_count"] == 4 and e57["units_hint"] == "metre"
