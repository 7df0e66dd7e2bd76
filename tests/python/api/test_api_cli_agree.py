"""The API and the command line are one house (issue 32): the same inputs give the same output
bytes whether a user calls m3c2kit.compare on m3c2kit.read clouds and writes with m3c2kit.write, or
runs `m3c2 compare`. In particular the default orientation is one rule (settings.orientation): an
E57 reference with a scanner pose orients the normals towards the scanner in both."""
from __future__ import annotations

import filecmp
import shutil
from pathlib import Path

import numpy as np
import pytest

import m3c2kit
from m3c2kit.cli.main import main
from m3c2kit.io import read_cloud, write_cloud_table
from m3c2kit.settings.cloudcompare_params import read_cloudcompare_params

PAIRS = Path(__file__).resolve().parents[2] / "data" / "pairs" / "autzen-bmx"
PARAMS = {"normal_scale": 1.0, "projection_scale": 0.6, "max_depth": 1.0}
FLAGS = ["--normal-scale", "1.0", "--projection-scale", "0.6", "--max-depth", "1.0"]


def _ceiling(z: float, seed: int) -> np.ndarray:
    """A rough 6 m x 6 m ceiling at height z (points 0.1 m apart, 5 mm of noise)."""
    g = np.arange(-3.0, 3.0, 0.1)
    x, y = np.meshgrid(g, g)
    rng = np.random.default_rng(seed)
    return np.column_stack([x.ravel(), y.ravel(), z + 0.005 * rng.standard_normal(x.size)])


def _e57(path: Path, points: np.ndarray, scanner) -> None:
    pye57 = pytest.importorskip("pye57")
    local = points - np.asarray(scanner, float)
    with pye57.E57(str(path), mode="w") as out:
        out.write_scan_raw({"cartesianX": local[:, 0], "cartesianY": local[:, 1], "cartesianZ": local[:, 2]},
                           name="scan", rotation=np.array([1.0, 0.0, 0.0, 0.0]), translation=np.asarray(scanner, float))


def _api_equals_cli(tmp_path, ref: Path, cmp_: Path, suffix: str, params: dict, flags: list[str]) -> m3c2kit.Result:
    reference, compared = m3c2kit.read(ref), m3c2kit.read(cmp_)
    result = m3c2kit.compare(reference, compared, threads=2, **params)
    m3c2kit.write(tmp_path / f"api{suffix}", result, like=reference)
    assert main(["compare", str(ref), str(cmp_), "-o", str(tmp_path / f"cli{suffix}"), "--threads", "2", "-q",
                 *flags]) == 0
    assert filecmp.cmp(tmp_path / f"api{suffix}", tmp_path / f"cli{suffix}", shallow=False)
    return result


def test_an_e57_ceiling_scanned_from_below_has_one_sign(tmp_path):
    """The issue's example: the compared ceiling is 0.1 higher, the scanner below it. The normals
    point to the scanner (down) in both, so the ceiling moved away from it: -0.1 in both."""
    scanner = (0.5, -0.25, 0.0)
    _e57(tmp_path / "ref.e57", _ceiling(10.0, 1), scanner)
    _e57(tmp_path / "cmp.e57", _ceiling(10.1, 2), scanner)
    result = _api_equals_cli(tmp_path, tmp_path / "ref.e57", tmp_path / "cmp.e57", ".csv", PARAMS, FLAGS)
    ok = np.isfinite(result.distance)
    assert ok.mean() > 0.9
    assert np.median(result.distance[ok]) == pytest.approx(-0.1, abs=0.005)
    assert result.params["orient"] == "sensor"
    # An explicit --orient +z flips it, in both.
    flipped = _api_equals_cli(tmp_path, tmp_path / "ref.e57", tmp_path / "cmp.e57", "_z.csv",
                              dict(PARAMS, orient="+z"), FLAGS + ["--orient", "+z"])
    assert np.median(flipped.distance[ok]) == pytest.approx(0.1, abs=0.005)


def test_the_core_points_clouds_own_scanner_comes_first(tmp_path):
    """--core from an E57 with its own pose: that scanner orients (CloudCompare's rule), in both."""
    _e57(tmp_path / "ref.e57", _ceiling(10.0, 1), (0.0, 0.0, 20.0))  # reference scanned from above
    _e57(tmp_path / "core.e57", _ceiling(10.0, 3)[::7], (0.0, 0.0, 0.0))  # core points from below
    write_cloud_table(tmp_path / "cmp.ply", _ceiling(10.1, 2), {})
    reference, compared, core = (m3c2kit.read(tmp_path / n) for n in ("ref.e57", "cmp.ply", "core.e57"))
    result = m3c2kit.compare(reference, compared, core, threads=2, **PARAMS)
    assert main(["compare", str(tmp_path / "ref.e57"), str(tmp_path / "cmp.ply"), "--core", str(tmp_path / "core.e57"),
                 "-o", str(tmp_path / "cli.csv"), "-q", *FLAGS]) == 0
    cli = read_cloud(tmp_path / "cli.csv")
    np.testing.assert_array_equal(cli.fields["distance"], result.distance.astype(np.float32))
    assert np.nanmedian(result.distance) == pytest.approx(-0.1, abs=0.005)


@pytest.mark.parametrize("suffix", [".las", ".txt"])
def test_las_and_ascii_inputs(tmp_path, suffix):
    for name, z, seed in (("ref", 10.0, 1), ("cmp", 10.1, 2)):
        write_cloud_table(tmp_path / f"{name}{suffix}", _ceiling(z, seed), {})
    result = _api_equals_cli(tmp_path, tmp_path / f"ref{suffix}", tmp_path / f"cmp{suffix}", ".las", PARAMS, FLAGS)
    assert result.params["orient"] == "+z"
    assert np.nanmedian(result.distance) == pytest.approx(0.1, abs=0.005)


def test_a_cloudcompare_params_file(tmp_path):
    """`m3c2 compare --params FILE` and m3c2kit.compare(**read_cloudcompare_params(FILE)): the same
    file gives the same settings (--compat cloudcompare included) and the same bytes."""
    for name in ("autzen-bmx-2010.las", "autzen-bmx-2023.las", "autzen-bmx-cores.txt"):
        shutil.copy(PAIRS / name, tmp_path / name)
    # CloudCompare's parameters for this pair, as qM3C2 saves them (PROVENANCE.md; test_cli.py).
    (tmp_path / "m3c2_params.txt").write_text(
        "[General]\nM3C2VER=1\nNormalScale=2.780864\nNormalMode=0\nNormalPreferedOri=4\nSearchScale=5.780864\n"
        "SearchDepth=5.5\nUseSinglePass4Depth=true\nSubsampleEnabled=false\nRegistrationErrorEnabled=false\n"
        "UseMedian=false\nUseMinPoints4Stat=false\nProjDestIndex=2\nExportStdDevInfo=true\n"
        "ExportDensityAtProjScale=true\nMaxThreadCount=2\n")
    params = read_cloudcompare_params(tmp_path / "m3c2_params.txt")
    assert params["compat"] == "cloudcompare"
    core = m3c2kit.read(tmp_path / "autzen-bmx-cores.txt")
    reference, compared = m3c2kit.read(tmp_path / "autzen-bmx-2010.las"), m3c2kit.read(tmp_path / "autzen-bmx-2023.las")
    position = params.pop("position")  # how the table is written: m3c2kit.write's keyword
    result = m3c2kit.compare(reference, compared, core, **params)
    m3c2kit.write(tmp_path / "api.csv", result, like=reference, position=position)
    assert main(["compare", str(tmp_path / "autzen-bmx-2010.las"), str(tmp_path / "autzen-bmx-2023.las"),
                 "--core", str(tmp_path / "autzen-bmx-cores.txt"), "--params", str(tmp_path / "m3c2_params.txt"),
                 "-o", str(tmp_path / "cli.csv"), "-q"]) == 0
    assert filecmp.cmp(tmp_path / "api.csv", tmp_path / "cli.csv", shallow=False)
    assert np.isfinite(result.distance).mean() > 0.5
