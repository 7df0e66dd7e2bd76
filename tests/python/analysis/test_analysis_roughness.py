"""m3c2 roughness (section 5.1, eq. 3): the Hurst exponent of synthetic self-affine surfaces, the
mean roughness against a brute-force numpy computation, the fit, and the command line."""
from __future__ import annotations

import csv

import numpy as np
import pytest

from m3c2kit.analysis import fit_scaling, roughness_by_scale, roughness_table
from m3c2kit.analysis.synthetic import self_affine_surface
from m3c2kit.cli.main import main

N, SPACING = 256, 0.1           # 25.6 x 25.6 surface, one point per 0.1 x 0.1 cell
SCALES = np.geomspace(1.0, 6.4, 7)  # 10 spacings to a quarter of the surface: well inside the self-affine range


def _surface_and_cores(hurst, seed=3):
    pts = self_affine_surface(N, SPACING, hurst, rms=0.05, seed=seed)
    half = SCALES.max() / 2
    length = N * SPACING
    x, y = pts[:, 0], pts[:, 1]
    inner = np.nonzero((x > half) & (x < length - half) & (y > half) & (y < length - half))[0]
    return pts, pts[inner[::97]]


def brute_sigma(points, core, diameters):
    """sigma(D): sqrt(smallest eigenvalue of the co-moment / (n - 1)) of the points within D/2."""
    out = np.full((len(core), len(diameters)), np.nan)
    for i, c in enumerate(core):
        d2 = ((points - c) ** 2).sum(axis=1)
        for k, dia in enumerate(diameters):
            nb = points[d2 <= (dia / 2) ** 2]
            if len(nb) < 3:
                continue
            v = nb - nb.mean(axis=0)
            out[i, k] = np.sqrt(max(np.linalg.eigvalsh(v.T @ v)[0], 0.0) / (len(nb) - 1))
    return out


@pytest.mark.slow
@pytest.mark.parametrize("hurst", [0.3, 0.5, 0.8])
def test_fit_recovers_the_hurst_exponent(hurst):
    pts, core = _surface_and_cores(hurst)
    table = roughness_table(roughness_by_scale(pts, core, SCALES, min_points=10), SCALES)
    assert (table["n_core"] == len(core)).all()
    fit = fit_scaling(SCALES, table["mean_sigma"])
    assert abs(fit["beta"] - hurst) <= 0.1, fit
    assert fit["beta_se"] < 0.05


@pytest.mark.slow
def test_mean_roughness_matches_brute_force():
    pts, core = _surface_and_cores(0.5, seed=4)
    core = core[::3]
    engine = roughness_table(roughness_by_scale(pts, core, SCALES), SCALES)["mean_sigma"]
    brute = np.nanmean(brute_sigma(pts, core, SCALES), axis=0)
    np.testing.assert_allclose(engine, brute, rtol=0.02)
    np.testing.assert_allclose(engine, brute, rtol=1e-9)  # in fact the same computation


def test_table_statistics_and_nan():
    sigma = np.array([[1.0, np.nan], [3.0, 2.0], [np.nan, np.nan]])
    t = roughness_table(sigma, [1, 2])
    np.testing.assert_allclose(t["mean_sigma"], [2.0, 2.0])
    assert t["std_sigma"][0] == pytest.approx(np.sqrt(2.0)) and np.isnan(t["std_sigma"][1])
    assert list(t["n_core"]) == [2, 1]


def test_fit_of_an_exact_power_law():
    d = np.array([0.25, 0.5, 1, 2, 4, 8])
    m = 0.02 * (d / 0.5) ** 0.37
    fit = fit_scaling(d, m)
    assert fit["beta"] == pytest.approx(0.37, abs=1e-12)
    assert fit["sigma_l0"] == pytest.approx(0.02, rel=1e-12)
    assert fit["beta_se"] == pytest.approx(0.0, abs=1e-10)
    partial = fit_scaling(d, np.where(d < 1, 5 * m, m), fit_range=(1, 8))  # outside the range: ignored
    assert partial["beta"] == pytest.approx(0.37, abs=1e-12) and partial["n_scales"] == 4


def test_command_line(tmp_path, capsys):
    pts, core = _surface_and_cores(0.5)
    np.save(tmp_path / "surface.npy", pts)
    np.save(tmp_path / "core.npy", core)
    out, png = tmp_path / "table.csv", tmp_path / "plot.png"
    assert main(["roughness", str(tmp_path / "surface.npy"), "--normal-scale", "1:6.4:0.9", "--core",
                 str(tmp_path / "core.npy"), "--fit-range", "1:6.4", "-o", str(out), "--plot", str(png),
                 "--quiet"]) == 0
    text = capsys.readouterr().out
    assert "beta = " in text and "sigma(l0 = 0.5)" in text
    rows = list(csv.DictReader(out.open()))
    assert [float(r["D"]) for r in rows] == pytest.approx([1.0, 1.9, 2.8, 3.7, 4.6, 5.5, 6.4])
    assert set(rows[0]) == {"D", "mean_sigma", "std_sigma", "n_core", "in_fit"}
    assert png.stat().st_size > 1000 and png.read_bytes()[:4] == b"\x89PNG"
    beta = float(text.split("beta = ")[1].split()[0])
    assert abs(beta - 0.5) <= 0.1


def test_bad_range_is_a_usage_error(tmp_path, capsys):
    np.save(tmp_path / "c.npy", np.random.default_rng(0).random((50, 3)))
    assert main(["roughness", str(tmp_path / "c.npy"), "--normal-scale", "2:1:0.5", "-o", str(tmp_path / "t.csv")]) == 2
    assert main(["roughness", str(tmp_path / "c.npy"), "--normal-scale", "1", "--fit-range", "3", "-o",
                 str(tmp_path / "t.csv")]) == 2


@pytest.mark.parametrize("offset", [(0.0, 0.0, 0.0), (512345.25, 5412345.5, 1234.0)])
def test_exact_tilted_plane_has_no_roughness_exponent(tmp_path, capsys, offset):
    # Issue 14: sigma(D) had a floor of ~3e-10 D (the summed co-moment's smallest eigenvalue), and
    # eq. (3) fitted a spurious beta of 0.98 to it on an exact plane. sigma(D) is now at the
    # rounding (<= 1e-12 D, the centred pass) and such scales are planar, left out of the fit.
    g = np.arange(-40, 41) * 0.0625
    x, y = (a.ravel() for a in np.meshgrid(g, g))
    pts = np.column_stack([x, y, 0.5 * x + 0.25 * y]) + np.asarray(offset)
    np.save(tmp_path / "plane.npy", pts)
    np.save(tmp_path / "core.npy", pts[::97])
    out = tmp_path / "r.csv"
    assert main(["roughness", str(tmp_path / "plane.npy"), "--normal-scale", "0.5,1,2", "--core",
                 str(tmp_path / "core.npy"), "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert "planar to the engine's precision" in text and "no roughness exponent" in text
    assert "beta = nan" in text
    rows = list(csv.DictReader(out.open()))
    for row in rows:
        assert float(row["mean_sigma"]) <= 1e-12 * float(row["D"])
