"""docs/errors.md, "Parameters", "Legitimate runs that need a warning", "Different CRS or units"
and "Memory": bad option values (exit 2 naming the option), CloudCompare parameter files with
unknown or malformed keys, the summary warnings for a too thin cylinder and a too short
--max-depth, the CRS/units check and --ignore-crs, and the memory estimate."""
from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

import m3c2kit
from m3c2kit import api, engine
from m3c2kit.run import memory
from m3c2kit.cli import compare as compare_cli
from m3c2kit.cli.main import main
from m3c2kit.run.diagnostics import cylinder_warnings as result_warnings
from m3c2kit.base.errors import CloudReadError
from m3c2kit.io import Cloud, files as io_files, guard, write_cloud_table
from m3c2kit.io.crs import crs_label, same_crs
from synthetic import grid

BASE = {"--normal-scale": "0.5", "--projection-scale": "0.3", "--max-depth": "0.5"}


def write_xyz(path: Path, xyz) -> Path:
    np.savetxt(path, np.atleast_2d(xyz), fmt="%.17g")
    return path


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out = capsys.readouterr()
    return code, out.out, out.err


def compare_args(d: Path, **overrides):
    opts = {k.lstrip("-"): v for k, v in BASE.items()}
    opts.update({k.replace("_", "-"): v for k, v in overrides.items()})
    flat = [x for k, v in opts.items() for x in ((f"--{k}", v) if v is not None else ())]
    return ["compare", d / "ref.xyz", d / "cmp.xyz", "-o", d / "out.csv", "--quiet", *flat]


# ------------------------------------------------------------------------------- parameters

BAD_VALUES = [
    ("normal-scale", "0", "--normal-scale must be finite and > 0, got '0'"),
    ("normal-scale", "-1", "--normal-scale must be finite and > 0, got '-1'"),
    ("normal-scale", "nan", "--normal-scale must be finite and > 0, got 'nan'"),
    ("normal-scale", "inf", "--normal-scale must be finite and > 0, got 'inf'"),
    ("normal-scale", "1:0.5:0.1", "--normal-scale range '1:0.5:0.1': the largest scale 0.5 is below the smallest 1.0"),
    ("normal-scale", ",", "--normal-scale is empty"),
    ("projection-scale", "0", "--projection-scale must be finite and > 0, got 0.0"),
    ("projection-scale", "-1", "--projection-scale must be finite and > 0, got -1.0"),
    ("projection-scale", "nan", "--projection-scale must be finite and > 0, got nan"),
    ("projection-scale", "inf", "--projection-scale must be finite and > 0, got inf"),
    ("max-depth", "0", "--max-depth must be finite and > 0, got 0.0"),
    ("max-depth", "-1", "--max-depth must be finite and > 0, got -1.0"),
    ("max-depth", "nan", "--max-depth must be finite and > 0, got nan"),
    ("registration-error", "-1", "--registration-error must be finite and >= 0, got -1.0"),
    ("registration-error", "nan", "--registration-error must be finite and >= 0, got nan"),
    ("confidence", "0", "--confidence must be in (0, 1), got 0.0"),
    ("confidence", "1", "--confidence must be in (0, 1), got 1.0"),
    ("confidence", "nan", "--confidence must be in (0, 1), got nan"),
    ("min-points", "0", "--min-points must be an integer >= 1, got 0"),
    ("min-points", "-1", "--min-points must be an integer >= 1, got -1"),
    ("min-points", str(2**40), "--min-points must be an integer >= 1, at most 4294967295, got 1099511627776"),
    ("min-points", "nan", "argument --min-points: invalid int value: 'nan'"),
    ("bootstrap", "1", "--bootstrap must be 0 (off) or >= 2 resamples, got 1"),
    ("bootstrap", "-3", "--bootstrap must be 0 (off) or >= 2 resamples, got -3"),
    ("seed", "-1", "--seed must be a non-negative integer, got -1"),
    ("seed", str(2**64), "--seed must be a non-negative integer, at most 18446744073709551615, got 18446744073709551616"),
    ("threads", "-1", "--threads must be 0 (all) or a positive integer, got -1"),
    ("threads", str(10**12), "--threads must be 0 (all) or a positive integer, at most 2147483647, got 1000000000000"),
    ("core-spacing", "0", "--core-spacing must be finite and > 0, got 0.0"),
    ("core-spacing", "nan", "--core-spacing must be finite and > 0, got nan"),
    ("first-pass-depth", "0", "--first-pass-depth must be finite and > 0, got 0.0"),
    ("first-pass-depth", "2", "--first-pass-depth (2.0) must not exceed --max-depth (0.5)"),
    ("normal-subsample", "-1", "--normal-subsample must be finite and > 0, got -1.0"),
    ("orient", "0,0,nan", "--orient point must be finite, got '0,0,nan'"),
    ("orient", "sideways", "--orient must be +x|-x|+y|-y|+z|-z, X,Y,Z, an existing FILE of points, origin, barycentre or sensor (away:POINT for away from a point), got 'sideways'"),
]


@pytest.mark.parametrize("option, value, message", BAD_VALUES, ids=[f"{o}={v}" for o, v, _ in BAD_VALUES])
def test_bad_values_exit_2_naming_the_option(pair, capsys, option, value, message):
    code, _, err = run(capsys, *compare_args(pair, **{option: value}))
    assert code == 2
    assert err.strip().splitlines()[-1] == f"m3c2: error: {message}"
    assert not (pair / "out.csv").exists()


def test_missing_required_options(pair, capsys):
    """The Python API requires every scale; the command line chooses a missing one from the data
    (tests/python/cli/test_auto_scales.py), except in a tiled run."""
    import m3c2kit
    from m3c2kit.base.errors import UsageError
    with pytest.raises(UsageError, match=r"^--max-depth is required \(or a --params file that sets it\)$"):
        m3c2kit.compare(pair / "ref.xyz", pair / "cmp.xyz", normal_scale=0.5, projection_scale=0.3)
    code, out, err = run(capsys, *compare_args(pair, max_depth=None))
    assert code == 0 and err == "" and (pair / "out.csv").exists()
    code, _, err = run(capsys, *compare_args(pair, max_depth=None), "--tile-size", "5")
    assert code == 2 and "--max-depth missing" in err


PARAMS = ("[General]\nM3C2VER=1\nNormalScale=0.5\nNormalMode=0\nSearchScale=0.3\nSearchDepth=0.5\n"
          "UseSinglePass4Depth=true\n")


@pytest.mark.parametrize("extra, message", [
    ("Bogus=1\n", "unknown CloudCompare parameter 'Bogus'"),
    ("searchdepth=1\n", "CloudCompare parameter 'searchdepth' must be spelled 'SearchDepth' (keys are case-sensitive)"),
    ("MinPoints4Stat=four\n", "malformed value for MinPoints4Stat: 'four' (expected an integer)"),
    ("UseMedian=maybe\n", "malformed value for UseMedian: 'maybe' (expected true or false)"),
    ("RegistrationError=nan\n", "malformed value for RegistrationError: 'nan' (expected a finite number)"),
    ("no equals sign\n", "line 8: cannot parse 'no equals sign' (expected Key=value)"),
    ("NormalMode=1\n", "line 8: duplicate key 'NormalMode'"),
])
def test_cloudcompare_params_unknown_or_malformed_keys_exit_2(pair, capsys, extra, message):
    params = pair / "params.txt"
    params.write_text(PARAMS + extra)
    code, _, err = run(capsys, "compare", pair / "ref.xyz", pair / "cmp.xyz", "-o", pair / "out.csv", "--params",
                       params)
    assert code == 2
    assert err == f"m3c2: error: {params}: {message}\n"
    assert not (pair / "out.csv").exists()


def test_cloudcompare_params_good_file_runs(pair, capsys):
    params = pair / "params.txt"
    params.write_text(PARAMS)
    code, _, err = run(capsys, "compare", pair / "ref.xyz", pair / "cmp.xyz", "-o", pair / "out.csv", "--params",
                       params, "--quiet")
    assert code == 0, err


# -------------------------------------------------------------------------------- warnings

def _noisy_pair(d: Path, change=0.1, n=40, spacing=0.05):
    rng = np.random.default_rng(0)
    ref = grid(n, spacing)
    cmp = grid(n, spacing, change)
    ref[:, 2] += rng.normal(0, 0.002, len(ref))
    cmp[:, :2] += rng.uniform(-spacing / 3, spacing / 3, (len(cmp), 2))
    cmp[:, 2] += rng.normal(0, 0.002, len(cmp))
    write_xyz(d / "ref.xyz", ref)
    write_xyz(d / "cmp.xyz", cmp)


def test_no_warning_on_a_well_parameterised_run(tmp_path, capsys):
    _noisy_pair(tmp_path)
    code, out, err = run(capsys, *compare_args(tmp_path)[:-7], "--normal-scale", "0.5", "--projection-scale", "0.3",
                         "--max-depth", "0.5")
    assert code == 0 and "warning:" not in out + err


def test_projection_scale_below_the_point_spacing_warns(tmp_path, capsys):
    _noisy_pair(tmp_path)  # spacing 0.05; d = 0.04 holds about one point per cloud
    argv = ["compare", tmp_path / "ref.xyz", tmp_path / "cmp.xyz", "-o", tmp_path / "out.csv",
            "--normal-scale", "0.5", "--projection-scale", "0.04", "--max-depth", "0.5"]
    code, out, err = run(capsys, *argv)
    assert code == 0
    lines = [line for line in err.splitlines() if line.startswith("m3c2: warning: the median cylinder")]
    assert len(lines) == 1 and "warning" not in out  # warnings go to stderr (issue 13)
    assert "fewer than --min-points 4" in lines[0] and "consider a larger --projection-scale" in lines[0]
    code, out, err = run(capsys, *argv, "--quiet")  # --quiet: the warning still goes to stderr
    assert code == 0 and out == ""
    assert "m3c2: warning: the median cylinder holds" in err


def test_max_depth_shorter_than_the_change_warns(tmp_path, capsys):
    _noisy_pair(tmp_path, change=0.5)
    code, out, err = run(capsys, "compare", tmp_path / "ref.xyz", tmp_path / "cmp.xyz", "-o", tmp_path / "out.csv",
                         "--normal-scale", "0.5", "--projection-scale", "0.3", "--max-depth", "0.2")
    assert code == 0
    assert "status: empty_cylinder_compared 1600" in out
    # The compared points are there, 0.5 along the normal: the depth is too short, and by how much
    # (m3c2kit.run.quality; tests/python/run/test_quality.py for the no-overlap case, which never advises it).
    line = [x for x in err.splitlines() if "only beyond --max-depth" in x]
    assert len(line) == 1 and line[0].startswith("m3c2: warning: 1,600 of the 1,600 core points with a normal "
                                                 "(100.0 %) have compared points only beyond --max-depth 0.2")
    assert "--max-depth 0.51 reaches 95 % of them" in line[0] and "overlap" not in err


def _fake(status, n1, n2):
    return SimpleNamespace(status=np.asarray(status, np.uint8), n1=np.asarray(n1, np.uint32),
                           n2=np.asarray(n2, np.uint32))


def test_warning_thresholds():
    # Empty cylinders in one cloud are diagnosed by m3c2kit.run.quality (no overlap vs depth too
    # short, test_quality.py); result_warnings no longer advises a depth blindly.
    n = 100
    n1, n2 = np.full(n, 20), np.full(n, 20)
    n2[:11] = 0
    assert result_warnings(_fake(np.where(n2 == 0, 4, 0), n1, n2), 4) == []
    # Both clouds empty is not "one cloud only" (the surface is absent in both: a gap).
    assert result_warnings(_fake(np.full(n, 3), np.zeros(n), np.zeros(n)), 4)[:1] == [
        "the median cylinder holds n1 = 0, n2 = 0 points, fewer than --min-points 4: the projection scale "
        "d = None is small for the point spacing and most LODs are NaN; consider a larger --projection-scale"]
    # Median exactly min_points: no warning.
    assert result_warnings(_fake(np.zeros(3), [4, 4, 3], [4, 5, 4]), 4) == []
    assert result_warnings(_fake([1, 2], [0, 0], [0, 0]), 4) == []  # no cylinder searched at all


# ------------------------------------------------------------------------------- CRS / units

def _wkt(name: str, code: int, unit=('metre', 1)) -> str:
    return (f'PROJCS["{name}",GEOGCS["WGS 84",DATUM["WGS_1984",SPHEROID["WGS 84",6378137,298.257223563]],'
            f'PRIMEM["Greenwich",0],UNIT["degree",0.0174532925199433]],PROJECTION["Transverse_Mercator"],'
            f'PARAMETER["central_meridian",9],PARAMETER["scale_factor",0.9996],PARAMETER["false_easting",500000],'
            f'UNIT["{unit[0]}",{unit[1]}]' + (f',AUTHORITY["EPSG","{code}"]' if code else "") + "]")


def _las(path: Path, xyz, crs: str | None):
    write_cloud_table(path, xyz, {}, like=Cloud(grid()[:1], crs=crs, scale=(0.001,) * 3, offset=(0.0,) * 3))
    return path


def test_different_crs_is_an_error_naming_both(tmp_path, capsys):
    ref = _las(tmp_path / "ref.las", grid(), _wkt("WGS 84 / UTM zone 32N", 32632))
    cmp = _las(tmp_path / "cmp.las", grid(z=0.1), _wkt("WGS 84 / UTM zone 33N", 32633))
    argv = ["compare", ref, cmp, "-o", tmp_path / "out.csv", *[x for kv in BASE.items() for x in kv], "--quiet"]
    code, _, err = run(capsys, *argv)
    assert code == 1
    assert err == (f"m3c2: error: the clouds have different CRSs: reference {ref} is in 'WGS 84 / UTM zone 32N' "
                   f"(EPSG:32632), compared {cmp} in 'WGS 84 / UTM zone 33N' (EPSG:32633); reproject one of them, "
                   f"or pass --ignore-crs if the coordinates are comparable\n")
    assert not (tmp_path / "out.csv").exists()
    code, _, err = run(capsys, *argv, "--ignore-crs")
    assert code == 0, err


def test_different_units_is_an_error(tmp_path, capsys, shared_data):
    ref = _las(tmp_path / "ref.las", grid(), _wkt("site grid", 0, ("US survey foot", 0.304800609601219)))
    # The compared file has GeoTIFF keys only (EPSG:26916, metre), the reference a local grid in feet.
    utm = m3c2kit.read(shared_data / "readers/pdal/las/test_utm16.las")
    cmp = tmp_path / "cmp.las"
    write_cloud_table(cmp, grid(z=0.1) + utm.offset, {}, like=utm)
    assert m3c2kit.read(cmp).units_hint == "metre" and m3c2kit.read(ref).units_hint == "US survey foot"
    code, _, err = run(capsys, "compare", ref, cmp, "-o", tmp_path / "out.csv", "--quiet",
                       *[x for kv in BASE.items() for x in kv])
    assert code == 1
    # With pyproj the two CRSs are told apart first (a local grid in feet vs UTM 16N).
    assert err == (f"m3c2: error: the clouds have different CRSs: reference {ref} is in 'site grid', compared "
                   f"{cmp} in 'NAD83 / UTM zone 16N' (EPSG:26916); reproject one of them, or pass --ignore-crs "
                   f"if the coordinates are comparable\n")


def test_core_points_crs_is_checked_too(tmp_path, capsys):
    ref = _las(tmp_path / "ref.las", grid(), _wkt("WGS 84 / UTM zone 32N", 32632))
    cmp = _las(tmp_path / "cmp.las", grid(z=0.1), _wkt("WGS 84 / UTM zone 32N", 32632))
    core = _las(tmp_path / "core.las", grid()[::7], _wkt("WGS 84 / UTM zone 31N", 32631))
    code, _, err = run(capsys, "compare", ref, cmp, "--core", core, "-o", tmp_path / "out.csv", "--quiet",
                       *[x for kv in BASE.items() for x in kv])
    assert code == 1 and f"core points {core} in 'WGS 84 / UTM zone 31N' (EPSG:32631)" in err


def test_same_crs_spelled_differently_and_unknown_crs_pass(autzen_pair, tmp_path, capsys):
    pair = autzen_pair
    a, b = m3c2kit.read(pair / "autzen-bmx-2010.las"), m3c2kit.read(pair / "autzen-bmx-2023.las")
    assert a.crs != b.crs and same_crs(a.crs, b.crs) is True  # two WKT spellings of one compound CRS
    compare_cli.check_same_crs(a, b)
    # A cloud without CRS (text) against one with a CRS: refused (issue 13), unless --ignore-crs
    # or --crs gives it the reference's.
    write_xyz(tmp_path / "cmp.xyz", grid(z=0.1))
    ref = _las(tmp_path / "ref.las", grid(), _wkt("WGS 84 / UTM zone 32N", 32632))
    argv = ["compare", ref, tmp_path / "cmp.xyz", "-o", tmp_path / "out.csv", "--quiet",
            *[x for kv in BASE.items() for x in kv]]
    code, _, err = run(capsys, *argv)
    assert code == 1 and "only one cloud has a CRS" in err and str(tmp_path / "cmp.xyz") in err, err
    for extra in (["--ignore-crs"], ["--crs", "EPSG:32632"]):
        code, _, err = run(capsys, *argv, *extra)
        assert code == 0, err


def test_same_crs_rules():
    utm32, utm33 = _wkt("WGS 84 / UTM zone 32N", 32632), _wkt("WGS 84 / UTM zone 33N", 32633)
    assert same_crs(utm32, utm32.replace(",", ", ")) is True
    assert same_crs(utm32, "EPSG:32632") is True
    assert same_crs(utm32, "EPSG:32633") is False and same_crs(utm32, utm33) is False
    assert same_crs("EPSG:2992", "EPSG:2992") is True
    assert same_crs(None, utm32) is None and same_crs(utm32, "") is None
    # pyproj compares definitions: a WKT without authority with UTM 32N's parameters is UTM 32N,
    # whatever its name; another central meridian is another CRS.
    assert same_crs(_wkt("local", 0), "EPSG:32632") is True
    assert same_crs(_wkt("a", 0), _wkt("b", 0).replace('"central_meridian",9', '"central_meridian",15')) is False
    assert same_crs(_wkt("a", 0), "not a CRS[]") is None  # PROJ cannot read it: unknown, never refused
    assert crs_label(utm32) == "'WGS 84 / UTM zone 32N' (EPSG:32632)" and crs_label(None) == "unknown"


# ----------------------------------------------------------------------------------- memory

def test_estimate_memory_formula():
    from m3c2kit.settings import build_params
    mem = engine.INDEX_MEMORY
    copied, moments = mem["bytes_per_point"] + mem["copy_bytes_per_point"], mem["moments_bytes_per_point"]
    assert memory.estimate_memory(0, 0, 0) == 0
    # The default normals are the reference's: its node moments, none on the compared cloud.
    assert memory.estimate_memory(1000, 2000, 0) == int((1000 * (copied + moments) + 2000 * copied) * mem["overhead"])
    assert memory.estimate_memory(0, 0, 1000) == mem["bytes_per_core_point"] * 1000
    big = memory.estimate_memory(10**9, 10**9, 10**8)
    assert big == int((10**9 * (2 * copied + moments)) * mem["overhead"] + mem["bytes_per_core_point"] * 10**8)
    # Normals on both clouds: moments on both; given core normals: none.
    both = build_params(normal_scale=1, projection_scale=1, max_depth=1, normal_source="mean")
    assert memory.estimate_memory(1000, 1000, 0, both) == int(2000 * (copied + moments) * mem["overhead"])
    given = build_params(projection_scale=1, max_depth=1, normal_source="core")
    assert memory.estimate_memory(1000, 1000, 0, given) == int(2000 * copied * mem["overhead"])
    # Ordered in place: no copies, unless an uncertainty model forbids it.
    in_place = mem["bytes_per_point"]
    assert memory.estimate_memory(1000, 1000, 0, given, reorder_inputs=True) == int(2000 * in_place * mem["overhead"])
    ep = build_params(projection_scale=1, max_depth=1, normal_source="core", uncertainty="ep")
    assert memory.estimate_memory(1000, 1000, 0, ep, reorder_inputs=True) == int(2000 * copied * mem["overhead"])


def test_check_memory_with_injected_available_memory():
    needed = memory.estimate_memory(10**6, 10**6, 10**5)
    assert memory.check_memory(10**6, 10**6, 10**5, available=needed) == needed
    with pytest.raises(memory.InsufficientMemory) as err:
        memory.check_memory(10**6, 10**6, 10**5, available=needed - 1)
    message = str(err.value)
    assert message.startswith("not enough memory: this run needs about 177.7 MiB (spatial index of 1000000 + "
                              "1000000 points, results for 100000 core points) but only 177.7 MiB is available")
    assert "--tile-size" in message and "fewer core points" in message


def test_compare_checks_memory_before_computing(monkeypatch):
    monkeypatch.setenv(guard.MEMORY_ENV, "1000")
    with pytest.raises(memory.InsufficientMemory):
        m3c2kit.compare(grid(), grid(z=0.1), normal_scale=0.5, projection_scale=0.3, max_depth=0.5)


def test_cli_exits_1_when_the_run_needs_more_memory(pair, capsys, monkeypatch):
    # The files (~10 KiB each) fit; the run (the indexes, ordered in place, + 400 core points ~ 95 KiB) does not.
    monkeypatch.setenv(guard.MEMORY_ENV, "30000")
    code, _, err = run(capsys, *compare_args(pair))
    assert code == 1
    assert err.startswith("m3c2: error: not enough memory: this run needs about 95.3 KiB")
    assert "--tile-size" in err
    assert not (pair / "out.csv").exists()


def test_file_too_big_for_memory_is_refused_before_reading(pair, capsys, monkeypatch, shared_data):
    las = shared_data / "readers/laspy/simple.las"  # 1065 points of 34 bytes (format 3)
    assert io_files.estimated_read_bytes(las) == 1065 * (24 + 34)
    assert io_files.estimated_read_bytes(pair / "ref.xyz") == (pair / "ref.xyz").stat().st_size
    with pytest.raises(CloudReadError, match=r"simple.las: reading it needs at least 60.3 KiB of memory but only "
                                             r"1000 bytes is available"):
        io_files._check_read_memory(las, None, available=1000)
    io_files._check_read_memory(las, None, available=1065 * 58)
    monkeypatch.setenv(guard.MEMORY_ENV, "1000")
    code, _, err = run(capsys, "compare", las, pair / "cmp.xyz", "-o", pair / "out.csv", "--quiet",
                       *[x for kv in BASE.items() for x in kv])
    assert code == 1 and err.startswith(f"m3c2: error: {las}: reading it needs at least")


def test_available_memory_sources(monkeypatch, tmp_path):
    monkeypatch.delenv(guard.MEMORY_ENV, raising=False)
    limit, usage = tmp_path / "memory.max", tmp_path / "memory.current"
    limit.write_text("1000000\n")
    usage.write_text("400000\n")
    monkeypatch.setattr(guard, "_CGROUP_FILES", ((str(limit), str(usage)),))
    assert guard.available_memory() == 600000  # the cgroup's room is far below the machine's
    limit.write_text("max\n")
    machine = guard.available_memory()
    assert machine is not None and machine > 600000
    monkeypatch.setenv(guard.MEMORY_ENV, "12345")
    assert guard.available_memory() == 12345
