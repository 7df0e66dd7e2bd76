"""2D mode (--grid, section 6.1.2): grid core points, vertical normals, d = 1.1 cell, GeoTIFF rasters."""
import csv

import numpy as np
import pytest

rasterio = pytest.importorskip("rasterio")
from rasterio.crs import CRS  # noqa: E402
from rasterio.transform import rowcol, xy  # noqa: E402

import m3c2kit  # noqa: E402
from m3c2kit.io.fields import typed_columns  # noqa: E402
from m3c2kit.run import raster  # noqa: E402
from m3c2kit.cli.main import main  # noqa: E402
from m3c2kit.base.errors import CloudWriteError  # noqa: E402
from m3c2kit.io import Cloud, read_cloud, write_cloud_table  # noqa: E402

from synthetic import write_xyz  # noqa: E402

CELL = 2.0
WKT = CRS.from_epsg(32633).to_wkt()
X0, Y0 = 500000.0, 4500000.0  # UTM-like coordinates: the geotransform must keep them exactly


def surface(x, y):
    return 0.5 * np.sin((x - X0) / 7.0) + 0.02 * (y - Y0)


def change(x, y):
    """The known change field: a 0.3 high mound on a 0.1 lowering."""
    return 0.3 * np.exp(-(((x - X0) - 20) ** 2 + ((y - Y0) - 14) ** 2) / 40.0) - 0.1


def dod_pair(noise=0.003, hole=True, seed=3):
    """Two gridded surfaces over 40 x 30 m, z2 = z1 + change(x, y) + noise; the reference has a
    hole (no points) over x in [8, 12), y in [20, 24) (relative)."""
    rng = np.random.default_rng(seed)
    s = 0.25
    g = np.stack(np.meshgrid(np.arange(0.1, 40, s), np.arange(0.1, 30, s)), -1).reshape(-1, 2) + [X0, Y0]

    def cloud(extra):
        xy = g + rng.uniform(-s / 3, s / 3, g.shape)
        return np.column_stack([xy, surface(xy[:, 0], xy[:, 1]) + extra(xy) + rng.normal(0, noise, len(xy))])

    ref = cloud(lambda xy: 0.0)
    cmp = cloud(lambda xy: change(xy[:, 0], xy[:, 1]))
    if hole:
        rx, ry = ref[:, 0] - X0, ref[:, 1] - Y0
        ref = ref[~((rx >= 8) & (rx < 12) & (ry >= 20) & (ry < 24))]
    return ref, cmp


def read_csv(path):
    with open(path) as f:
        rows = list(csv.reader(f))
    body = np.array(rows[1:], dtype=float)
    return {name: body[:, k] for k, name in enumerate(rows[0])}


@pytest.fixture(scope="module")
def las_pair(tmp_path_factory):
    d = tmp_path_factory.mktemp("grid")
    ref, cmp = dod_pair()
    like = Cloud(np.zeros((1, 3)), crs=WKT)
    write_cloud_table(d / "ref.las", ref, {}, like=like)
    write_cloud_table(d / "cmp.las", cmp, {}, like=like)
    return d, read_cloud(d / "ref.las"), read_cloud(d / "cmp.las")


@pytest.fixture(scope="module")
def grid_run(las_pair):
    d, ref, cmp = las_pair
    out = d / "change.csv"
    assert main(["compare", str(d / "ref.las"), str(d / "cmp.las"), "-o", str(out), "--grid", str(CELL),
                 "--max-depth", "2", "--quiet"]) == 0
    return d, out, read_csv(out), ref, cmp


def open_raster(out, name):
    return rasterio.open(raster.raster_paths(out)[name])


def test_every_raster_is_written_beside_the_output(grid_run):
    d, out, table, _, _ = grid_run
    names = sorted(p.name for p in d.iterdir())
    for name in ("distance", "lod", "significant", "n1", "n2", "status"):
        assert f"change_{name}.tif" in names
    assert not [n for n in names if n.startswith(".")], names  # no temporary left


def test_rasters_equal_the_point_table_at_the_right_pixels(grid_run):
    _, out, table, _, _ = grid_run
    x, y = table["x"], table["y"]
    for name in ("distance", "lod", "significant", "n1", "n2", "status"):
        with open_raster(out, name) as src:
            band = src.read(1)
            rows, cols = rowcol(src.transform, x, y)
            rows, cols = np.asarray(rows), np.asarray(cols)
            # the pixel centre is the core point
            cx, cy = xy(src.transform, rows, cols)
            np.testing.assert_allclose(cx, x, atol=1e-6)
            np.testing.assert_allclose(cy, y, atol=1e-6)
            got = band[rows, cols].astype(float)
            want = table[name]
            if name in ("distance", "lod"):
                want = want.astype(np.float32).astype(float)
                np.testing.assert_array_equal(np.isnan(got), np.isnan(want), err_msg=name)
                np.testing.assert_array_equal(got[~np.isnan(got)], want[~np.isnan(want)], err_msg=name)
            else:
                nodata = src.nodata
                np.testing.assert_array_equal(got, np.where(np.isnan(want), nodata, want), err_msg=name)


def test_several_cells_by_coordinates(grid_run):
    """Cells picked by map coordinates: the lowest-y row is the LAST image row (north up)."""
    _, out, table, _, _ = grid_run
    with open_raster(out, "distance") as src:
        band = src.read(1)
        assert src.transform.e < 0 and src.transform.a == CELL
        for k in (0, len(table["x"]) // 3, len(table["x"]) - 1, int(np.argmax(table["y"])), int(np.argmin(table["y"]))):
            x, y = table["x"][k], table["y"][k]
            r = int((src.bounds.top - y) // CELL)
            c = int((x - src.bounds.left) // CELL)
            assert band[r, c] == np.float32(table["distance"][k])
        lowest = int(np.argmin(table["y"]))
        assert (src.bounds.top - table["y"][lowest]) // CELL == src.height - 1


def test_nodata_where_the_cell_has_no_reference_point(grid_run):
    _, out, table, ref, _ = grid_run
    g = raster.grid_core_points(ref, CELL)
    occupied = np.zeros((g.rows, g.cols), bool)
    occupied[g.image_rows(), g.col.astype(int)] = True
    assert (~occupied).sum() >= 4  # the 4 x 4 m hole
    for name in ("distance", "lod", "significant", "n1", "n2", "status"):
        with open_raster(out, name) as src:
            band = src.read(1)
            assert (src.height, src.width) == (g.rows, g.cols)
            if np.issubdtype(band.dtype, np.floating):
                assert np.isnan(src.nodata) and np.isnan(band[~occupied]).all()
            else:
                assert (band[~occupied] == src.nodata).all(), name
    # the hole's cells, by map coordinates
    with open_raster(out, "distance") as src:
        for hx, hy in ((9, 21), (11, 23)):
            r, c = src.index(X0 + hx, Y0 + hy)
            assert np.isnan(src.read(1)[r, c])


def test_dtypes_nodata_and_descriptions(grid_run):
    _, out, _, _, _ = grid_run
    for name, (dtype, nodata, description) in raster.RASTERS.items():
        with open_raster(out, name) as src:
            assert src.dtypes[0] == dtype and src.count == 1
            assert src.descriptions[0] == description
            assert (np.isnan(src.nodata) if np.isnan(nodata) else src.nodata == nodata)


def test_crs_is_the_reference_crs(grid_run):
    _, out, _, ref, _ = grid_run
    assert ref.crs is not None
    with open_raster(out, "distance") as src:
        assert src.crs == CRS.from_wkt(WKT)
        assert src.crs.to_epsg() == 32633


def test_crs_of_the_real_autzen_pair_is_kept(shared_data, tmp_path):
    pair = shared_data / "pairs" / "autzen-bmx"
    out = tmp_path / "autzen.laz"
    assert main(["compare", str(pair / "autzen-bmx-2010.las"), str(pair / "autzen-bmx-2023.las"), "-o", str(out),
                 "--grid", "3", "--max-depth", "5", "--quiet"]) == 0
    ref = read_cloud(pair / "autzen-bmx-2010.las")
    with open_raster(out, "distance") as src:
        assert src.crs == CRS.from_wkt(ref.crs)  # compound: NAD83 / Oregon LCC (m) + NAVD88 height (ftUS)
    assert read_cloud(out).crs == ref.crs


def test_no_crs_writes_without_one_and_warns(tmp_path, capsys):
    ref, cmp = dod_pair(hole=False)
    write_xyz(tmp_path / "ref.xyz", ref[::4])
    write_xyz(tmp_path / "cmp.xyz", cmp[::4])
    out = tmp_path / "o.csv"
    assert main(["compare", str(tmp_path / "ref.xyz"), str(tmp_path / "cmp.xyz"), "-o", str(out), "--grid", "4",
                 "--max-depth", "2", "--quiet"]) == 0
    assert "without a CRS" in capsys.readouterr().err
    with open_raster(out, "distance") as src:
        assert src.crs is None


def test_projection_scale_defaults_to_1_1_cell(grid_run):
    d, out, table, ref, cmp = grid_run
    g = raster.grid_core_points(ref, CELL)
    np.testing.assert_array_equal(np.column_stack([table["x"], table["y"], table["z"]]), g.core_points)
    want = m3c2kit.compare(ref, cmp, g.core_points, normal_source="vertical", projection_scale=1.1 * CELL,
                        max_depth=2).columns()
    stored = typed_columns(want)  # the table's stored types (float32 measures: m3c2kit.io.fields)
    for name in ("distance", "lod", "n1", "n2", "status"):
        np.testing.assert_array_equal(table[name], np.asarray(stored[name], float), err_msg=name)
    other = m3c2kit.compare(ref, cmp, g.core_points, normal_source="vertical", projection_scale=CELL, max_depth=2)
    assert not np.array_equal(other.n1, want["n1"])


def test_explicit_projection_scale_wins(las_pair, tmp_path):
    d, ref, cmp = las_pair
    out = tmp_path / "p.csv"
    assert main(["compare", str(d / "ref.las"), str(d / "cmp.las"), "-o", str(out), "--grid", str(CELL),
                 "--projection-scale", "3", "--max-depth", "2", "--quiet"]) == 0
    g = raster.grid_core_points(ref, CELL)
    want = m3c2kit.compare(ref, cmp, g.core_points, normal_source="vertical", projection_scale=3, max_depth=2)
    np.testing.assert_array_equal(read_csv(out)["n1"], want.n1.astype(float))


def test_normals_are_vertical(grid_run):
    _, _, table, _, _ = grid_run
    assert (table["nz"] == 1).all() and (table["nx"] == 0).all() and (table["ny"] == 0).all()


def test_dem_of_difference_recovers_the_known_field(grid_run):
    _, out, table, _, _ = grid_run
    with open_raster(out, "distance") as src:
        band = src.read(1).astype(float)
        rows, cols = np.mgrid[0:src.height, 0:src.width]
        cx, cy = xy(src.transform, rows.ravel(), cols.ravel())
    cx, cy = np.asarray(cx).reshape(band.shape), np.asarray(cy).reshape(band.shape)
    ok = np.isfinite(band)
    # inner cells (complete cylinders); the change field varies little over one cell
    inner = ok & (cx - X0 > 2) & (cx - X0 < 38) & (cy - Y0 > 2) & (cy - Y0 < 28)
    assert inner.sum() > 200
    err = band[inner] - change(cx[inner], cy[inner])
    assert np.abs(err).max() < 0.01, np.abs(err).max()
    assert abs(np.mean(err)) < 0.002
    with open_raster(out, "significant") as src:
        sig = src.read(1)
    assert (sig[inner] == 1).mean() > 0.95  # 0.1 to 0.3 m change vs ~3 mm noise


@pytest.mark.parametrize("extra, message", [
    (["--normal-scale", "1"], "--normal-scale"),
    (["--normal-source", "reference"], "--normal-source"),
    (["--position", "reference"], "--position"),
    (["--core-spacing", "1"], "not allowed with"),
    (["--grid", "-1"], "positive"),
])
def test_usage_errors(las_pair, tmp_path, capsys, extra, message):
    d, _, _ = las_pair
    args = ["compare", str(d / "ref.las"), str(d / "cmp.las"), "-o", str(tmp_path / "o.csv"), "--max-depth", "2"]
    if "--grid" not in extra:
        args += ["--grid", "2"]
    assert main(args + extra) == 2
    assert message in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_max_depth_is_chosen_from_the_data_when_not_given(las_pair, tmp_path, capsys):
    """As every compare run's (docs/cli.md, "Scales from the data"); the grid gives D and d."""
    d, _, _ = las_pair
    assert main(["compare", str(d / "ref.las"), str(d / "cmp.las"), "-o", str(tmp_path / "o.csv"), "--grid", "2"]) == 0
    out = capsys.readouterr().out
    chosen = [line for line in out.splitlines() if line.startswith("m3c2: scales chosen from the data")]
    assert len(chosen) == 1 and chosen[0].split("): ")[1].split()[0::2] == ["--max-depth"], out


def test_a_failed_raster_leaves_no_output(las_pair, tmp_path, monkeypatch):
    d, _, _ = las_pair
    out = tmp_path / "o.laz"
    out.write_bytes(b"old")

    def fail(paths, *a, **k):
        next(iter(paths.values())).write_bytes(b"partial")
        raise CloudWriteError("disk full")

    monkeypatch.setattr(raster, "write_rasters", fail)
    assert main(["compare", str(d / "ref.las"), str(d / "cmp.las"), "-o", str(out), "--grid", "2",
                 "--max-depth", "2", "--quiet"]) == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["o.laz"]
    assert out.read_bytes() == b"old"


def test_raster_paths():
    from pathlib import Path
    p = raster.raster_paths(Path("/a/b/run.copc.laz"))
    assert p["distance"] == Path("/a/b/run_distance.tif")
    assert raster.raster_paths("x.csv")["n2"] == Path("x_n2.tif")


def test_grid_core_points_flip():
    pts = np.array([[0.5, 0.5, 1.0], [2.5, 0.5, 2.0], [0.5, 4.5, 3.0]])
    g = raster.grid_core_points(pts, 1.0)
    img = g.image(g.core_points[:, 2], "float32", np.nan)
    assert img.shape == (5, 3)
    assert img[4, 0] == 1 and img[4, 2] == 2 and img[0, 0] == 3  # lowest y at the bottom row
    assert g.transform.f == g.y0 + 5.0
