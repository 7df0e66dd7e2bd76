"""The command line end to end: real files in every format, outputs read back, errors."""
import csv
import subprocess
import sys

import laspy
import numpy as np
import pytest

import m3c2kit
from m3c2kit.io.fields import typed_columns
from m3c2kit.io.quantised import Quantised
from m3c2kit.cli.main import main
from m3c2kit.engine.result import COLUMNS

from synthetic import noisy_plane_pair, write_xyz

BASE = ["--normal-scale", "0.5", "--projection-scale", "0.3", "--max-depth", "0.5", "--quiet"]


def read_csv(path):
    with open(path) as f:
        rows = list(csv.reader(f))
    header, body = rows[0], np.array(rows[1:], dtype=float)
    return header, {name: body[:, k] for k, name in enumerate(header)}


@pytest.fixture
def xyz_pair(tmp_path):
    ref, cmp = noisy_plane_pair(n=50, offset=0.1)
    write_xyz(tmp_path / "ref.xyz", ref)
    write_xyz(tmp_path / "cmp.xyz", cmp)
    core = ref[(ref[:, 0] > 0.5) & (ref[:, 0] < 2) & (ref[:, 1] > 0.5) & (ref[:, 1] < 2)][::5]
    write_xyz(tmp_path / "core.xyz", core)
    return tmp_path, ref, cmp, core


def test_issue_example_command_writes_the_columns(xyz_pair):
    d, ref, cmp, core = xyz_pair
    out = d / "out.csv"
    code = main(["compare", str(d / "ref.xyz"), str(d / "cmp.xyz"), "--core", str(d / "core.xyz"), "-o", str(out),
                 "--normal-scale", "2", "--projection-scale", "0.5", "--max-depth", "1", "--orient", "0,0,10"])
    assert code == 0
    header, cols = read_csv(out)
    assert tuple(header) == COLUMNS
    assert len(cols["x"]) == len(core)
    np.testing.assert_array_equal(np.column_stack([cols["x"], cols["y"], cols["z"]]), core)
    assert abs(np.nanmean(cols["distance"]) - 0.1) < 2e-3


def test_csv_output_equals_the_api(xyz_pair):
    d, ref, cmp, core = xyz_pair
    out = d / "out.csv"
    assert main(["compare", str(d / "ref.xyz"), str(d / "cmp.xyz"), "--core", str(d / "core.xyz"), "-o", str(out)] + BASE) == 0
    _, cols = read_csv(out)
    api = m3c2kit.compare(ref, cmp, core, normal_scale=0.5, projection_scale=0.3, max_depth=0.5).columns()
    stored = typed_columns(api)  # measured values as float32, counts uint32 (m3c2kit.io.fields)
    for name in COLUMNS:
        np.testing.assert_array_equal(cols[name], np.asarray(stored[name], dtype=float), err_msg=name)


@pytest.mark.parametrize("ext", [".las", ".laz", ".ply", ".csv"])
def test_every_output_format_reads_back_field_by_field(xyz_pair, ext):
    d, ref, cmp, core = xyz_pair
    out = d / f"out{ext}"
    assert main(["compare", str(d / "ref.xyz"), str(d / "cmp.xyz"), "--core", str(d / "core.xyz"), "-o", str(out)] + BASE) == 0
    back = m3c2kit.read(out)
    api = m3c2kit.compare(ref, cmp, core, normal_scale=0.5, projection_scale=0.3, max_depth=0.5).columns()
    atol = 0.0005 if ext in (".las", ".laz") else 0.0  # LAS stores coordinates at the 1 mm scale
    np.testing.assert_allclose(back.xyz, core, atol=atol, rtol=0)
    las = ext in (".las", ".laz")
    # The stored types: float32 measures, exact after the cast; LAS: CloudCompare's columns as
    # scaled integers (m3c2kit.io.quantised), read back as float64 with NaN for no_data.
    table = {k: v for k, v in api.items() if k not in ("x", "y", "z")}
    stored = {k: _as_read(v) for k, v in typed_columns(table, las=las).items()}
    if las:
        assert set(stored) <= set(back.fields) and "nx" not in back.fields
    for name in stored:
        if ext != ".csv":  # text has no types: its values read back as float64
            assert back.fields[name].dtype == stored[name].dtype, name
        np.testing.assert_array_equal(np.asarray(back.fields[name], dtype=float),
                                      np.asarray(stored[name], dtype=float), err_msg=name)


def _as_read(column):
    """A column as a reader gives it back: a Quantised one decoded (NaN where no_data)."""
    if not isinstance(column, Quantised):
        return np.asarray(column)
    raw = column.encoded()
    value = raw.astype(np.float64) if column.scale is None else raw * column.scale
    return np.where(raw == column.no_data, np.nan, value)


def test_real_las_pair_with_cloudcompare_params(tmp_path, autzen_pair):
    pair = autzen_pair
    params = tmp_path / "m3c2_params.txt"
    params.write_text("[General]\nM3C2VER=1\nNormalScale=2.780864\nNormalMode=0\nNormalPreferedOri=4\n"
                      "SearchScale=5.780864\nSearchDepth=5.5\nUseSinglePass4Depth=true\nSubsampleEnabled=false\n"
                      "RegistrationErrorEnabled=false\nUseMedian=false\nUseMinPoints4Stat=false\nProjDestIndex=2\n"
                      "ExportStdDevInfo=true\nExportDensityAtProjScale=true\nMaxThreadCount=2\n")
    out = tmp_path / "out.laz"
    code = main(["compare", str(pair / "autzen-bmx-2010.las"), str(pair / "autzen-bmx-2023.las"), "--core",
                 str(pair / "autzen-bmx-largersample.txt"), "-o", str(out), "--params", str(params), "--quiet"])
    assert code == 0
    las = laspy.read(out)
    src_crs = m3c2kit.read(pair / "autzen-bmx-2010.las").crs
    assert src_crs is not None and m3c2kit.read(out).crs == src_crs  # the reference's CRS is kept
    assert len(las.points) == 103
    # CloudCompare's 6 zero normals are NaN here (stored as the distance's no_data value)
    assert np.isnan(m3c2kit.read(out).fields["distance"]).sum() >= 6


@pytest.mark.parametrize("args, code, message", [
    (["compare", "missing.xyz", "cmp.xyz", "-o", "o.csv"] + BASE, 1, "missing.xyz"),
    (["compare", "ref.xyz", "cmp.xyz", "-o", "o.csv", "--projection-scale", "-1", "--normal-scale", "1",
      "--max-depth", "1"], 2, "--projection-scale"),
    (["compare", "ref.xyz", "cmp.xyz", "-o", "o.csv", "--normal-scale", "1", "--max-depth", "1", "--tile-size", "5"], 2,
     "--projection-scale"),  # without --tile-size, chosen from the data (test_auto_scales.py)
    (["compare", "ref.xyz", "cmp.xyz", "-o", "o.csv", "--bogus"] + BASE, 2, "bogus"),
    (["compare", "ref.xyz", "cmp.xyz", "-o", "o.unknownext"] + BASE, 1, "o.unknownext"),
])
def test_errors_exit_codes_and_no_output(xyz_pair, capsys, monkeypatch, args, code, message):
    d = xyz_pair[0]
    monkeypatch.chdir(d)
    assert main(args) == code
    err = capsys.readouterr().err
    assert message in err
    assert not any(p.name.startswith("o.") for p in d.iterdir())


def test_unwritable_output_leaves_nothing(xyz_pair, capsys):
    d = xyz_pair[0]
    blocker = d / "file"
    blocker.write_text("x")
    assert main(["compare", str(d / "ref.xyz"), str(d / "cmp.xyz"), "-o", str(blocker / "out.csv")] + BASE) == 1
    assert str(blocker / "out.csv") in capsys.readouterr().err


def test_summary_is_printed(xyz_pair):
    d = xyz_pair[0]
    proc = subprocess.run([sys.executable, "-m", "m3c2kit", "compare", str(d / "ref.xyz"), str(d / "cmp.xyz"), "--core",
                           str(d / "core.xyz"), "-o", str(d / "o.csv")] + BASE[:-1], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert "core points" in proc.stdout and "status: ok" in proc.stdout and "xi > 20" in proc.stdout


def test_subsample_normals_and_info_commands(xyz_pair, capsys):
    d, ref, _, _ = xyz_pair
    assert main(["subsample", str(d / "ref.xyz"), "-o", str(d / "sub.csv"), "--spacing", "0.2"]) == 0
    sub = m3c2kit.read(d / "sub.csv").xyz
    dist = np.linalg.norm(sub[:, None] - sub[None], axis=-1)
    np.fill_diagonal(dist, np.inf)
    assert dist.min() >= 0.2
    assert main(["normals", str(d / "sub.csv"), "-o", str(d / "n.csv"), "--normal-scale", "0.5,1", "--quiet"]) == 0
    header, cols = read_csv(d / "n.csv")
    assert {"nx", "ny", "nz", "normal_scale", "roughness", "status"} <= set(header)
    ok = cols["status"] == 0
    assert ok.mean() > 0.9 and np.all(cols["nz"][ok] > 0.99)
    assert main(["info", str(d / "ref.xyz")]) == 0
    assert str(len(ref)) in capsys.readouterr().out


def test_orient_file_of_scanner_positions(xyz_pair):
    d, ref, cmp, core = xyz_pair
    write_xyz(d / "scanners.xyz", np.array([[1.0, 1.0, -5.0], [100.0, 100.0, -5.0]]))
    out = d / "o.csv"
    assert main(["compare", str(d / "ref.xyz"), str(d / "cmp.xyz"), "--core", str(d / "core.xyz"), "-o", str(out),
                 "--orient", str(d / "scanners.xyz")] + BASE) == 0
    _, cols = read_csv(out)
    assert np.all(cols["nz"] < -0.99)  # towards the scanners below
    assert abs(np.mean(cols["distance"]) + 0.1) < 2e-3  # the change is signed along the normal
