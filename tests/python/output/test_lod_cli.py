"""The LOD statistic, py4dgeo's scale rule and the position fallback from the command line and
the API (issue 14): --lod z|t|auto|bootstrap with the old --t-statistic / --bootstrap N mapped
onto it, the calibrated default, --compat cloudcompare, --scale-selection py4dgeo, --position
reference|compared (NaN where there is no projection) and reference-or-core."""
import csv

import numpy as np
import pytest

import m3c2kit
import m3c2kit.base.errors
import m3c2kit.settings.table
from m3c2kit.cli.main import main

from synthetic import noisy_plane_pair, write_xyz

# n ~ 11 points per cylinder (d = 0.15 on a 0.05 grid): t and z differ.
KW = dict(normal_scale=0.5, projection_scale=0.15, max_depth=0.5)


@pytest.fixture(scope="module")
def pair():
    ref, cmp = noisy_plane_pair(n=40, offset=0.0)
    core = ref[(ref[:, 0] > 0.4) & (ref[:, 0] < 1.5) & (ref[:, 1] > 0.4) & (ref[:, 1] < 1.5)][::7]
    return ref, cmp, core


def lod(pair, **kw):
    ref, cmp, core = pair
    return m3c2kit.compare(ref, cmp, core, **KW, **kw)


def test_lod_statistics_and_the_old_flags(pair):
    z, t, auto = lod(pair, lod="z"), lod(pair, lod="t"), lod(pair, lod="auto")
    ok = np.isfinite(z.lod)
    assert ok.sum() > 20 and np.all(z.n1[ok] < 30)
    assert np.all(t.lod[ok] > z.lod[ok] * 1.02)         # Welch t at n ~ 11
    np.testing.assert_array_equal(auto.lod, t.lod)       # below 30 the paper's rule is t
    np.testing.assert_array_equal(lod(pair, t_statistic=True).lod, auto.lod)  # --t-statistic = --lod auto
    boot = lod(pair, bootstrap=50, seed=3)
    np.testing.assert_array_equal(boot.lod, lod(pair, lod="bootstrap", bootstrap=50, seed=3).lod)
    assert not np.array_equal(boot.lod, z.lod)
    # The default is the calibrated auto; CloudCompare's semantics keep z.
    np.testing.assert_array_equal(lod(pair).lod, auto.lod)
    table = m3c2kit.settings.table.by_name()
    assert table["lod"].default_for() == "auto" and table["lod"].default_for("cloudcompare") == "z"
    with pytest.raises(m3c2kit.base.errors.UsageError, match="contradicts"):
        lod(pair, lod="z", t_statistic=True)


def test_median_lod_default_and_cloudcompares(pair):
    mj, cc = lod(pair, median=True), lod(pair, median=True, median_lod="cloudcompare")
    ok = np.isfinite(mj.lod)
    assert not np.allclose(mj.lod[ok], cc.lod[ok])
    assert m3c2kit.settings.table.by_name()["median_lod"].default_for("cloudcompare") == "cloudcompare"


def _csv(path):
    rows = list(csv.DictReader(open(path)))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


def test_command_line_lod_scale_selection_and_position(tmp_path, pair):
    ref, cmp, core = pair
    cmp = cmp[cmp[:, 0] < 1.0]  # no compared points beyond x = 1: empty cylinders there
    for name, pts in (("ref", ref), ("cmp", cmp), ("core", core)):
        write_xyz(tmp_path / f"{name}.xyz", pts)
    base = ["compare", str(tmp_path / "ref.xyz"), str(tmp_path / "cmp.xyz"), "--core", str(tmp_path / "core.xyz"),
            "--normal-scale", "0.2,0.4,0.8", "--projection-scale", "0.15", "--max-depth", "0.5", "--quiet"]
    out = {}
    for tag, extra in (("t", ["--lod", "t"]), ("z", ["--lod", "z"]), ("py4dgeo", ["--scale-selection", "py4dgeo"]),
                       ("ref", ["--position", "reference"]), ("refcore", ["--position", "reference-or-core"])):
        assert main(base + extra + ["-o", str(tmp_path / f"{tag}.csv")]) == 0
        out[tag] = _csv(tmp_path / f"{tag}.csv")
    ok = np.isfinite(out["z"]["lod"])
    assert np.all(out["t"]["lod"][ok] > out["z"]["lod"][ok])
    scales = out["py4dgeo"]["normal_scale"]
    assert set(np.round(np.unique(scales[np.isfinite(scales)]), 6)) <= {0.2, 0.4, 0.8}  # float32 column
    none = ~np.isfinite(out["ref"]["distance"])
    assert none.any() and (~none).any()
    assert np.isnan(out["ref"]["x"][none]).all() and np.isfinite(out["ref"]["x"][~none]).all()
    np.testing.assert_array_equal(out["refcore"]["x"][none], core[none, 0])
    np.testing.assert_array_equal(out["refcore"]["z"][~none], out["ref"]["z"][~none])
