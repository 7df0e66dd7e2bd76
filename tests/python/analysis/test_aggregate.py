"""m3c2 aggregate (m3c2kit.analysis.aggregate): the variance of a regional mean against its
definition summed by brute force in numpy, mean and volume of a known change, the grid check,
coverage of the intervals over simulated surveys with correlated errors (seeded), and the
command's table and messages."""
from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest

from m3c2kit import engine
from m3c2kit.analysis.aggregate import TOTAL, Survey, aggregate, check_grid
from m3c2kit.analysis.error_model import Component, ErrorModel, save
from m3c2kit.analysis.random_fields import sample_field
from m3c2kit.base.errors import UsageError
from m3c2kit.cli.main import main
from m3c2kit.io.polygons import Polygon, region_index

MODEL = ErrorModel(0.0, (Component("spherical", 4e-4, 6.0), Component("exponential", 1e-4, 15.0)))


def lattice(cols: int, rows: int, cell: float, x0: float = 1000.0, y0: float = 2000.0) -> np.ndarray:
    c, r = np.meshgrid(np.arange(cols), np.arange(rows))
    return np.column_stack([x0 + (c.ravel() + 0.5) * cell, y0 + (r.ravel() + 0.5) * cell])


def square(name, x0, y0, x1, y1) -> Polygon:
    return Polygon(name, [np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], float)])


def brute_covariance(xy, model) -> float:
    h = np.hypot(*(xy[:, None, :] - xy[None, :, :]).transpose(2, 0, 1))
    return float(model.covariance(h).sum())


def test_binding_sum_matches_numpy_brute_force():
    rng = np.random.default_rng(1)
    xy = rng.uniform(0, 50, (1500, 2)) + [4e5, 5e6]
    want = brute_covariance(xy, MODEL)
    exact, _ = engine.region_covariance_sum(xy, MODEL.components, exact=True)
    binned, sides = engine.region_covariance_sum(xy, MODEL.components)
    assert exact == pytest.approx(want, rel=1e-12)
    assert binned == pytest.approx(want, rel=5e-4)
    assert sides == [6.0 / 8, 15.0 / 8]


def test_mean_volume_and_variance_of_a_known_change():
    cell = 0.5
    xy = lattice(40, 30, cell)
    rng = np.random.default_rng(2)
    u2 = rng.uniform(1e-5, 4e-5, len(xy))
    d = np.full(len(xy), 0.25)
    d[::7] = np.nan  # missing cells: left out, the area covered says so
    lod = np.full(len(xy), 0.1)
    lod[5] = 0.3  # one cell not significant
    survey = Survey(xy, d, lod, u2)
    west = square("west", 1000, 2000, 1010, 2015)
    t = aggregate(survey, [west, square("east", 1010, 2000, 1020, 2015)], model=MODEL, cell=cell,
                  simulations=20, seed=3)
    assert [r.region for r in t.rows] == ["west", "east", TOTAL]
    w, total = t.rows[0], t.rows[2]
    inside = (xy[:, 0] < 1010)
    ok = inside & np.isfinite(d)
    assert w.core_points == inside.sum() == 600 and w.with_distance == ok.sum()
    assert w.mean == pytest.approx(0.25, abs=1e-15)
    assert w.volume == pytest.approx(0.25 * ok.sum() * cell * cell, rel=1e-12)
    assert w.covered_area == pytest.approx(ok.sum() * 0.25) and w.region_area == pytest.approx(150.0)
    assert w.covered_share == pytest.approx(ok.sum() * 0.25 / 150)
    want_var = (u2[ok].sum() + brute_covariance(xy[ok], MODEL)) / ok.sum() ** 2
    assert w.mean_se ** 2 == pytest.approx(want_var, rel=5e-4)
    assert w.se_uncorrelated == pytest.approx(math.sqrt(u2[ok].sum()) / ok.sum())
    z = 1.959963984540054
    assert (w.mean_low, w.mean_high) == pytest.approx((0.25 - z * w.mean_se, 0.25 + z * w.mean_se))
    assert w.volume_se == pytest.approx(w.mean_se * ok.sum() * 0.25)
    assert w.significant == ok.sum() - (1 if ok[5] else 0)
    assert w.significant_area == pytest.approx(w.significant * 0.25)
    assert total.with_distance == np.isfinite(d).sum()
    # the change is 2.5 lod: every simulated survey flags the same cells
    assert w.significant_low == w.significant_high == w.significant


def test_without_a_model_the_intervals_are_uncorrelated_and_say_so():
    xy = lattice(20, 20, 1.0)
    survey = Survey(xy, np.full(400, 0.1), np.full(400, 0.05), np.full(400, 1e-4))
    t = aggregate(survey, [square("all", 0, 0, 5000, 5000)], simulations=0)
    assert t.rows[0].mean_se == pytest.approx(math.sqrt(400 * 1e-4) / 400)
    assert t.rows[0].se_correlated is None and t.rows[0].volume is None
    assert any("too narrow" in n and "Rolstad" in n for n in t.notes)
    assert any("no --cell-size" in n for n in t.notes)


def test_the_nugget_excess_adds_to_the_uncorrelated_part():
    xy = lattice(10, 10, 1.0)
    survey = Survey(xy, np.zeros(100), np.full(100, 1.0), np.full(100, 1e-4))
    model = ErrorModel(5e-4, (Component("spherical", 1e-4, 3.0),), mean_u2=2e-4)
    t = aggregate(survey, [square("a", 0, 0, 5000, 5000)], model=model, simulations=0)
    want = (100 * (1e-4 + 3e-4) + brute_covariance(xy, model)) / 100 ** 2
    assert t.rows[0].mean_se ** 2 == pytest.approx(want, rel=1e-6)


def test_grid_check():
    xy = lattice(10, 8, 2.0)
    check_grid(xy, 2.0, "r.csv")
    check_grid(xy + 1e-5, 2.0, "r.csv")  # rounding of a LAS scale
    with pytest.raises(UsageError, match=r"r\.csv: the core points are not on a grid of cell 3"):
        check_grid(xy, 3.0, "r.csv")
    with pytest.raises(UsageError, match=r"coarser than --cell-size 1 \(--grid 2\?\)"):
        check_grid(xy, 1.0, "r.csv")
    with pytest.raises(UsageError, match="several core points in one cell"):
        check_grid(np.vstack([xy, xy[:1]]), 2.0, "r.csv")
    jitter = xy.copy()
    jitter[3] += [0.3, 0.0]
    with pytest.raises(UsageError, match="not on a grid"):
        check_grid(jitter, 2.0, "r.csv")


def test_region_names_must_be_unique():
    survey = Survey(lattice(4, 4, 1.0), np.zeros(16), np.ones(16), np.ones(16))
    with pytest.raises(UsageError, match="'a' are used more than once"):
        aggregate(survey, [square("a", 0, 0, 1, 1), square("a", 1, 1, 2, 2)], simulations=0)
    with pytest.raises(UsageError, match="name of the total row"):
        aggregate(survey, [square(TOTAL, 0, 0, 1, 1)], simulations=0)


def _simulated_survey(xy, truth, model, u2, seed):
    field = sample_field(xy, model, seed)
    noise = np.random.default_rng([seed, 99]).standard_normal(len(xy)) * np.sqrt(u2)
    return Survey(xy, truth + field + noise, np.full(len(xy), 1.0), u2)


def test_intervals_cover_the_true_mean_and_volume_with_correlated_errors():
    """100 seeded surveys (validation/aggregate_coverage.py runs 400): the 95 % intervals with the
    model cover the true mean within the binomial 99 % interval of 0.95 (88 to 99 of 100); without
    the model the same surveys' intervals cover far less (the test can fail both ways)."""
    cell = 1.0
    xy = lattice(48, 48, cell)
    model = ErrorModel(0.0, (Component("spherical", 1e-3, 12.0),))
    u2 = np.full(len(xy), 4e-4)
    truth = np.where(xy[:, 0] < 1024, 0.3, -0.1)
    regions = [square("left", 1000, 2000, 1024, 2048), square("patch", 1030, 2010, 1046, 2030)]
    inside = np.stack([region_index(xy, [p]) == 0 for p in regions])
    true_mean = [float(truth[inside[0]].mean()), float(truth[inside[1]].mean()), float(truth[inside.any(0)].mean())]
    assert true_mean[:2] == pytest.approx([0.3, -0.1])
    covered = np.zeros((2, 3), dtype=int)
    surveys = 100
    for s in range(surveys):
        survey = _simulated_survey(xy, truth, model, u2, seed=1000 + s)
        for k, m in enumerate((model, None)):
            t = aggregate(survey, regions, model=m, cell=cell, simulations=0)
            for r, row in enumerate(t.rows):
                covered[k, r] += row.mean_low <= true_mean[r] <= row.mean_high
                vol = true_mean[r] * row.with_distance * cell * cell
                assert (row.volume_low <= vol <= row.volume_high) == (row.mean_low <= true_mean[r] <= row.mean_high)
    assert (covered[0] >= 88).all() and (covered[0] <= 99).all(), covered
    assert (covered[1] <= 60).all(), covered


def _write_result(path, xy, d, lod, sigma, n):
    with open(path, "w") as f:
        f.write("x,y,z,distance,lod,significant,n1,n2,sigma1,sigma2,nx,ny,nz\n")
        for (x, y), di, li in zip(xy, d, lod):
            f.write(f"{float(x)!r},{float(y)!r},0.0,{float(di)!r},{float(li)!r},{int(abs(di) > li)},{n},{n},"
                    f"{sigma!r},{sigma!r},0,0,1\n")


def test_command_writes_csv_and_json(tmp_path, capsys):
    xy = lattice(12, 10, 0.5, 0.0, 0.0)
    d = np.full(len(xy), 0.2)
    d[4] = np.nan
    _write_result(tmp_path / "r.csv", xy, d, np.full(len(xy), 0.05), 0.01, 10)
    (tmp_path / "regions.wkt").write_text("POLYGON ((0 0, 3 0, 3 5, 0 5, 0 0))\nPOLYGON ((3 0, 6 0, 6 5, 3 5, 3 0))\n")
    save(tmp_path / "m.json", MODEL)
    assert main(["aggregate", str(tmp_path / "r.csv"), "--regions", str(tmp_path / "regions.wkt"), "-o",
                 str(tmp_path / "t.csv"), "--cell-size", "0.5", "--error-model", str(tmp_path / "m.json"),
                 "--simulations", "5"]) == 0
    assert "wrote" in capsys.readouterr().out
    rows = list(csv.DictReader(open(tmp_path / "t.csv")))
    assert [r["region"] for r in rows] == ["0", "1", TOTAL]
    assert float(rows[0]["volume"]) == pytest.approx(0.2 * 59 * 0.25)
    assert rows[0]["intervals"] == "correlated" and float(rows[0]["se_correlated"]) > 0
    # no --cell-size: no volume or area column at all, and a note saying why
    assert main(["aggregate", str(tmp_path / "r.csv"), "--regions", str(tmp_path / "regions.wkt"), "-o",
                 str(tmp_path / "t.json"), "-q", "--confidence", "0.9"]) == 0
    doc = json.loads((tmp_path / "t.json").read_text())
    assert doc["format"] == "m3c2kit-aggregate" and doc["confidence"] == 0.9 and doc["intervals"] == "uncorrelated only"
    assert "volume" not in doc["regions"][0] and "significant_area" not in doc["regions"][0]
    assert any("no --cell-size" in n for n in doc["notes"])
    assert doc["regions"][0]["mean"] == pytest.approx(0.2)


@pytest.mark.parametrize("extra, needle", [
    (["-o", "t.txt"], "-o t.txt: the table is written as .csv or .json"),
    (["-o", "t.csv", "--cell-size", "0.7"], "r.csv: the core points are not on a grid of cell 0.7"),
    (["-o", "t.csv", "--confidence", "1.5"], "--confidence"),
    (["-o", "t.csv", "--error-model", "none.json"], "none.json: no such file"),
])
def test_command_errors(tmp_path, capsys, monkeypatch, extra, needle):
    monkeypatch.chdir(tmp_path)
    xy = lattice(4, 4, 0.5, 0.0, 0.0)
    _write_result(tmp_path / "r.csv", xy, np.full(16, 0.1), np.full(16, 0.05), 0.01, 10)
    (tmp_path / "g.wkt").write_text("POLYGON ((0 0, 3 0, 3 3, 0 0))\n")
    code = main(["aggregate", "r.csv", "--regions", "g.wkt", *extra])
    assert code == 2 and needle in capsys.readouterr().err
    assert not (tmp_path / "t.csv").exists()


def test_missing_fields_named(tmp_path, capsys):
    (tmp_path / "r.csv").write_text("x,y,z,distance\n0,0,0,1\n")
    (tmp_path / "g.wkt").write_text("POLYGON ((0 0, 3 0, 3 3, 0 0))\n")
    assert main(["aggregate", str(tmp_path / "r.csv"), "--regions", str(tmp_path / "g.wkt"), "-o",
                 str(tmp_path / "t.csv")]) == 2
    err = capsys.readouterr().err
    assert "no 'lod', 'sigma1', 'sigma2', 'n1', 'n2' field" in err and "--all-fields" in err


@pytest.mark.parametrize("name", ["=HYPERLINK(\"http://x\",\"y\")", "+1+1", "-2+3", "@SUM(A1)", "\tcmd", "\rcmd"])
def test_a_region_name_is_never_a_live_formula_in_the_csv(name, tmp_path, capsys):
    """Issue 42: a region named =HYPERLINK(...) landed in the CSV as a live spreadsheet formula.
    Text that a spreadsheet evaluates gets a leading apostrophe; the JSON keeps the name as it is."""
    xy = lattice(4, 4, 0.5, 0.0, 0.0)
    _write_result(tmp_path / "r.csv", xy, np.full(16, 0.1), np.full(16, 0.05), 0.01, 10)
    ring = [[0, 0], [3, 0], [3, 3], [0, 3], [0, 0]]
    (tmp_path / "g.geojson").write_text(json.dumps({"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": {"name": name}, "geometry": {"type": "Polygon", "coordinates": [ring]}}]}))
    for out in ("t.csv", "t.json"):
        assert main(["aggregate", str(tmp_path / "r.csv"), "--regions", str(tmp_path / "g.geojson"), "-o",
                     str(tmp_path / out), "-q"]) == 0
    rows = list(csv.DictReader(open(tmp_path / "t.csv", newline="")))
    assert rows[0]["region"] == "'" + name
    assert json.loads((tmp_path / "t.json").read_text())["regions"][0]["region"] == name


def _regions_case(tmp_path, geojson: dict, crs: str | None = None):
    xy = lattice(4, 4, 0.5, 0.0, 0.0)
    _write_result(tmp_path / "r.csv", xy, np.full(16, 0.1), np.full(16, 0.05), 0.01, 10)
    if crs is not None:  # the result as a LAS file in that CRS
        pyproj = pytest.importorskip("pyproj")
        from m3c2kit.io import read_cloud, write_cloud_table
        from m3c2kit.io.cloud import Cloud
        cloud = read_cloud(tmp_path / "r.csv")
        xyz = cloud.xyz + [500000.0, 4000000.0, 0.0]
        write_cloud_table(tmp_path / "r.las", xyz, cloud.fields, like=Cloud(xyz, crs=pyproj.CRS(crs).to_wkt()))
    (tmp_path / "g.geojson").write_text(json.dumps(geojson))


def _collection(*rings, crs=None):
    doc = {"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": {"name": f"r{k}"}, "geometry": {"type": "Polygon", "coordinates": [ring]}}
        for k, ring in enumerate(rings)]}
    if crs:
        doc["crs"] = {"type": "name", "properties": {"name": crs}}
    return doc


SQUARE = [[0, 0], [3, 0], [3, 3], [0, 3], [0, 0]]


@pytest.mark.parametrize("ring, words", [
    ([[0, 0], [2, 2], [2, 0], [0, 2], [0, 0]], "region 'r0': self-intersecting"),  # a bow tie
    ([[0, 0], [3, 3], [3, 0], [0, 1], [0, 0]], "region 'r0': self-intersecting"),  # unequal lobes
    ([[0, 0], [1, 1], [2, 2], [0, 0]], "region 'r0': a region of zero area"),
])
def test_a_region_without_a_well_defined_inside_is_refused(ring, words, tmp_path, capsys):
    """Issue 42: self-intersecting and zero-area regions were accepted and summed."""
    _regions_case(tmp_path, _collection(ring))
    assert main(["aggregate", str(tmp_path / "r.csv"), "--regions", str(tmp_path / "g.geojson"), "-o",
                 str(tmp_path / "t.csv")]) == 2
    err = capsys.readouterr().err
    assert str(tmp_path / "g.geojson") in err and words in err
    assert not (tmp_path / "t.csv").exists()


def test_a_hole_touching_its_exterior_at_a_point_is_a_valid_region(tmp_path, capsys):
    _regions_case(tmp_path, {"type": "Polygon", "coordinates": [SQUARE, [[0, 0], [2, 1], [1, 2], [0, 0]]]})
    assert main(["aggregate", str(tmp_path / "r.csv"), "--regions", str(tmp_path / "g.geojson"), "-o",
                 str(tmp_path / "t.csv"), "-q"]) == 0


def test_regions_in_another_crs_are_refused(tmp_path, capsys):
    """Issue 42: EPSG:4326 regions over a UTM result summed 0 core points, NaN, exit 0."""
    _regions_case(tmp_path, _collection([[10, 45], [11, 45], [11, 46], [10, 46], [10, 45]],
                                        crs="urn:ogc:def:crs:EPSG::4326"), crs="EPSG:32633")
    assert main(["aggregate", str(tmp_path / "r.las"), "--regions", str(tmp_path / "g.geojson"), "-o",
                 str(tmp_path / "t.csv")]) == 2
    err = capsys.readouterr().err
    assert "the regions are in" in err and "reproject the regions" in err and not (tmp_path / "t.csv").exists()
    # the same CRS, named either way, passes
    ring = [[500000, 4000000], [500003, 4000000], [500003, 4000003], [500000, 4000003], [500000, 4000000]]
    _regions_case(tmp_path, _collection(ring, crs="EPSG:32633"), crs="EPSG:32633")
    assert main(["aggregate", str(tmp_path / "r.las"), "--regions", str(tmp_path / "g.geojson"), "-o",
                 str(tmp_path / "t.csv"), "-q"]) == 0


def test_regions_that_hold_no_core_point_are_said(tmp_path, capsys):
    far = [[100, 100], [101, 100], [101, 101], [100, 101], [100, 100]]
    _regions_case(tmp_path, _collection(far))  # no CRS named: only the extents tell
    assert main(["aggregate", str(tmp_path / "r.csv"), "--regions", str(tmp_path / "g.geojson"), "-o",
                 str(tmp_path / "t.csv")]) == 2
    err = capsys.readouterr().err
    assert "no region holds a point of" in err and "another CRS" in err and not (tmp_path / "t.csv").exists()
    _regions_case(tmp_path, _collection(SQUARE, far))
    assert main(["aggregate", str(tmp_path / "r.csv"), "--regions", str(tmp_path / "g.geojson"), "-o",
                 str(tmp_path / "t.csv"), "-q"]) == 0
    assert "warning:" in (err := capsys.readouterr().err) and "region 'r1' holds no core point" in err


def test_the_error_models_d_is_checked_against_the_results(tmp_path, capsys):
    """Issue 42: aggregate never checked the model's d. A compare output does not record its d:
    --projection-scale gives it (a d other than the model's is refused, naming both); without
    it the model's is taken and the run says so; without a model it would change nothing."""
    xy = lattice(6, 6, 0.5, 0.0, 0.0)
    _write_result(tmp_path / "r.csv", xy, np.full(len(xy), 0.1), np.full(len(xy), 0.05), 0.01, 10)
    (tmp_path / "g.wkt").write_text("POLYGON ((0 0, 3 0, 3 3, 0 3, 0 0))\n")
    from dataclasses import replace
    fitted = 0.5
    save(tmp_path / "m.json", replace(MODEL, projection_scale=fitted, mean_u2=1e-6))
    run = ["aggregate", str(tmp_path / "r.csv"), "--regions", str(tmp_path / "g.wkt"), "-o", str(tmp_path / "t.csv"),
           "--simulations", "0", "-q"]
    assert main([*run, "--error-model", str(tmp_path / "m.json"), "--projection-scale", str(2 * fitted)]) == 2
    assert capsys.readouterr().err == (f"m3c2: error: --error-model {tmp_path / 'm.json'} was fitted at "
                                       f"--projection-scale {fitted:g}, {tmp_path / 'r.csv'}'s is {2 * fitted:g}: the "
                                       "correlated variance of a cylinder mean depends on d; fit a model on a result "
                                       "of this d (m3c2 variogram)\n")
    assert not (tmp_path / "t.csv").exists()
    assert main([*run, "--error-model", str(tmp_path / "m.json"), "--projection-scale", str(fitted)]) == 0
    assert capsys.readouterr().err == ""
    assert main([*run, "--error-model", str(tmp_path / "m.json")]) == 0
    assert f"taken as the error model's, d = {fitted:g}; give --projection-scale" in capsys.readouterr().err
    assert main([*run, "--projection-scale", "1"]) == 2
    assert "without a model it would change nothing" in capsys.readouterr().err


def test_regions_in_the_horizontal_part_of_a_compound_crs_are_taken_and_an_unreadable_crs_refused(tmp_path, capsys):
    """Issue 42 (hostile round 2): a LAS result in 'UTM 33N + EGM96 height' refused regions in UTM
    33N, the only CRS a plan-view polygon can carry; a regions CRS PROJ cannot read was accepted."""
    ring = [[500000, 4000000], [500003, 4000000], [500003, 4000003], [500000, 4000003], [500000, 4000000]]
    _regions_case(tmp_path, _collection(ring, crs="urn:ogc:def:crs:EPSG::32633"), crs="EPSG:32633+5773")
    assert main(["aggregate", str(tmp_path / "r.las"), "--regions", str(tmp_path / "g.geojson"), "-o",
                 str(tmp_path / "t.csv"), "-q"]) == 0
    _regions_case(tmp_path, _collection(ring, crs="urn:ogc:def:crs:EPSG::32632"), crs="EPSG:32633+5773")
    assert main(["aggregate", str(tmp_path / "r.las"), "--regions", str(tmp_path / "g.geojson"), "-o",
                 str(tmp_path / "t2.csv"), "-q"]) == 2
    assert "reproject the regions" in capsys.readouterr().err
    _regions_case(tmp_path, _collection(ring, crs="garbage-crs"), crs="EPSG:32633")
    assert main(["aggregate", str(tmp_path / "r.las"), "--regions", str(tmp_path / "g.geojson"), "-o",
                 str(tmp_path / "t3.csv"), "-q"]) == 2
    assert capsys.readouterr().err == (f"m3c2: error: --regions {tmp_path / 'g.geojson'}: its CRS garbage-crs cannot be "
                                       "read: name one PROJ knows (as EPSG:32633 or urn:ogc:def:crs:EPSG::32633) or none (the "
                                       "data's coordinates)\n")
    assert not (tmp_path / "t2.csv").exists() and not (tmp_path / "t3.csv").exists()


def test_a_cell_or_a_region_beyond_the_float_range_is_refused_in_words(tmp_path, capsys):
    """Hostile round 2: --cell-size 1e-300 overflowed the cell index (numpy's cast warning, then
    'several core points in one cell'); a region at 1e300 overflowed its area ('zero area')."""
    xy = lattice(4, 4, 0.5, 0.0, 0.0)
    _write_result(tmp_path / "r.csv", xy, np.full(16, 0.1), np.full(16, 0.05), 0.01, 10)
    (tmp_path / "g.wkt").write_text("POLYGON ((0 0, 3 0, 3 3, 0 3, 0 0))\n")
    run = ["aggregate", str(tmp_path / "r.csv"), "-o", str(tmp_path / "t.csv"), "-q"]
    assert main([*run, "--regions", str(tmp_path / "g.wkt"), "--cell-size", "1e-300"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--cell-size 1e-300 is too small for the core points' extent" in err, err
    (tmp_path / "far.wkt").write_text("POLYGON ((-1e300 -1e300, 1e300 -1e300, 1e300 1e300, -1e300 1e300, -1e300 -1e300))\n")
    assert main([*run, "--regions", str(tmp_path / "far.wkt")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "are too large for its area to be computed" in err, err
    assert not (tmp_path / "t.csv").exists()


def test_repeated_core_points_are_said(tmp_path, capsys):
    """Hostile round 2: a reference with every point twice (merged scans) as its own core points:
    aggregate counted 1800 core points for 900 positions and narrowed the interval 1.6x, silently."""
    xy = lattice(4, 4, 0.5, 0.0, 0.0)
    twice = np.concatenate([xy, xy])
    _write_result(tmp_path / "r.csv", twice, np.full(32, 0.1), np.full(32, 0.05), 0.01, 10)
    (tmp_path / "g.wkt").write_text("POLYGON ((-1 -1, 3 -1, 3 3, -1 3, -1 -1))\n")
    assert main(["aggregate", str(tmp_path / "r.csv"), "--regions", str(tmp_path / "g.wkt"), "-o",
                 str(tmp_path / "t.csv"), "-q", "--simulations", "0"]) == 0
    err = capsys.readouterr().err
    assert "16 core points repeat the position of another (32 core points at 16 positions)" in err, err
    _write_result(tmp_path / "once.csv", xy, np.full(16, 0.1), np.full(16, 0.05), 0.01, 10)
    assert main(["aggregate", str(tmp_path / "once.csv"), "--regions", str(tmp_path / "g.wkt"), "-o",
                 str(tmp_path / "t2.csv"), "-q", "--simulations", "0"]) == 0
    assert "repeat the position" not in capsys.readouterr().err
