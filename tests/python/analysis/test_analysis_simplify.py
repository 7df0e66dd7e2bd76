"""m3c2 simplify (section 6.3): projected positions by self-comparison, mean vs median, density."""
from __future__ import annotations

import csv
import math

import numpy as np
import pytest

from m3c2kit.analysis import simplify
from m3c2kit.analysis.synthetic import noisy_plane
from m3c2kit.cli.main import main


@pytest.fixture(scope="module")
def plane_with_outliers():
    pts = noisy_plane(80, 80, 0.1, noise=0.01, seed=2)
    rng = np.random.default_rng(3)
    out = rng.choice(len(pts), size=len(pts) // 20, replace=False)
    pts[out, 2] += 0.5  # 5 % outliers half a unit above
    return pts


def test_mean_is_the_local_average(plane_with_outliers):
    pts = plane_with_outliers
    core = np.array([[4.0, 4.0, 0.0], [2.05, 5.55, 0.0]])
    xyz, f = simplify(pts, core, projection_scale=0.6, vertical=True, max_depth=1.0)
    for c, p, n in zip(core, xyz, f["density"]):
        inside = (np.hypot(pts[:, 0] - c[0], pts[:, 1] - c[1]) <= 0.3) & (np.abs(pts[:, 2] - c[2]) <= 1.0)
        assert n == inside.sum()
        assert p[2] == pytest.approx(pts[inside, 2].mean(), abs=1e-12)
        assert p[:2] == pytest.approx(c[:2])
    np.testing.assert_allclose(f["density_per_area"], f["density"] / (math.pi * 0.3 ** 2))
    np.testing.assert_allclose(f["nz"], 1.0)


def test_median_removes_outliers(plane_with_outliers):
    pts = plane_with_outliers
    mean_xyz, _ = simplify(pts, core_spacing=1.0, projection_scale=0.6, normal_scale=1.5, max_depth=1.0)
    med_xyz, f = simplify(pts, core_spacing=1.0, projection_scale=0.6, normal_scale=1.5, max_depth=1.0, median=True)
    assert np.abs(np.median(mean_xyz[:, 2]) - 0.025) < 0.02   # mean pulled up by 5 % of 0.5
    assert np.median(np.abs(med_xyz[:, 2])) < 0.008            # median stays on the surface
    assert np.abs(med_xyz[:, 2]).max() < 0.03
    assert np.median(f["nz"]) > 0.99  # (outliers can tilt a few PCA normals)
    assert np.all(np.isfinite(f["roughness"]))


def test_command_line(plane_with_outliers, tmp_path, capsys):
    np.save(tmp_path / "p.npy", plane_with_outliers)
    out = tmp_path / "s.csv"
    assert main(["simplify", str(tmp_path / "p.npy"), "--core-spacing", "1", "--projection-scale", "0.5",
                 "--median", "-o", str(out)]) == 0
    assert "projected points (median" in capsys.readouterr().out
    rows = list(csv.DictReader(out.open()))
    assert list(rows[0]) == ["x", "y", "z", "roughness", "sigma", "density", "density_per_area", "nx", "ny", "nz",
                             "normal_scale", "offset", "status"]
    assert all(float(r["normal_scale"]) == 1.0 for r in rows)  # default D = 2 d


def test_real_cloud(autzen_pair, tmp_path):
    cloud = autzen_pair / "autzen-bmx-2010.las"
    out = tmp_path / "autzen.laz"
    assert main(["simplify", str(cloud), "--core-spacing", "3", "--projection-scale", "4", "-o", str(out),
                 "--quiet"]) == 0
    import m3c2kit
    c = m3c2kit.read(out)
    assert len(c) > 10 and "density_per_area" in c.fields
