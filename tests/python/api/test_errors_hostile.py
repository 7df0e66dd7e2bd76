"""docs/errors.md, issue 15 points 6, 10 and 11 (the parts in modules the front end wires in):
`m3c2 suggest` on 2 or 3 points, a parameter-file value of 5,000 digits, lengths that are
denormal floats, non-real coordinate arrays, terminal escapes in what is printed."""
from __future__ import annotations

import datetime

import numpy as np
import pytest

from m3c2kit.analysis.suggest import suggest as suggest_parameters
from m3c2kit.cli.main import main
from m3c2kit.settings.cloudcompare_params import read_cloudcompare_params
from m3c2kit.base.errors import M3C2Error, UsageError, printable
from m3c2kit.io.arrays import as_coordinates
from m3c2kit.settings.limits import check_tile_size, usable_length


@pytest.mark.parametrize("n", [1, 2, 3, 4, 9])
def test_suggest_on_a_few_points_is_a_clear_error(tmp_path, capsys, n):
    """It raised IndexError (a traceback) on 2 or 3 points."""
    path = tmp_path / "few.xyz"
    np.savetxt(path, np.random.default_rng(n).uniform(0, 1, (n, 3)))
    assert main(["suggest", str(path), str(path)]) == 1
    assert capsys.readouterr().err == (f"m3c2: error: {path}: {n} points; suggest needs at least 10 "
                                       f"(sigma(D) is fitted to 10 neighbours, section 5.1)\n")


def test_suggest_on_a_line_or_a_sparse_cloud_is_a_clear_error():
    line = np.column_stack([np.arange(50.0), np.zeros(50), np.zeros(50)])
    with pytest.raises(M3C2Error, match=r"the reference cloud: the points span no surface"):
        suggest_parameters(line, line)
    sparse = np.random.default_rng(0).uniform(0, 1000, (12, 3))
    with pytest.raises(M3C2Error, match=r"no candidate D .* holds 10 neighbours"):
        suggest_parameters(sparse, sparse)


@pytest.mark.parametrize("key", ["MinPoints4Stat", "MaxThreadCount", "SearchDepth"])
def test_a_parameter_value_of_5000_digits_is_a_usage_error(tmp_path, key):
    """int() of 5,000 digits raised ValueError (Python's 4300-digit limit): a traceback."""
    path = tmp_path / "params.txt"
    path.write_text(f"[General]\n{key}={'9' * 5000}\n")
    with pytest.raises(UsageError) as err:
        read_cloudcompare_params(path)
    message = str(err.value)
    assert message.startswith(f"{path}: ") and "(5000 characters)" in message and len(message) < 300


@pytest.mark.parametrize("value", [5e-324, 1e-310, "5e-324"])
def test_denormal_lengths_are_refused_naming_the_option(value):
    with pytest.raises(UsageError, match=r"^--tile-size .* is too small to be a length \(below 2.23e-308"):
        usable_length("--tile-size", value)


@pytest.mark.parametrize("value", [0, -1, float("nan"), float("inf"), "1e400", "x", None])
def test_non_lengths_are_refused_naming_the_option(value):
    with pytest.raises(UsageError, match=r"^--grid must be"):
        usable_length("--grid", value)


def test_huge_and_normal_lengths_are_kept():
    assert usable_length("--tile-size", 1e300) == 1e300
    assert usable_length("--tile-size", "2.5") == 2.5


def test_a_tile_much_smaller_than_the_halo_is_refused():
    with pytest.raises(UsageError, match=r"^--tile-size 0.5 is too small for the halo of 30 .* read about 1.46e\+04 "
                                         r"times its own area; use --tile-size 15 or more"):
        check_tile_size(0.5, 30.0)
    check_tile_size(15.0, 30.0)


@pytest.mark.parametrize("values, what", [
    (np.ones((4, 3), dtype=bool), "booleans"),
    (np.ones((4, 3), dtype=complex), "complex numbers"),
    (np.full((4, 3), np.datetime64("2024-01-01")), "datetimes"),
    (np.full((4, 3), np.timedelta64(1, "s")), "timedeltas"),
    (np.full((4, 3), "1.5"), "strings"),
    (np.array([[1, 2, None]] * 4, dtype=object), "Python objects"),
    ([[datetime.date(2024, 1, 1)] * 3], "Python objects"),
])
def test_non_real_coordinate_arrays_are_refused_naming_the_argument(values, what):
    """np.asarray(..., dtype=float64) accepted complex (imaginary part dropped), bool, datetime."""
    with pytest.raises(UsageError, match=rf"^reference must be an \(N, 3\) array of real numbers, got {what}"):
        as_coordinates("reference", values)


def test_real_coordinate_arrays_are_viewed_or_converted():
    a = np.arange(12.0).reshape(4, 3)
    assert as_coordinates("reference", a) is a or np.shares_memory(as_coordinates("reference", a), a)
    np.testing.assert_array_equal(as_coordinates("reference", a.astype(np.int16)), a)
    np.testing.assert_array_equal(as_coordinates("reference", a.astype(np.float32)), a)
    with pytest.raises(UsageError, match=r"got shape \(12,\)"):
        as_coordinates("reference", a.ravel())


@pytest.mark.parametrize("raw, shown", [
    ("ok\tstill ok\nnext line", "ok\tstill ok\nnext line"),
    ("\x1b]0;pwned\x07title", "\\x1b]0;pwned\\x07title"),
    ("\x1b[2J\x1b[31mred", "\\x1b[2J\\x1b[31mred"),
    ("c1 csi \x9b31m", "c1 csi \\x9b31m"),
    ("del\x7f cr\r bs\x08", "del\\x7f cr\\x0d bs\\x08"),
    ("evil\u202etxt.exe", "evil\\u202etxt.exe"),
    ("caf\u00e9 \u6e2c", "caf\u00e9 \u6e2c"),
])
def test_printable_escapes_terminal_controls_and_keeps_text(raw, shown):
    assert printable(raw) == shown


# ----------------------------------------------------------- wired into the command line and API

def _escape_cloud(path):
    np.savetxt(path, np.random.default_rng(0).uniform(0, 1, (50, 3)))
    return path


def test_an_escape_sequence_in_a_file_name_reaches_no_terminal(tmp_path, capsys):
    """`m3c2: error: ...` printed the file name raw: ESC ] 0 ; retitles the terminal window."""
    name = tmp_path / "evil\x1b]0;pwned\x07\x1b[2J.bogus"
    name.write_text("1 2 3\n")
    assert main(["info", str(name)]) == 1
    err = capsys.readouterr().err
    assert "\x1b" not in err and "\x07" not in err
    assert "evil\\x1b]0;pwned\\x07\\x1b[2J.bogus" in err


def test_an_escape_sequence_in_a_las_wkt_reaches_no_terminal(tmp_path, capsys):
    import laspy
    las = laspy.LasData(laspy.LasHeader(version="1.4", point_format=6))
    las.x, las.y, las.z = np.arange(5.0), np.arange(5.0), np.arange(5.0)
    las.header.vlrs.append(laspy.vlrs.known.WktCoordinateSystemVlr('LOCAL_CS["\x1b[31mred\x1b]0;t\x07",UNIT["metre",1]]'))
    las.header.global_encoding.wkt = True
    path = tmp_path / "wkt.las"
    las.write(path)
    assert main(["info", str(path)]) == 0
    out = capsys.readouterr().out
    assert "\x1b" not in out and "\x07" not in out
    assert main(["info", "--json", str(path)]) == 0
    out = capsys.readouterr().out
    assert "\x1b" not in out and "\x07" not in out


def test_bootstrap_above_the_maximum_names_the_option(tmp_path, capsys):
    ref = _escape_cloud(tmp_path / "ref.xyz")
    assert main(["compare", str(ref), str(ref), "-o", str(tmp_path / "o.csv"), "--normal-scale", "1",
                 "--projection-scale", "1", "--max-depth", "1", "--bootstrap", "1000000000"]) == 2
    assert capsys.readouterr().err == ("m3c2: error: --bootstrap must be 0 (off) or >= 2 resamples, at most 100000, "
                                       "got 1000000000\n")
    assert not (tmp_path / "o.csv").exists()


@pytest.mark.parametrize("tile, message", [
    ("5e-324", "--tile-size 5e-324 is too small to be a length"),
    ("1e-6", "--tile-size 1e-06 is too small for the halo of"),
])
def test_tile_sizes_that_cannot_work_are_refused_naming_the_option(tmp_path, capsys, tile, message):
    """--tile-size 5e-324 was a traceback, 1e-6 said 'use fewer core points', and 0.5 beside a
    halo of 30 looped for minutes with memory growing."""
    ref = _escape_cloud(tmp_path / "ref.xyz")
    assert main(["compare", str(ref), str(ref), "-o", str(tmp_path / "o.csv"), "--normal-scale", "1",
                 "--projection-scale", "1", "--max-depth", "1", "--tile-size", tile]) == 2
    assert capsys.readouterr().err.startswith(f"m3c2: error: {message}")


@pytest.mark.parametrize("kind", ["complex", "bool", "datetime"])
def test_the_api_refuses_non_real_coordinates(kind):
    """complex (imaginary part dropped), bool and datetime arrays were computed on."""
    from m3c2kit import api
    good = np.random.default_rng(0).uniform(0, 1, (50, 3))
    bad = {"complex": good + 1j, "bool": good > 0.5, "datetime": np.full((50, 3), np.datetime64("2024-01-01"))}[kind]
    with pytest.raises(UsageError, match=r"^compared must be an \(N, 3\) array of real numbers"):
        api.compare(good, bad, normal_scale=1, projection_scale=1, max_depth=1)


def test_a_grid_too_fine_for_the_memory_is_refused_before_allocating(tmp_path, capsys, monkeypatch):
    """--grid 0.001 on a 20 m cloud took 8.6 GB: the rasters were not in the memory estimate."""
    rng = np.random.default_rng(0)
    cloud = np.column_stack([rng.uniform(0, 20, (400, 2)), rng.normal(0, 0.01, 400)])
    np.savetxt(tmp_path / "ref.xyz", cloud)
    monkeypatch.setenv("M3C2_AVAILABLE_MEMORY", str(2 * 2**30))
    out = tmp_path / "dod.laz"
    assert main(["compare", str(tmp_path / "ref.xyz"), str(tmp_path / "ref.xyz"), "-o", str(out), "--grid", "0.001",
                 "--max-depth", "1", "--quiet"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("m3c2: error: --grid 0.001 makes rasters of ") and "only 2.0 GiB is available" in err
    assert "use a larger --grid (at least about 0.00" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ref.xyz"]


@pytest.mark.parametrize("cell", ["5e-324", "0", "nan"])
def test_grid_sizes_that_are_not_lengths_are_refused(tmp_path, capsys, cell):
    ref = _escape_cloud(tmp_path / "ref.xyz")
    assert main(["compare", str(ref), str(ref), "-o", str(tmp_path / "o.laz"), "--grid", cell, "--max-depth", "1"]) == 2
    assert capsys.readouterr().err.startswith("m3c2: error: --grid ")


def test_a_closed_stdout_ends_quietly(tmp_path):
    """`m3c2 info x | head -1` printed a BrokenPipeError traceback."""
    import subprocess
    import sys
    from child_env import child_env
    path = _escape_cloud(tmp_path / "cloud.xyz")
    proc = subprocess.Popen([sys.executable, "-m", "m3c2kit", "info", str(path)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, env=child_env())
    proc.stdout.close()  # the reader is gone before the first line
    err = proc.stderr.read().decode()
    proc.wait(timeout=120)
    assert "Traceback" not in err and "BrokenPipeError" not in err, err
    assert proc.returncode == 1


def test_an_output_that_is_a_folder_says_so(tmp_path, capsys):
    """`-o adir` said "cannot write '' files"."""
    ref = _escape_cloud(tmp_path / "ref.xyz")
    (tmp_path / "adir").mkdir()
    assert main(["compare", str(ref), str(ref), "-o", str(tmp_path / "adir"), "--normal-scale", "1",
                 "--projection-scale", "1", "--max-depth", "1", "--quiet"]) == 1
    assert capsys.readouterr().err == f"m3c2: error: {tmp_path / 'adir'}: is a directory\n"


def test_an_empty_orientation_says_so(tmp_path, capsys):
    """`--orient ""` said ". is a directory" (Path("") is the working folder)."""
    ref = _escape_cloud(tmp_path / "ref.xyz")
    assert main(["compare", str(ref), str(ref), "-o", str(tmp_path / "o.csv"), "--normal-scale", "1",
                 "--projection-scale", "1", "--max-depth", "1", "--orient", "", "--quiet"]) == 2
    assert capsys.readouterr().err == ("m3c2: error: --orient is empty: give +x|-x|+y|-y|+z|-z, X,Y,Z, an "
                                       "existing FILE of points, origin, barycentre or sensor (away:POINT for "
                                       "away from a point)\n")


def test_a_nan_in_the_reference_is_the_references():
    """With the reference as its own core points (the default) the NaN was "in the core points"."""
    from m3c2kit import api
    ref = np.random.default_rng(0).uniform(0, 1, (100, 3))
    ref[5, 2] = np.nan
    with pytest.raises(UsageError, match=r"^reference cloud has 1 non-finite coordinates"):
        api.compare(ref, ref[::-1].copy(), normal_scale=1, projection_scale=1, max_depth=1)


_GOOD = np.random.default_rng(1).uniform(0, 1, (60, 3))
_KW = dict(normal_scale=0.5, projection_scale=0.5, max_depth=0.5)
_BAD_CALLS = [
    ("compare", (_GOOD, "cloud"), _KW), ("compare", (_GOOD, None), _KW), ("compare", (_GOOD, _GOOD[:, :2]), _KW),
    ("compare", (_GOOD, _GOOD + 1j), _KW), ("compare", (_GOOD, [[1, 2, [3]]]), _KW),
    ("compare", (_GOOD, _GOOD), dict(_KW, normal_scale="abc")), ("compare", (_GOOD, _GOOD), dict(_KW, normal_scale=-1)),
    ("compare", (_GOOD, _GOOD), dict(_KW, max_depth=float("nan"))), ("compare", (_GOOD, _GOOD), dict(_KW, bogus=1)),
    ("compare", (_GOOD, _GOOD), dict(_KW, threads=-1)), ("compare", (_GOOD, _GOOD), dict(_KW, threads="many")),
    ("compare", (_GOOD, _GOOD), dict(_KW, bootstrap=10**9)), ("compare", (_GOOD, _GOOD), dict(_KW, orient="")),
    ("compare", (_GOOD, _GOOD), dict(_KW, orient=object())), ("compare", (_GOOD, _GOOD), dict(_KW, confidence=2)),
    ("compare", (_GOOD, _GOOD), dict(_KW, min_points=1.5)), ("compare", (_GOOD, _GOOD), dict(_KW, seed=-1)),
    ("compare", (_GOOD, _GOOD), dict(_KW, core_points=np.zeros((0, 3)))),
    ("compare", (_GOOD, _GOOD), dict(_KW, progress=lambda done, total: False)),
    ("normals", (_GOOD,), dict(normal_scale=0)), ("normals", ("x",), dict(normal_scale=1)),
    ("subsample", (_GOOD, 0), {}), ("subsample", (_GOOD, "x"), {}), ("subsample", (None, 1), {}),
]


@pytest.mark.parametrize("fn, args, kwargs", _BAD_CALLS)
def test_the_api_raises_only_the_packages_exceptions(fn, args, kwargs):
    """ValueError, TypeError, AttributeError and m3c2kit._core.Cancelled escaped the API."""
    import m3c2kit
    with pytest.raises(M3C2Error):
        getattr(m3c2kit, fn)(*args, **kwargs)
