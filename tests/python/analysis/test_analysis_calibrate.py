"""m3c2 calibrate (sections 5.2.1-5.2.2): percentages of correctly non-significant core points on
a subsampled copy of the same surface, the LOD95 scaling and eq. (7), and the command line."""
from __future__ import annotations

import csv

import numpy as np
import pytest

from m3c2kit.analysis import calibrate
from m3c2kit.analysis.calibrate import CorePoints, report_lines
from m3c2kit.analysis.calibrate import resolve_spacing
from m3c2kit.analysis.synthetic import noisy_plane
from m3c2kit.cli.main import main
from m3c2kit.base.errors import UsageError

D_LIST = [0.8, 1.2, 1.6, 2.4]  # n2 >= 4 needs d >~ 0.7 on the 0.3-spaced copy


@pytest.fixture(scope="module")
def plane():
    return noisy_plane(120, 120, 0.1, noise=0.01, seed=5)


@pytest.fixture(scope="module")
def result(plane):
    return calibrate(plane, D_LIST, spacings=("raw", "3x"), cores=CorePoints(max_count=300), bootstrap=30, seed=1)


@pytest.mark.slow
def test_table(result):
    t = result["table"]
    assert list(t["d"]) == D_LIST
    for key in ("pct_not_significant_z", "pct_not_significant_t", "pct_not_significant_bootstrap"):
        assert np.all((t[key] >= 0) & (t[key] <= 100))
        assert np.all(t[key] >= 85), (key, t[key])  # an unchanged Gaussian surface: >= 95 % expected
    assert np.all(t["n_lod_z"] > 200)
    assert np.all(np.diff(t["mean_lod95"]) < 0)  # LOD95 falls with d
    assert np.all(t["mean_n1"] > t["mean_n2"])   # raw vs subsampled
    i = result["info"]
    assert i["spacing"] == pytest.approx(0.1, rel=0.05) and i["spacing1"] == 0 and i["spacing2"] == pytest.approx(3 * i["spacing"])
    assert i["normals"].startswith("vertical")


def test_scaling_of_a_gaussian_plane(result):
    # beta = 0 (no roughness scaling) and n ~ d^2: eq. (1) gives LOD95 ~ d^-1 (section 5.2.2's
    # "decreases rapidly as the inverse of d").
    f = result["fit"]
    assert f["alpha"] == pytest.approx(-1.0, abs=0.15)
    assert abs(f["beta"]) < 0.1
    assert f["gamma"] == pytest.approx(2.0, abs=0.2)
    assert f["alpha_predicted"] == pytest.approx(f["beta"] - 0.95)


def test_resolve_spacing():
    assert resolve_spacing("raw", 0.1) == 0
    assert resolve_spacing("2.5x", 0.1) == pytest.approx(0.25)
    assert resolve_spacing("0.045", 0.1) == 0.045
    with pytest.raises(UsageError):
        resolve_spacing("-1", 0.1)
    with pytest.raises(UsageError):
        resolve_spacing("abc", 0.1)


@pytest.mark.slow
def test_command_line(plane, tmp_path, capsys):
    np.save(tmp_path / "plane.npy", plane)
    out, png = tmp_path / "cal.csv", tmp_path / "cal.png"
    assert main(["calibrate", str(tmp_path / "plane.npy"), "--projection-scales", "0.4:1.2:0.4", "--spacings",
                 "0.15,0.2", "--max-core", "200", "--bootstrap", "10", "-o", str(out), "--plot", str(png)]) == 0
    text = capsys.readouterr().out
    assert "eq. (7) predicts beta - 0.95" in text and "cloud 1: 0.15" in text
    rows = list(csv.DictReader(out.open()))
    assert [float(r["d"]) for r in rows] == pytest.approx([0.4, 0.8, 1.2])
    assert {"pct_not_significant_z", "pct_not_significant_t", "pct_not_significant_bootstrap", "mean_lod95"} <= set(rows[0])
    assert png.read_bytes()[:4] == b"\x89PNG"
    assert main(["calibrate", str(tmp_path / "plane.npy"), "--projection-scales", "1", "--spacings", "raw",
                 "-o", str(out)]) == 2


def test_real_cloud(autzen_pair, tmp_path, capsys):
    cloud = autzen_pair / "autzen-bmx-2010.las"
    out = tmp_path / "autzen.csv"
    assert main(["calibrate", str(cloud), "--projection-scales", "3,4,6", "--bootstrap", "10", "-o", str(out)]) == 0
    assert len(list(csv.DictReader(out.open()))) == 3


def test_every_lod_statistic_is_measured_and_one_is_recommended(result):
    # Issue 14: the no-change false-positive rate of mean / median x z / auto / t / bootstrap at
    # each d, the closest to the nominal 5 % per d, and per statistic over the scales.
    t = result["table"]
    for statistic in ("mean", "median"):
        for lod in ("z", "auto", "t", "bootstrap"):
            v = t[f"fp_{statistic}_{lod}"]
            assert v.shape == (len(D_LIST),) and np.all((v >= 0) & (v <= 0.15)), (statistic, lod, v)
    # The legacy columns are the same runs: z and the paper's t rule (auto).
    np.testing.assert_allclose(100 - t["pct_not_significant_z"], 100 * t["fp_mean_z"])
    np.testing.assert_allclose(100 - t["pct_not_significant_t"], 100 * t["fp_mean_auto"])
    for d, rec in zip(D_LIST, t["recommended"]):
        statistic, lod = rec.split("/")
        rates = {k: abs(t[k][D_LIST.index(d)] - 0.05) for k in t if k.startswith("fp_")}
        assert rates[f"fp_{statistic}_{lod}"] == min(rates.values())
    rec = result["recommendation"]
    assert set(rec) == {"mean", "median"} and all(lod in ("z", "auto", "t", "bootstrap") for lod, _ in rec.values())
    lines = report_lines(result)
    assert any(line.startswith("recommended with the mean: --lod ") for line in lines)
