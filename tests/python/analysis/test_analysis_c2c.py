"""m3c2 c2c (section 3.4): C2C and C2C_HF from the C++ engine against numpy brute force, and the
command line."""
from __future__ import annotations

import csv

import numpy as np
import pytest

from m3c2kit.analysis import c2c
from m3c2kit.analysis.synthetic import noisy_plane
from m3c2kit.cli.main import main
from m3c2kit.base.errors import UsageError


def brute(ref, q):
    d = np.sqrt(((q[:, None, :] - ref[None, :, :]) ** 2).sum(axis=-1))
    return d.argmin(axis=1), d.min(axis=1)


def brute_plane(ref, j, q, k):
    order = np.lexsort((np.arange(len(ref)), ((ref - ref[j]) ** 2).sum(axis=1)))[:k]
    nb = ref[order]
    c = nb.mean(axis=0)
    n = np.linalg.eigh((nb - c).T @ (nb - c))[1][:, 0]
    return abs((q - c) @ n)


def test_nearest_matches_brute_force():
    rng = np.random.default_rng(0)
    ref, q = rng.random((4000, 3)), rng.random((500, 3)) * 1.4 - 0.2
    r = c2c(ref, q, threads=2)
    j, d = brute(ref, q)
    np.testing.assert_array_equal(r["nearest"], j)
    np.testing.assert_allclose(r["distance"], d, rtol=1e-14, atol=0)
    np.testing.assert_array_equal(r["hf_distance"], r["distance"])
    assert np.isnan(r["model_distance"]).all() and (r["model_count"] == 0).all()


def test_plane_model_matches_brute_force_pca():
    ref = noisy_plane(40, 40, 1.0, noise=0.2, seed=1)
    q = noisy_plane(20, 20, 1.0, noise=0.2, z=3.0, x_shift=0.5, seed=2)
    r = c2c(ref, q, model="plane", model_neighbours=8, rule="model")
    j, d = brute(ref, q)
    np.testing.assert_array_equal(r["nearest"], j)
    expected = np.array([brute_plane(ref, jj, qq, 8) for jj, qq in zip(j, q)])
    np.testing.assert_allclose(r["model_distance"], expected, rtol=1e-9)
    np.testing.assert_array_equal(r["hf_distance"], r["model_distance"])
    closer = c2c(ref, q, model="plane", model_neighbours=8)
    np.testing.assert_array_equal(closer["hf_distance"], np.minimum(closer["distance"], closer["model_distance"]))


def test_closest_point_bias_and_plane_correction_on_offset_grids():
    # Fig. 4b in small: grids offset by half a spacing, no noise, raised by 1: C2C sees
    # sqrt(1 + 0.5^2) from the x offset, the plane model the true 1.
    ref = noisy_plane(30, 30, 1.0, noise=0.0)
    q = noisy_plane(10, 10, 1.0, noise=0.0, z=1.0, x_shift=10.5)
    r = c2c(ref, q, model="plane", model_radius=1.5)
    np.testing.assert_allclose(r["distance"], np.sqrt(1.25))
    np.testing.assert_allclose(r["hf_distance"], 1.0, atol=1e-12)


def test_bad_parameters():
    pts = np.random.default_rng(1).random((20, 3))
    with pytest.raises(UsageError):
        c2c(pts, pts, model="quadric")
    with pytest.raises(UsageError):
        c2c(pts, pts, model="plane", model_radius=-1.0)
    with pytest.raises(UsageError):
        c2c(pts, pts, model="plane", model_neighbours=2)
    with pytest.raises(UsageError):
        c2c(np.zeros((0, 3)), pts)


def test_command_line(tmp_path, capsys):
    ref = noisy_plane(30, 30, 1.0, noise=0.05, seed=1)
    cmp_ = noisy_plane(30, 30, 1.0, noise=0.05, z=0.4, x_shift=0.3, seed=2)
    np.save(tmp_path / "ref.npy", ref)
    np.save(tmp_path / "cmp.npy", cmp_)
    out = tmp_path / "c2c.csv"
    assert main(["c2c", str(tmp_path / "ref.npy"), str(tmp_path / "cmp.npy"), "-o", str(out), "--model", "plane",
                 "--model-radius", "1.5", "--threads", "2"]) == 0
    assert "C2C_HF mean" in capsys.readouterr().out
    rows = list(csv.DictReader(out.open()))
    assert list(rows[0]) == ["x", "y", "z", "c2c", "c2c_hf", "model_points"]
    assert len(rows) == len(cmp_)
    r = c2c(ref, cmp_, model="plane", model_radius=1.5)
    np.testing.assert_allclose([float(x["c2c"]) for x in rows], r["distance"], rtol=1e-12)
    np.testing.assert_allclose([float(x["c2c_hf"]) for x in rows], r["hf_distance"], rtol=1e-12)
    # plain C2C on core points of the compared cloud
    out2 = tmp_path / "plain.csv"
    assert main(["c2c", str(tmp_path / "ref.npy"), str(tmp_path / "cmp.npy"), "-o", str(out2), "--core-spacing", "3",
                 "--quiet"]) == 0
    rows2 = list(csv.DictReader(out2.open()))
    assert list(rows2[0]) == ["x", "y", "z", "c2c"] and len(rows2) < len(cmp_)
    assert main(["c2c", str(tmp_path / "ref.npy"), str(tmp_path / "cmp.npy"), "-o", str(out2),
                 "--model-radius", "1"]) == 2


def test_real_pair(autzen_pair, tmp_path):
    pair = autzen_pair
    out = tmp_path / "autzen.laz"
    assert main(["c2c", str(pair / "autzen-bmx-2010.las"), str(pair / "autzen-bmx-2023.las"), "-o", str(out),
                 "--model", "plane", "--quiet"]) == 0
    import m3c2kit
    cloud = m3c2kit.read(out)
    assert len(cloud) == len(m3c2kit.read(pair / "autzen-bmx-2023.las"))
    assert np.all(cloud.fields["c2c_hf"] <= cloud.fields["c2c"] + 1e-6)
