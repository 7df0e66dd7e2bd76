"""Fuzz targets for m3c2's parsers of untrusted input (docs/errors.md, "Fuzzing").

Each target takes arbitrary bytes, feeds them to one parser and checks its contract: the only
exceptions that may escape are the documented ones, and what is returned is well formed.
Anything else (TypeError, IndexError, an unexpected ValueError, ...) is a bug: the target
re-raises it and the fuzzer reports the input.

    ascii_reader   m3c2kit.io.read_cloud on a .xyz/.csv/.txt/.pts file  -> CloudReadError only
    ply_reader     m3c2kit.io.read_cloud on a .ply file                  -> CloudReadError only
    cc_params      m3c2kit.settings.cloudcompare_params.read_cloudcompare_params  -> UsageError only
    cli_args       cli.make_parser().parse_args + compare_cli.compare_settings + settings.build_params and the
                   option parsers of m3c2kit.options                      -> M3C2Error (UsageError:
                   exit 2), or SystemExit(0) for --help

Drivers: tests/fuzz/fuzz.py (atheris / libFuzzer) and tests/fuzz/random_fuzz.py (a seeded,
bounded mutation fuzzer without dependencies, also run by pytest).
"""
from __future__ import annotations

import contextlib
import io
import math
import os
import sys
import tempfile
from pathlib import Path

_REPO = Path(__file__).resolve().parents[2]
try:  # an installed m3c2 wins; fall back to the source tree
    import m3c2kit  # noqa: F401
except ImportError:  # pragma: no cover
    sys.path.insert(0, str(_REPO / "python"))

import numpy as np  # noqa: E402

from m3c2kit import api
from m3c2kit.cli import compare as compare_cli  # noqa: E402
from m3c2kit.cli import main as cli  # noqa: E402
from m3c2kit.settings import build_params, parameters_of  # noqa: E402
from m3c2kit.settings.parsers import positive  # noqa: E402
from m3c2kit.settings.cloudcompare_params import read_cloudcompare_params  # noqa: E402
from m3c2kit.base.errors import CloudReadError, M3C2Error, UsageError  # noqa: E402
from m3c2kit.io import read_cloud  # noqa: E402

_WORK = Path(tempfile.mkdtemp(prefix="m3c2-fuzz-"))
_TEXT_EXTENSIONS = (".xyz", ".csv", ".txt", ".pts", ".asc", ".neu")


def _write(name: str, data: bytes) -> Path:
    path = _WORK / name
    path.write_bytes(data)
    return path


def _check_cloud(cloud) -> None:
    xyz = cloud.xyz
    assert xyz.dtype == np.float64 and xyz.ndim == 2 and xyz.shape[1] == 3, xyz.shape
    assert len(xyz) > 0, "read_cloud returned an empty cloud"
    assert np.isfinite(xyz).all(), "read_cloud returned non-finite coordinates"
    for name, values in cloud.fields.items():
        assert np.shape(values) == (len(xyz),), (name, np.shape(values))


def ascii_reader(data: bytes) -> None:
    """read_cloud on a delimited text file: a Cloud or CloudReadError, nothing else."""
    ext = _TEXT_EXTENSIONS[data[0] % len(_TEXT_EXTENSIONS)] if data else ".xyz"
    path = _write("cloud" + ext, data[1:])
    try:
        cloud = read_cloud(path)
    except CloudReadError as e:
        assert str(e).startswith(f"{path}: "), str(e)
        return
    _check_cloud(cloud)


def ply_reader(data: bytes) -> None:
    """read_cloud on a .ply file: a Cloud or CloudReadError, nothing else."""
    path = _write("cloud.ply", data)
    try:
        cloud = read_cloud(path)
    except CloudReadError as e:
        assert str(e).startswith(f"{path}: "), str(e)
        return
    _check_cloud(cloud)


_CC_TYPES = {"normal_source": str, "projection_scale": float, "max_depth": float, "registration_error": float,
             "median": bool, "min_points": int, "depth_search": str, "positive_search_only": bool,
             "position": str, "threads": int}


def cc_params(data: bytes) -> None:
    """read_cloudcompare_params: a dict of typed m3c2 options or UsageError naming the file."""
    path = _write("fuzzed_params.txt", data)
    try:
        values = read_cloudcompare_params(path)
    except UsageError as e:
        assert str(e).startswith(f"{path}: "), str(e)
        return
    assert isinstance(values, dict)
    for key, kind in _CC_TYPES.items():
        if key in values:
            assert isinstance(values[key], kind), (key, values[key])
    for key in ("projection_scale", "max_depth"):
        assert math.isfinite(values[key]) and values[key] > 0, (key, values[key])


# ------------------------------------------------------------------------------ command line

# Chunks of the input separated by NUL are argv words; a chunk starting with \x01 is replaced by
# a word of this vocabulary (so that mutations reach every option quickly).
VOCAB = ("compare", "normals", "subsample", "info", "-o", "--output", "--core", "--core-spacing",
         "--normal-scale", "--projection-scale", "--max-depth", "--registration-error", "--orient",
         "--normal-source", "--core-normals", "--median", "--confidence", "--min-points", "--t-statistic",
         "--bootstrap", "--seed", "--first-pass-depth", "--depth-search", "--positive-search-only",
         "--normal-subsample", "--compat", "--params", "--projected", "--position", "--drop-nonfinite",
         "--ignore-crs", "--threads", "--quiet", "--spacing", "--grid", "-h", "0", "-1", "nan", "inf", "1e308",
         "1:2:0.5", "0.5,1,2", "+z", "-x", "1,2,3", "two-pass", "progressive", "single", "vertical", "core",
         "mean", "cloudcompare", "ref.xyz", "cmp.xyz", "out.csv", "18446744073709551616", "-9999999999999")



def argv_from_bytes(data: bytes) -> list[str]:
    words = []
    for chunk in data.split(b"\0"):
        if chunk[:1] == b"\x01" and len(chunk) >= 2:
            words.append(VOCAB[chunk[1] % len(VOCAB)])
        else:
            words.append(chunk.decode("utf-8", "surrogateescape"))
    return words


def _no_files(path):
    raise UsageError(f"{path}: (fuzzing reads no point files)")


def cli_args(data: bytes) -> None:
    """argv -> parse_args -> the option checks of the chosen command, without reading clouds or
    running the engine. Only M3C2Error (UsageError: exit 2) or SystemExit(0) (--help) escape."""
    argv = argv_from_bytes(data)
    sink = io.StringIO()
    with contextlib.redirect_stdout(sink), contextlib.redirect_stderr(sink):
        try:
            args = cli.make_parser().parse_args(argv)
            _check_command(args)
        except M3C2Error:
            return
        except SystemExit as e:  # argparse's --help prints and exits 0; errors exit 2 via UsageError
            assert e.code in (0, None), f"SystemExit({e.code!r}) from argv {argv!r}"
            return


def _check_command(args) -> None:
    cwd = os.getcwd()
    os.chdir(_WORK)  # relative --params paths resolve in the scratch directory
    try:
        if args.command == "compare":
            settings = compare_cli.compare_settings(args)
            settings.pop("position", None)
            build_params(read_points=_no_files, **settings)
        elif args.command == "normals":
            given = {p.name: getattr(args, p.name) for p in parameters_of("normals")}
            build_params("normals", read_points=_no_files, **given)
        elif args.command == "subsample":
            positive("--spacing", args.spacing)
    finally:
        os.chdir(cwd)


# ------------------------------------------------------------------------------------ CRS text

def crs_text(data: bytes) -> None:
    """The CRS helpers on any text (a LAS WKT record, --crs): values or None, never an exception
    (a deeply nested WKT raised RecursionError), and printable() leaves no control character."""
    from m3c2kit.base.errors import printable
    from m3c2kit.io import crs
    text = data.decode("utf-8", "replace")
    assert isinstance(crs.looks_like_wkt(text), bool)
    crs.parse_crs(text)
    label = crs.crs_label(text)
    assert isinstance(label, str) and "\n" not in label
    crs.crs_units(text)
    crs.crs_info(text)
    crs.is_angular(text)
    assert crs.same_crs(text, "EPSG:32632") in (True, False, None)
    shown = printable(label)
    assert not any(ord(c) < 32 and c not in "\t\n" or 0x7F <= ord(c) < 0xA0 for c in shown), shown


# ---------------------------------------------------------------------------------- LAS header

def las_header(data: bytes) -> None:
    """check_las_file on any bytes: a LasLayout whose point count the file can hold, or a
    ValueError (the reader prefixes the path); never another exception, never a read of more
    than the file."""
    from m3c2kit.io.las_header import check_las_file
    path = _write("fuzzed.las", data)
    try:
        layout = check_las_file(path)
    except ValueError:
        return
    if not layout.compressed and layout.record_length:
        assert layout.point_count * layout.record_length <= len(data), layout


TARGETS = {"ascii_reader": ascii_reader, "ply_reader": ply_reader, "cc_params": cc_params, "cli_args": cli_args,
           "crs_text": crs_text, "las_header": las_header}

# ----------------------------------------------------------------------------------- seeds

_PARAMS_SEED = (b"[General]\nM3C2VER=1\nNormalScale=2.78\nNormalMode=0\nNormalPreferedOri=4\nSearchScale=5.78\n"
                b"SearchDepth=5.5\nUseSinglePass4Depth=true\nSubsampleEnabled=false\nRegistrationErrorEnabled=true\n"
                b"RegistrationError=0.01\nUseMedian=false\nUseMinPoints4Stat=true\nMinPoints4Stat=5\n"
                b"ProjDestIndex=2\nExportStdDevInfo=true\nMaxThreadCount=2\n")
_PLY_ASCII = (b"ply\nformat ascii 1.0\ncomment x\nelement vertex 3\nproperty float x\nproperty float y\n"
              b"property float z\nproperty uchar intensity\nelement face 1\nproperty list uchar int vertex_indices\n"
              b"end_header\n0 0 0 1\n1 0 0 2\n0 1 0.5 3\n3 0 1 2\n")


def _ply_binary() -> bytes:
    header = (b"ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty double x\nproperty double y\n"
              b"property double z\nproperty int class\nend_header\n")
    body = np.array([(0.0, 1.0, 2.0, 7), (3.0, 4.0, 5.0, 8)],
                    dtype=[("x", "<f8"), ("y", "<f8"), ("z", "<f8"), ("c", "<i4")]).tobytes()
    return header + body


def _argv(*words: str) -> bytes:
    return b"\0".join(w.encode() for w in words)


SEEDS = {
    "ascii_reader": [b"\x00" + b"1 2 3\n4 5 6\n7 8 9\n",
                     b"\x01" + b"x,y,z,intensity\n1.5,2.5,3.5,10\n4,5,6,11\n",
                     b"\x02" + b"// X;Y;Z\n1;2;3\n4;5;6\n",
                     b"\x03" + b"3\n1 2 3 255 0 0\n4 5 6 0 255 0\n7 8 9 0 0 255\n",
                     b"\x00" + b"# comment\n\"1\",\"2\",\"3\"\n\"4\",\"5\",\"6\"\n",
                     b"\x04" + b"1\t2\t3\n\n4\t5\tnan\n"],
    "ply_reader": [_PLY_ASCII, _ply_binary(), _PLY_ASCII.replace(b"ascii", b"binary_big_endian")],
    "cc_params": [_PARAMS_SEED, _PARAMS_SEED.replace(b"NormalMode=0", b"NormalMode=2\nNormalMinScale=1\n"
                                                      b"NormalStep=0.5\nNormalMaxScale=3"),
                  b"[General]\nM3C2VER=1\nSearchScale=\"1\" ; c\nSearchDepth=2\nNormalMode=3\n"],
    "cli_args": [_argv("compare", "ref.xyz", "cmp.xyz", "-o", "out.csv", "--normal-scale", "0.5", "--projection-scale",
                       "0.3", "--max-depth", "0.5"),
                 _argv("compare", "ref.xyz", "cmp.xyz", "-o", "o.laz", "--normal-scale", "1:3:0.5", "--projection-scale",
                       "1", "--max-depth", "2", "--first-pass-depth", "1", "--bootstrap", "100", "--seed", "3",
                       "--confidence", "0.99", "--orient", "1,2,3", "--threads", "2", "--min-points", "5"),
                 _argv("compare", "ref.xyz", "cmp.xyz", "-o", "o.csv", "--params", "m3c2_params.txt"),
                 _argv("normals", "in.xyz", "-o", "n.ply", "--normal-scale", "0.5,1,2", "--orient", "-z"),
                 _argv("subsample", "in.xyz", "-o", "s.csv", "--spacing", "0.1"),
                 _argv("info", "x.las")],
}
_WKT_SEED = (b'PROJCS["WGS 84 / UTM zone 32N",GEOGCS["WGS 84",DATUM["WGS_1984",SPHEROID["WGS 84",6378137,298.257223563]],'
             b'PRIMEM["Greenwich",0],UNIT["degree",0.0174532925199433]],PROJECTION["Transverse_Mercator"],'
             b'PARAMETER["central_meridian",9],UNIT["metre",1],AUTHORITY["EPSG","32632"]]')
SEEDS["crs_text"] = [_WKT_SEED, b"EPSG:26916", b"A[" * 3000 + b"]" * 3000, b'GEOGCS["\x1b]0;x\x07\x1b[2J"]',
                     b"+proj=utm +zone=17 +datum=WGS84"]


def _las_seed(version: str, point_format: int, compress: bool) -> bytes:
    import laspy
    las = laspy.LasData(laspy.LasHeader(version=version, point_format=point_format))
    las.x, las.y, las.z = np.arange(5.0), np.arange(5.0), np.arange(5.0)
    out = io.BytesIO()
    las.write(out, do_compress=compress)
    return out.getvalue()


SEEDS["las_header"] = [_las_seed("1.2", 3, False), _las_seed("1.4", 6, False), _las_seed("1.4", 6, True),
                       b"LASF" + bytes(400)]
(_WORK / "m3c2_params.txt").write_bytes(_PARAMS_SEED)  # what the cli_args seed's --params names
