"""m3c2 variogram: the C++ pair sums against a brute-force numpy computation (the same bins),
the same bits for any thread count, the fit's recovery of a known model, and the command with
compare --error-model end to end (with --stable POLYGONS)."""
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from m3c2kit import engine
from m3c2kit.analysis.error_model import Component, ErrorModel, load
from m3c2kit.analysis.random_fields import sample_field
from m3c2kit.analysis import variogram as vg
from m3c2kit.analysis.variogram import empirical_variogram, fit_model
from m3c2kit.base.errors import UsageError


def _brute(points, values, edges, planar=False):
    p = points[:, :2] if planar else points
    i, j = np.triu_indices(len(p), 1)
    h = np.linalg.norm(p[i] - p[j], axis=1)
    k = np.searchsorted(edges, h, side="right") - 1
    ok = (h >= edges[0]) & (h < edges[-1])
    pairs = np.bincount(k[ok], minlength=len(edges) - 1)
    half = np.bincount(k[ok], 0.5 * (values[i] - values[j])[ok] ** 2, minlength=len(edges) - 1)
    lag = np.bincount(k[ok], h[ok], minlength=len(edges) - 1)
    return pairs, lag, half


@pytest.mark.parametrize("planar", [False, True])
def test_kernel_against_brute_force(planar):
    rng = np.random.default_rng(5)
    pts = rng.uniform(0, 10, (400, 3))
    vals = rng.normal(size=400)
    edges = np.r_[0.0, np.geomspace(0.3, 12.0, 15)]
    # every centre, a ball holding every point, no thinning, no random pairs: each pair twice
    r = engine.variogram_pairs(pts, vals, edges, seed=1, centres=400, near_radius=50.0, max_neighbours=1000,
                               far_pairs=0, planar=planar, threads=2)
    pairs, lag, half = _brute(pts, vals, edges, planar)
    assert np.array_equal(np.asarray(r["pairs"]), 2 * pairs)  # the same bins exactly
    assert np.allclose(r["lag_sum"], 2 * lag, rtol=1e-12) and np.allclose(r["half_sq_sum"], 2 * half, rtol=1e-12)


def test_random_pairs_estimate_the_brute_force_and_threads_agree():
    rng = np.random.default_rng(6)
    pts = np.c_[rng.uniform(0, 50, (3000, 2)), np.zeros(3000)]
    vals = sample_field(pts[:, :2], ErrorModel(0.0, (Component("spherical", 1.0, 10.0),)), 2)
    edges = np.r_[0.0, np.geomspace(1.0, 40.0, 10)]
    runs = [engine.variogram_pairs(pts, vals, edges, seed=3, centres=500, near_radius=3.0, max_neighbours=64,
                                   far_pairs=400_000, planar=False, threads=t) for t in (1, 2, 3)]
    for r in runs[1:]:
        for key in ("pairs", "lag_sum", "half_sq_sum"):
            assert np.array_equal(np.asarray(r[key]), np.asarray(runs[0][key]))  # the same bits
    pairs, _, half = _brute(pts, vals, edges)
    got = np.asarray(runs[0]["half_sq_sum"]) / np.asarray(runs[0]["pairs"])
    assert np.allclose(got[2:], (half / pairs)[2:], rtol=0.08)


def test_kernel_refuses_bad_input():
    pts = np.zeros((3, 3))
    with pytest.raises(UsageError, match="finite"):
        engine.variogram_pairs(pts, np.array([0.0, np.nan, 1.0]), [0.0, 1.0], seed=0, centres=3, near_radius=1.0,
                               max_neighbours=8, far_pairs=0, planar=False)
    with pytest.raises(UsageError, match="increasing"):
        engine.variogram_pairs(pts, np.zeros(3), [1.0, 1.0], seed=0, centres=3, near_radius=1.0, max_neighbours=8,
                               far_pairs=0, planar=False)


@pytest.mark.parametrize("kind, range_", [("spherical", 10.0), ("exponential", 10.0)])
def test_fit_recovers_range_and_sill(kind, range_):
    g = np.arange(0.0, 300.0, 1.0)
    x, y = np.meshgrid(g, g)
    xy = np.c_[x.ravel(), y.ravel()]
    truth = ErrorModel(1e-5, (Component(kind, 1e-4, range_),))
    vals = sample_field(xy, truth, 11, include_nugget=True)
    emp = empirical_variogram(np.c_[xy, np.zeros(len(xy))], vals, seed=2, threads=2)
    model, kept = fit_model(emp, seed=2)
    main = max(model.components, key=lambda c: c.sill)
    assert model.correlated_variance() == pytest.approx(1e-4, rel=0.2), kept
    assert main.range == pytest.approx(range_, rel=0.2), kept
    assert model.nugget == pytest.approx(1e-5, rel=0.5)


def _m3c2(*args):
    return subprocess.run([sys.executable, "-m", "m3c2kit", *map(str, args)], capture_output=True, text=True)


def test_command_and_error_model_end_to_end(tmp_path):
    rng = np.random.default_rng(8)
    field = ErrorModel(0.0, (Component("spherical", 0.008 ** 2, 6.0),))
    clouds = []
    for seed in (1, 2):
        xy = rng.uniform(0, 40, (25600, 2))
        z = rng.normal(0, 0.005, len(xy)) + sample_field(xy, field, seed)
        path = tmp_path / f"e{seed}.xyz"
        np.savetxt(path, np.c_[xy, z], fmt="%.6f")
        clouds.append(path)
    g = np.arange(1.0, 39.0, 1.0)
    cx, cy = np.meshgrid(g, g)
    np.savetxt(tmp_path / "core.xyz", np.c_[cx.ravel(), cy.ravel(), np.zeros(cx.size)], fmt="%.3f")
    common = ["--core", tmp_path / "core.xyz", "--projection-scale", "1", "--max-depth", "0.2",
              "--normal-source", "vertical", "--lod", "z", "-q"]
    r = _m3c2("compare", *clouds, "-o", tmp_path / "plain.csv", *common)
    assert r.returncode == 0, r.stderr
    (tmp_path / "model.png").write_bytes(b"the user's own figure")
    r = _m3c2("variogram", tmp_path / "plain.csv", "--projection-scale", "1", "-o", tmp_path / "model.json")
    assert r.returncode == 0, r.stderr
    # issue 42: a figure only with --plot; model.png beside it was replaced
    assert "correlated variance" in r.stdout and (tmp_path / "model.png").read_bytes() == b"the user's own figure"
    # issue 42: fitted on every core point while many are significant: said (here correlated error, no change)
    assert "% of the core points are significant at their LOD and every core point is taken as stable" in r.stderr
    plotted = _m3c2("variogram", tmp_path / "plain.csv", "--projection-scale", "1", "-o", tmp_path / "other.json",
                    "--plot", tmp_path / "figure.svg", "-q")
    assert plotted.returncode == 0, plotted.stderr
    assert (tmp_path / "figure.svg").read_bytes().lstrip().startswith(b"<?xml")
    assert load(tmp_path / "other.json") == load(tmp_path / "model.json")
    for bad, words in ((tmp_path / "m.png", "the error model is written as .json"), ("", "names no file")):
        refused = _m3c2("variogram", tmp_path / "plain.csv", "--projection-scale", "1", "-o", bad)
        assert refused.returncode == 2 and words in refused.stderr and "Traceback" not in refused.stderr, refused.stderr
    assert not (tmp_path / "m.png").exists()
    model = load(tmp_path / "model.json")
    plain = np.genfromtxt(tmp_path / "plain.csv", delimiter=",", names=True)
    # mean_u2: eq. (1)'s s1^2/n1 + s2^2/n2 over the core points fitted (every one with a LOD here);
    # the LOD's sigma_c^2 is the total sill minus it
    u2 = plain["sigma1"] ** 2 / plain["n1"] + plain["sigma2"] ** 2 / plain["n2"]
    assert model.mean_u2 == pytest.approx(np.nanmean(u2), rel=1e-5)  # the file's float32 columns
    assert model.projection_scale == 1.0 and model.excess_variance() == pytest.approx(
        model.nugget + model.correlated_variance() - model.mean_u2, rel=1e-12) and model.excess_variance() > 0
    assert f"sigma_c^2 {model.excess_variance():.6g}" in r.stdout
    r = _m3c2("compare", *clouds, "-o", tmp_path / "model.csv", "--error-model", tmp_path / "model.json", *common)
    assert r.returncode == 0, r.stderr
    modelled = np.genfromtxt(tmp_path / "model.csv", delimiter=",", names=True)
    assert np.nanmean(plain["significant"]) > 0.3 and np.nanmean(modelled["significant"]) < 0.12
    # the LOD is eq. (1) with sigma_c^2 inside the square root
    z = 1.959963984540054
    se2 = (plain["lod"] / z) ** 2
    assert np.allclose(modelled["lod"], z * np.sqrt(se2 + model.excess_variance()), rtol=1e-6, equal_nan=True)
    # --stable POLYGONS: only the core points inside count (x < 20 here), the same numbers as
    # fitting those rows alone
    (tmp_path / "stable.geojson").write_text(json.dumps({"type": "Polygon", "coordinates": [
        [[0, 0], [20, 0], [20, 40], [0, 40], [0, 0]]]}))
    r = _m3c2("variogram", tmp_path / "plain.csv", "--stable", tmp_path / "stable.geojson", "--projection-scale",
              "1", "-o", tmp_path / "west.json")
    assert r.returncode == 0, r.stderr
    west = load(tmp_path / "west.json")
    inside = (plain["x"] < 20) & np.isfinite(u2) & np.isfinite(plain["distance"])
    assert f"{int(inside.sum())} stable core points" in r.stdout and inside.sum() < len(plain) - 100
    assert west.mean_u2 == pytest.approx(np.mean(u2[inside]), rel=1e-5)
    # another d is refused, naming the model and both d
    r = _m3c2("compare", *clouds, "-o", tmp_path / "x.csv", "--error-model", tmp_path / "model.json",
              *[a if a != "1" else "2" for a in common])
    assert r.returncode == 2 and "fitted at --projection-scale 1" in r.stderr and not (tmp_path / "x.csv").exists()
    # a result without the sigma / n columns (LAS without --all-fields) is refused, naming it
    r = _m3c2("compare", *clouds, "-o", tmp_path / "plain.las", *common)
    assert r.returncode == 0, r.stderr
    r = _m3c2("variogram", tmp_path / "plain.las", "--projection-scale", "1", "-o", tmp_path / "m3.json")
    assert r.returncode == 2 and "plain.las: no sigma1, sigma2 column(s)" in r.stderr and "--all-fields" in r.stderr
    assert not (tmp_path / "m3.json").exists()
    # --stable-field with a field the result lacks
    r = _m3c2("variogram", tmp_path / "plain.csv", "--stable-field", "classification=2", "-o", tmp_path / "m2.json")
    assert r.returncode == 2 and "no field 'classification'" in r.stderr and not (tmp_path / "m2.json").exists()


def test_error_model_refused_with_pm(tmp_path):
    from m3c2kit.analysis.error_model import save
    from m3c2kit.settings import build_params
    save(tmp_path / "m.json", ErrorModel(0.0, (Component("spherical", 1e-4, 5.0),), 1.0, mean_u2=0.0))
    with pytest.raises(UsageError, match="--error-model would change nothing"):
        build_params(projection_scale=1.0, max_depth=1.0, normal_scale=1.0, uncertainty="pm",
                     error_model=str(tmp_path / "m.json"))


def test_the_change_taken_for_error_is_said_only_past_the_false_alarm_rate():
    from types import SimpleNamespace
    distance = np.linspace(-1, 1, 1000)
    for share, said in ((0.05, False), (0.10, False), (0.11, True), (0.6, True)):
        significant = (np.arange(1000) < share * 1000).astype(float)
        cloud = SimpleNamespace(fields={"distance": distance, "significant": significant})
        message = vg.change_taken_for_error(cloud)
        assert (message is not None) == said, share
    assert vg.change_taken_for_error(SimpleNamespace(fields={"distance": distance})) is None


@pytest.mark.parametrize("value", ["nan", "inf", "-inf", "NaN"])
def test_a_stable_field_value_that_equals_nothing_is_refused(value):
    """Hostile round 2: --stable-field class=nan was accepted (NaN equals no value), so the
    selection was empty and the failure came later, in other words."""
    from m3c2kit.io.cloud import Cloud
    cloud = Cloud(np.zeros((3, 3)), {"class": np.array([np.nan, 1.0, 2.0])}, path="r.csv")
    with pytest.raises(UsageError, match=r"--stable-field 'class=.*': VALUE must be a finite number"):
        vg.stable_mask(cloud, field=f"class={value}")
    assert vg.stable_mask(cloud, field="class=2").tolist() == [False, False, True]
