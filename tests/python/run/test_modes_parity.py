"""Every mode takes every option (issue 32): --grid rasters, --report and --report-png, --crs and the
core points' own attributes are written by a tiled run (two tile sizes), a --memory-limit run and a
run on a Dask cluster byte for byte as by the in-memory run, and every run prints the same
warnings, the diagnosis of empty cylinders included (m3c2kit.run.cylinder_points streams the
diagnosed cylinders' points). Each mode writes into a folder of its own under the same relative
names: the report names the output file."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from m3c2kit.cli.main import main
from m3c2kit.io import read_cloud, write_cloud_table
from m3c2kit.run import memory
from test_run_modes import BASE, TILES, pair, scheduler  # noqa: F401 - the fixtures, shared

pytest.importorskip("rasterio")


def memory_limit() -> str:
    """A limit this process can run under, whatever the tests before it left resident."""
    return f"{(max(memory.BASE_BYTES, memory.rss_bytes() + memory.HEADROOM_BYTES) + 256 * 2**20) // 2**20}MiB"


def every_mode(root: Path, argv: list, scheduler, capsys, monkeypatch) -> dict:  # noqa: F811
    """Runs `m3c2 compare *argv` in memory, tiled at TILES, under a memory limit and on Dask, each in
    its own folder; returns {mode: ({file name: bytes}, [warning lines])} after checking that every
    mode wrote the in-memory run's files, byte for byte, and printed its warnings."""
    modes = {"memory": []} | {f"tile{s}": ["--tile-size", s] for s in TILES}
    modes["limit"] = ["--memory-limit", memory_limit()]
    if scheduler is not None:
        modes["dask"] = ["--tile-size", "1.1", "--dask-scheduler", scheduler]
    runs = {}
    for mode, extra in modes.items():
        folder = root / mode
        folder.mkdir(parents=True)
        monkeypatch.chdir(folder)
        capsys.readouterr()
        assert main(["compare", *argv, *extra]) == 0, mode
        err = capsys.readouterr().err
        files = {p.name: p.read_bytes() for p in sorted(folder.iterdir())}
        assert not [name for name in files if name.startswith(".")], f"{mode}: a spill folder was left"
        runs[mode] = (files, [line for line in err.splitlines() if line.startswith("m3c2: warning: ")])
    expected, warned = runs["memory"]
    assert expected
    for mode, (files, warnings) in runs.items():
        assert sorted(files) == sorted(expected), mode
        for name, data in files.items():
            assert data == expected[name], f"{mode}: {name} differs from the in-memory run's"
        assert warnings == warned, f"{mode}: other warnings than the in-memory run's"
    return runs


def inputs(d: Path, core: str | None = None) -> list[str]:
    return [str(d / "ref.las"), str(d / "cmp.las")] + (["--core", str(d / core)] if core else [])


@pytest.mark.slow
def test_grid_rasters_with_crs_in_every_mode(pair, scheduler, capsys, monkeypatch, tmp_path):  # noqa: F811
    runs = every_mode(tmp_path, [*inputs(pair), "-o", "change.laz", "--grid", "0.25", "--max-depth", "0.5",
                                 "--crs", "EPSG:32633", "-q"], scheduler, capsys, monkeypatch)
    files, _ = runs["memory"]
    assert {f"change_{name}.tif" for name in ("distance", "lod", "significant", "n1", "n2", "status")} <= set(files)
    import rasterio
    with rasterio.open(tmp_path / "dask" / "change_distance.tif" if "dask" in runs
                       else tmp_path / "tile0.6" / "change_distance.tif") as r:
        assert r.crs.to_epsg() == 32633 and r.width == 16 and np.isfinite(r.read(1)).mean() > 0.9
    assert "32633" in read_cloud(tmp_path / "tile0.6" / "change.laz").crs


@pytest.mark.slow
def test_report_and_figures_in_every_mode(pair, scheduler, capsys, monkeypatch, tmp_path):  # noqa: F811
    runs = every_mode(tmp_path, [*inputs(pair), "-o", "change.csv", *BASE, "--core-spacing", "0.3",
                                 "--report", "change.html", "--report-png", "fig"], scheduler, capsys, monkeypatch)
    files, _ = runs["memory"]
    assert {"change.html", "fig_distance.png", "fig_normals.png"} <= set(files)
    assert b"reference points</td><td>4000" in files["change.html"]  # counted by streaming in tiles


@pytest.mark.slow
def test_crs_in_every_mode(pair, scheduler, capsys, monkeypatch, tmp_path):  # noqa: F811
    assert read_cloud(pair / "ref.las").crs is None  # --crs assigns it
    every_mode(tmp_path, [*inputs(pair, "core.xyz"), "-o", "change.laz", *BASE, "--crs", "EPSG:2056"],
               scheduler, capsys, monkeypatch)
    assert "2056" in read_cloud(tmp_path / "limit" / "change.laz").crs


@pytest.fixture(scope="module")
def core_files(pair):  # noqa: F811
    """Core files with fields of their own: some reference points (whose attributes the output
    carries), and the same points moved by a hair (no reference point: none carried)."""
    ref = read_cloud(pair / "ref.las")
    pick = np.random.default_rng(4).choice(len(ref), 250, replace=False)
    write_cloud_table(pair / "cores_of_ref.csv", ref.xyz[pick], {"label": np.arange(250.0)})
    write_cloud_table(pair / "cores_moved.csv", ref.xyz[pick] + 1e-3, {"label": np.arange(250.0)})
    return pair


@pytest.mark.slow
@pytest.mark.parametrize("core, suffix", [("cores_of_ref.csv", ".csv"), ("cores_of_ref.csv", ".laz"),
                                          ("cores_moved.csv", ".csv"), (None, ".laz")])
def test_core_attributes_in_every_mode(core_files, scheduler, capsys, monkeypatch, tmp_path, core,  # noqa: F811
                                       suffix):
    runs = every_mode(tmp_path, [*inputs(core_files, core), "-o", f"change{suffix}", *BASE, "--all-fields"
                                 if suffix == ".laz" else "--float64"], scheduler, capsys, monkeypatch)
    out = read_cloud(tmp_path / "tile0.6" / f"change{suffix}")
    if core == "cores_moved.csv":
        assert "sx" not in out.fields  # a core point that is no reference point: nothing carried
    else:
        assert {"sx", "point_source_id"} <= set(out.fields)
        ref = read_cloud(core_files / "ref.las")
        np.testing.assert_array_equal(out.fields["point_source_id"][:5], ref.fields["point_source_id"][
            [np.flatnonzero((ref.xyz == p).all(axis=1))[0] for p in out.xyz[:5]]])
    assert runs


@pytest.fixture(scope="module")
def half_overlap(tmp_path_factory):
    """A reference over 4 x 4 m and a compared cloud over its west half, 0.8 m higher on its north
    half: empty cylinders of no overlap (east) and beyond --max-depth (north-west)."""
    d = tmp_path_factory.mktemp("overlap")
    rng = np.random.default_rng(21)
    ref = np.column_stack([rng.uniform(0, 4, (6000, 2)), rng.normal(0, 0.003, 6000)])
    cmp_ = np.column_stack([rng.uniform(0, 2, 3000), rng.uniform(0, 4, 3000), rng.normal(0, 0.003, 3000)])
    cmp_[cmp_[:, 1] > 2, 2] += 0.8
    intensity = rng.integers(0, 900, 6000).astype(np.uint16)
    for suffix in (".las", ".xyz"):
        write_cloud_table(d / f"ref{suffix}", ref, {"intensity": intensity})
        write_cloud_table(d / f"cmp{suffix}", cmp_, {})
    return d


@pytest.mark.slow
@pytest.mark.parametrize("suffix", [".las", ".xyz"])
def test_warnings_and_the_empty_cylinder_diagnosis_in_every_mode(half_overlap, scheduler, capsys, monkeypatch,  # noqa: F811
                                                                  tmp_path, suffix):
    """Text inputs written to LAZ also have the writer's own warning (the scale it chose rounds the
    coordinates): after the run's, in every mode."""
    clouds = [str(half_overlap / f"ref{suffix}"), str(half_overlap / f"cmp{suffix}")]
    runs = every_mode(tmp_path, [*clouds, "-o", "change.laz", *BASE, "--core-spacing", "0.2"],
                      scheduler, capsys, monkeypatch)
    _, warnings = runs["memory"]
    assert any("no compared point in their cylinder at any depth" in w for w in warnings)
    assert any("only beyond --max-depth" in w for w in warnings)
    assert ("LAS stores the coordinates" in warnings[-1]) == (suffix == ".xyz"), warnings


def test_classifier_every_kept_point_carries_its_attributes(scheduler, capsys, monkeypatch, tmp_path):  # noqa: F811
    """--classifier with every kept reference point a core point: their attributes stream beside
    them through the keep mask (m3c2kit.run.attributes)."""
    pytest.importorskip("sklearn")
    from canupo_scene import GROUND, VEGETATION, scene
    from m3c2kit.classify import train, write_classifier

    a, la = scene(11, size=8)
    b, lb = scene(11, size=8)
    clf = train([(a[la == GROUND], "2"), (a[la == VEGETATION], "3")], [0.5, 1.0], max_per_class=3000)
    data = tmp_path / "data"
    data.mkdir()
    write_classifier(data / "c.json", clf)
    write_cloud_table(data / "ref.las", a, {"intensity": np.arange(len(a)).astype(np.uint16)})
    write_cloud_table(data / "cmp.las", b[lb == GROUND] + [0, 0, 0.1], {})
    runs = every_mode(tmp_path / "runs", [*inputs(data), "-o", "change.csv", *BASE, "--classifier",
                                          str(data / "c.json"), "--keep", "2"], scheduler, capsys, monkeypatch)
    header = runs["memory"][0]["change.csv"].split(b"\n", 1)[0].split(b",")
    assert b"intensity" in header


def test_the_streamed_diagnosis_is_the_whole_clouds(half_overlap, tmp_path):
    """The empty-cylinder diagnosis on streamed clouds (small chunks, tilted normals) gives the in-memory
    diagnosis's numbers exactly: the kept points are a subsequence holding every cylinder's points."""
    import m3c2kit
    from m3c2kit.io.streaming import PointSource
    from m3c2kit.run import quality
    from m3c2kit.run.cylinder_points import StreamedCloud

    ref, cmp_ = read_cloud(half_overlap / "ref.las"), read_cloud(half_overlap / "cmp.las")
    with pytest.warns(m3c2kit.M3C2Warning):
        result = m3c2kit.compare(ref, cmp_, core_spacing=0.15, normal_scale=0.3, projection_scale=0.1,
                                 max_depth=0.5, orient="1,2,5")
    streamed = [StreamedCloud(PointSource(half_overlap / f"{n}.las"), 700) for n in ("ref", "cmp")]
    for at_most in (None, 50):
        whole = quality.cylinder_diagnosis(ref.xyz, cmp_.xyz, result, projection_scale=0.1, max_depth=0.5,
                                           at_most=at_most)
        tiles = quality.cylinder_diagnosis(*streamed, result, projection_scale=0.1, max_depth=0.5, at_most=at_most)
        assert whole and [vars(d).keys() for d in whole] == [vars(d).keys() for d in tiles]
        for a, b in zip(whole, tiles):
            for key, value in vars(a).items():
                np.testing.assert_array_equal(value, getattr(b, key), err_msg=key)


def test_the_streamed_grid_is_the_engines(tmp_path):
    """--grid's core points by streaming (bands of rows, chunks of 777 points) are the engine's on the
    whole cloud, bit for bit, even and odd cells and ties included."""
    from m3c2kit.io.streaming import PointSource
    from m3c2kit.run import raster
    from m3c2kit.run.grid_cores import streamed_grid
    from m3c2kit.run.spill import SpillFolder

    rng = np.random.default_rng(7)
    xyz = np.column_stack([rng.uniform(-3, 7, 20000), rng.uniform(100, 104, 20000), rng.normal(0, 1, 20000)])
    xyz[::5, 2] = np.round(xyz[::5, 2], 1)
    np.save(tmp_path / "r.npy", xyz)
    for cell in (0.05, 0.37, 2.5):
        spills = tmp_path / f"spills{cell}"
        spills.mkdir()
        a = raster.grid_core_points(xyz, cell)
        b = streamed_grid(PointSource(tmp_path / "r.npy"), cell, SpillFolder(spills), 777)
        assert (a.x0, a.y0, a.cell, a.rows, a.cols) == (b.x0, b.y0, b.cell, b.rows, b.cols)
        assert a.core_points.tobytes() == b.core_points.tobytes()
        assert a.row.tobytes() == b.row.tobytes() and a.col.tobytes() == b.col.tobytes()


def test_attributes_match_as_the_engine_does(tmp_path):
    """Held core points get the attributes of the first reference point equal to each (duplicates,
    -0.0 and 0.0 alike), the reference itself every row, and points off the reference none."""
    from m3c2kit import engine
    from m3c2kit.io.streaming import PointSource
    from m3c2kit.run.attributes import core_attributes

    rng = np.random.default_rng(3)
    xyz = rng.integers(0, 5, (3000, 3)).astype(np.float64)  # many duplicates
    xyz[:10, 0] = -0.0
    values = {"i": np.arange(3000), "f": rng.normal(size=3000)}
    source = PointSource(tmp_path / "r.npy", cloud=m3c2kit_cloud(xyz, values))
    for core in (xyz[rng.choice(3000, 400)] + 0.0, xyz.copy()):
        index = engine.match_rows(xyz, core)
        got = core_attributes(source, core, rows=256).gather(len(core))
        for name, v in values.items():
            np.testing.assert_array_equal(got[name], v[index])
    assert core_attributes(source, xyz[:5] + 0.5, rows=256) is None


def m3c2kit_cloud(xyz, fields):
    from m3c2kit.io import Cloud
    return Cloud(xyz, fields)
