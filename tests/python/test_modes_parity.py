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
        folder.mkdir()
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


def test_report_and_figures_in_every_mode(pair, scheduler, capsys, monkeypatch, tmp_path):  # noqa: F811
    runs = every_mode(tmp_path, [*inputs(pair), "-o", "change.csv", *BASE, "--core-spacing", "0.3",
                                 "--report", "change.html", "--report-png", "fig"], scheduler, capsys, monkeypatch)
    files, _ = runs["memory"]
    assert {"change.html", "fig_distance.png", "fig_normals.png"} <= set(files)
    assert b"reference points</td><td>4000" in files["change.html"]  # counted by streaming in tiles


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
