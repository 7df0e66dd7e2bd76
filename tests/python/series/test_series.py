"""m3c2 series (python/m3c2kit/series, docs/series.md): every epoch equals m3c2 compare bit for
bit, a killed run resumed by `add` gives the uninterrupted store, the store refuses other
parameters, Dask gives the same store, xarray.open_zarr reads the contract, 4D-OBC finds the
planted objects of the seeded synthetic series (validation/series_synthetic.py, reduced), the
engine's change points / DTW / median against independent oracles, and the py4dgeo import."""
from __future__ import annotations

import csv
import os
import signal
import subprocess
import sys
import time
import zipfile
import io
from pathlib import Path

import numpy as np
import pytest

xr = pytest.importorskip("xarray")
pytest.importorskip("zarr")

from m3c2kit import _core  # noqa: E402
from m3c2kit.cli.main import main  # noqa: E402
from m3c2kit.series import engine  # noqa: E402
from m3c2kit.series import store as st  # noqa: E402
from posix_paths import needs  # noqa: E402

REPO = Path(__file__).resolve().parents[3]
sys.path.insert(0, str(REPO / "validation"))
import series_synthetic as ss  # noqa: E402

PARAMS = ["--core-spacing", "0.5", "--normal-scale", "1", "--projection-scale", "1", "--max-depth", "1"]
SMALL = ss.Scenario(extent=12.0, density=16.0, epochs=7, offset_epoch=3,
                    landslide=ss.Landslide(4.0, 8.0, 2.5, 2.0, 0.08, 0.003, 2), blobs=(ss.Blob(8.0, 3.0, 2.0, 0.3, 1, 5),))
FIELDS = ("distance", "lod", "significant", "n1", "n2", "sigma1", "sigma2", "status")


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    folder = tmp_path_factory.mktemp("small")
    paths = ss.write(SMALL, folder)
    return folder, paths


def series_store(folder, paths, name, *extra):
    out = folder / name
    assert main(["series", str(paths[0]), *map(str, paths[1:]), "-o", str(out), *PARAMS, "--quiet", *extra]) == 0
    return out


def same(a, b) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    if a.dtype == np.float64:
        return a.shape == b.shape and np.array_equal(a.view(np.uint64), b.astype(np.float64).view(np.uint64))
    return a.shape == b.shape and np.array_equal(a, b, equal_nan=a.dtype.kind == "f")


def assert_same_store(x: Path, y: Path):
    a, b = xr.open_zarr(x), xr.open_zarr(y)
    assert set(a.variables) == set(b.variables)
    for name in a.variables:
        assert a[name].dims == b[name].dims, name
        va, vb = a[name].values, b[name].values
        if va.dtype.kind == "f":
            assert same(va, vb), name
        elif va.dtype.kind == "M":
            assert np.array_equal(np.isnat(va), np.isnat(vb)) and np.array_equal(va[~np.isnat(va)], vb[~np.isnat(vb)])
        else:
            assert np.array_equal(va, vb), name


@pytest.mark.slow
def test_each_epoch_equals_compare_bit_for_bit(small, tmp_path):
    folder, paths = small
    store = series_store(tmp_path, paths, "st.zarr")
    ds = xr.open_zarr(store)
    assert ds.sizes["epoch"] == len(paths) - 1 and ds["distance"].dims == ("core", "epoch")
    for k, epoch in enumerate(paths[1:]):
        out = tmp_path / f"c{k}.csv"
        assert main(["compare", str(paths[0]), str(epoch), "-o", str(out), *PARAMS, "--quiet", "--float64"]) == 0
        rows = list(csv.DictReader(open(out)))
        for name in FIELDS + ("x", "y", "z", "nx", "ny", "nz", "normal_scale", "roughness"):
            expected = np.array([float(r[name]) if r[name] not in ("", "nan") else np.nan for r in rows])
            got = ds[name].values[:, k] if name in FIELDS else ds[name].values
            assert same(got.astype(np.float64), expected), (k, name)


@pytest.mark.slow
def test_store_contract(small, tmp_path):
    folder, paths = small
    core = tmp_path / "core.npy"
    pts = ss.epoch_cloud(SMALL, 0)[::37][::-1].copy()  # an order of our own: kept
    np.save(core, pts)
    args = [a for a in PARAMS if a not in ("--core-spacing", "0.5")]
    out = tmp_path / "c.zarr"
    assert main(["series", str(paths[0]), str(folder / "epochs.txt"), "-o", str(out), "--core", str(core), *args,
                 "--quiet", "--epoch-chunk", "2", "--core-chunk", "50"]) == 0
    ds = xr.open_zarr(out)
    assert same(np.column_stack([ds.x, ds.y, ds.z]), pts)
    assert ds["time"].dims == ("epoch",) and ds["time"].dtype.kind == "M"
    assert ds["time"].values[1] - ds["time"].values[0] == np.timedelta64(1, "h")  # from the list file
    assert list(ds["time_source"].values) == ["list"] * len(paths)
    assert ds["distance"].encoding["chunks"] == (50, 2)
    assert "max_depth" in ds.attrs["parameters"] and ds.attrs["Conventions"] == "CF-1.8"
    window = ds["distance"].isel(core=slice(0, 50), epoch=slice(2, 4))
    assert window.data.npartitions == 1  # a window of time and region reads one chunk


@pytest.mark.slow
@needs("kernel_locks", why="a killed writer's lock is never dropped by the system: its lock file (a store's) or private folder stays")
def test_killed_run_resumed_by_add_equals_uninterrupted(small, tmp_path):
    folder, paths = small
    whole = series_store(tmp_path, paths, "whole.zarr", "--epoch-chunk", "2")
    killed = tmp_path / "killed.zarr"
    cmd = [sys.executable, "-m", "m3c2kit", "series", *map(str, paths), "-o", str(killed), *PARAMS, "--quiet",
           "--epoch-chunk", "2"]
    child = subprocess.Popen(cmd)
    deadline = time.time() + 300
    while time.time() < deadline and child.poll() is None:
        try:
            if st.committed_epochs(killed) >= 2:
                break
        except Exception:  # noqa: BLE001 - not created yet
            pass
        time.sleep(0.05)
    child.send_signal(signal.SIGKILL)
    child.wait()
    n = st.committed_epochs(killed)
    assert 2 <= n < len(paths), "the kill came after the run ended: the test says nothing"
    assert main(["series", "add", str(killed), *map(str, paths[1:]), "--quiet"]) == 0
    assert_same_store(whole, killed)
    assert main(["series", "add", str(killed), *map(str, paths[1:]), "--quiet"]) == 0  # nothing twice
    assert xr.open_zarr(killed).sizes["epoch"] == len(paths) - 1


def test_add_refuses_other_parameters_and_a_changed_reference(small, tmp_path, capsys):
    folder, paths = small
    store = series_store(tmp_path, paths[:3], "p.zarr")
    assert main(["series", "add", str(store), str(paths[3]), "--max-depth", "2"]) == 2
    assert "max_depth" in capsys.readouterr().err
    assert main(["series", "add", str(store), str(paths[3]), "--max-depth", "1", "--quiet"]) == 0
    assert main(["series", str(paths[0]), str(paths[1]), "-o", str(store), *PARAMS]) == 2  # exists: use add


@pytest.mark.slow
def test_dask_gives_the_same_store(small, tmp_path):
    distributed = pytest.importorskip("distributed")
    folder, paths = small
    serial = series_store(tmp_path, paths, "serial.zarr")
    with distributed.LocalCluster(n_workers=2, processes=True, threads_per_worker=1, dashboard_address=None,
                                  silence_logs=50) as c:
        dask = series_store(tmp_path, paths, "dask.zarr", "--dask-scheduler", c.scheduler_address, "--threads", "1")
    assert_same_store(serial, dask)


def test_missing_extra_names_it(monkeypatch):
    import builtins
    real = builtins.__import__

    def fake(name, *a, **k):
        if name in ("xarray", "zarr"):
            raise ImportError(name=name)
        return real(name, *a, **k)
    monkeypatch.setattr(builtins, "__import__", fake)
    with pytest.raises(Exception, match=r"m3c2kit\[series\]"):
        st.require_extra()


# ----------------------------------------------------------------------------------------------
# Analysis: oracles


def brute_dtw(x, y):
    n = len(x)
    d = np.full((n + 1, n + 1), np.inf)
    d[0, 0] = 0
    for i in range(1, n + 1):
        for j in range(1, n + 1):
            d[i, j] = abs(x[i - 1] - y[j - 1]) + min(d[i - 1, j], d[i, j - 1], d[i - 1, j - 1])
    return d[n, n]


def test_normalised_dtw_against_brute_force():
    rng = np.random.default_rng(5)
    for _ in range(30):
        n = int(rng.integers(2, 25))
        a, b = rng.normal(size=n), rng.normal(size=n)
        got = _core.normalised_dtw(a, b, a[0], b[0], a[0])
        expected = min(1.0, brute_dtw(a - a[0], b - b[0]) / np.abs(a - a[0]).sum())
        assert got == pytest.approx(expected, rel=1e-12)
    assert _core.normalised_dtw(np.ones(4), np.ones(4), 0, 0, 0) == 0.0
    assert np.isnan(_core.normalised_dtw(np.full(3, np.nan), np.ones(3)))


def test_change_points_find_steps():
    noise = 0.001 * np.random.default_rng(1).normal(size=100)
    ts = np.r_[np.zeros(30), np.ones(40), np.zeros(30)] + noise
    assert list(_core.change_points(ts, 24, 12, 1, 1.0)) == [30, 70]
    # A pulse no longer than the rest of the series on either side of it: no single break lowers
    # the L1 cost, so the search stops at its first candidate (as py4dgeo's; docs/series.md).
    ts = np.r_[np.zeros(40), np.ones(30), np.zeros(30)] + noise
    assert len(_core.change_points(ts, 24, 12, 1, 1.0)) == 0
    assert len(_core.change_points(np.zeros(60) + 0.001 * np.arange(60) % 2, 24, 12, 1, 1.0)) == 0
    with pytest.raises(Exception, match="shorter"):
        _core.change_points(np.zeros(10), 24, 12, 1, 1.0)


def test_temporal_median_against_numpy():
    rng = np.random.default_rng(2)
    v = rng.normal(size=(7, 30))
    v[rng.random(v.shape) < 0.2] = np.nan
    got = engine.temporal_median(v, 5)
    for t in range(30):
        window = v[:, max(0, t - 2):t + 3]
        with np.errstate(all="ignore"), pytest.warns(None) if False else _nowarn():
            expected = np.nanmedian(window, axis=1)
        assert same(got[:, t], expected)


class _nowarn:
    def __enter__(self):
        import warnings
        self._c = warnings.catch_warnings()
        self._c.__enter__()
        warnings.simplefilter("ignore")

    def __exit__(self, *a):
        self._c.__exit__(*a)


# ----------------------------------------------------------------------------------------------
# 4D objects-by-change on the reduced synthetic series


@pytest.fixture(scope="module")
def synthetic(tmp_path_factory):
    folder = tmp_path_factory.mktemp("synthetic")
    s = ss.Scenario.reduced()
    paths = ss.write(s, folder)
    store = folder / "st.zarr"
    assert main(["series", str(paths[0]), str(folder / "epochs.txt"), "-o", str(store), *PARAMS, "--quiet"]) == 0
    return s, store


@pytest.mark.slow
def test_objects_match_the_planted_ones(synthetic, tmp_path):
    s, store = synthetic
    assert main(["series", "smooth", str(store), "--window", "5"]) == 0
    table = tmp_path / "objects.csv"
    assert main(["series", "objects", str(store), "-o", str(table), "--quiet"]) == 0
    ds = xr.open_zarr(store)
    core = np.column_stack([ds.x, ds.y, ds.z])
    labels = ds["object"].values
    rows = list(csv.DictReader(open(table)))
    assert len(rows) == 1 + len(s.blobs)  # no false object (the registration offset is smoothed away)
    for name, truth in ss.planted(s, core, ds.sizes["epoch"]):
        best = max(ss.iou(truth, labels == k) for k in range(len(rows)))
        assert best >= 0.8, name
    report = tmp_path / "r.html"
    assert main(["series", "report", str(store), "-o", str(report), "--objects", str(table), "--core", "3"]) == 0
    assert report.read_text().count("<img") == 2 + len(rows)


def test_objects_beyond_the_memory_limit_run_on_a_mapped_file_with_the_same_result(synthetic, tmp_path, monkeypatch,
                                                                                   capsys):
    from m3c2kit.series import analysis
    s, store = synthetic
    values, name = analysis.distances_for_analysis(store)
    mapped, same_name = analysis.distances_for_analysis(store, in_memory_limit=values.nbytes - 1)
    assert isinstance(mapped, np.memmap) and not isinstance(values, np.memmap) and name == same_name
    assert same(np.asarray(mapped), values)
    # The engine reads the mapped file in place (no copy of the whole series in memory).
    assert np.shares_memory(np.ascontiguousarray(mapped, dtype=np.float64), mapped)
    tables = []
    for limit in (None, 1):
        monkeypatch.setattr(analysis, "IN_MEMORY_LIMIT", analysis.IN_MEMORY_LIMIT if limit is None else limit)
        table = tmp_path / f"objects_{limit}.csv"
        assert main(["series", "objects", str(store), "-o", str(table), "--quiet"]) == 0
        tables.append((table.read_text(), table.with_name(table.stem + "_members.csv").read_text(),
                       xr.open_zarr(store)["object"].values))
    assert tables[0][0] == tables[1][0] and tables[0][1] == tables[1][1]
    assert np.array_equal(tables[0][2], tables[1][2], equal_nan=True)  # NaN: no object
    # changepoints reads one core point's series: the same as that row of the whole variable.
    capsys.readouterr()
    assert main(["series", "changepoints", str(store), "--core", "3"]) == 0
    printed = capsys.readouterr().out
    ts = values[3]
    good = ~np.isnan(ts)
    ts = np.interp(np.arange(len(ts)), np.flatnonzero(good), ts[good])
    cps = engine.change_points(ts, 24, 12, 1, 1.0)
    assert f"change points at epochs {', '.join(map(str, cps)) or 'none'}" in printed


def test_a_failed_objects_table_leaves_neither_table(synthetic, tmp_path, monkeypatch):
    from m3c2kit.series import analysis
    s, store = synthetic
    table = tmp_path / "objects.csv"
    calls = []

    def fail_on_the_second(out, k):
        calls.append(k)
        if len(calls) == 2:
            raise RuntimeError("stopped")
        return original(out, k)

    original = analysis.object_members
    monkeypatch.setattr(analysis, "object_members", fail_on_the_second)
    with pytest.raises(RuntimeError, match="stopped"):
        main(["series", "objects", str(store), "-o", str(table), "--quiet"])
    assert len(calls) == 2  # the first object's rows had been written
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_objects_without_the_neighbour_table_are_the_same(synthetic):
    """4D-OBC keeps every core point's neighbours in a table only while it fits in
    neighbour_table_bytes (it grows with the radius squared); beyond, each neighbourhood is
    searched when needed. No table, and a table abandoned part-built, give the same objects."""
    from m3c2kit.series import analysis
    s, store = synthetic
    values, _ = analysis.distances_for_analysis(store)
    group = xr.open_zarr(store)
    core = np.column_stack([group.x.values, group.y.values, group.z.values])

    def run(table_bytes):
        p = engine.objects_params()
        if table_bytes is not None:
            p.neighbour_table_bytes = table_bytes
        return engine.objects_by_change(values, core, p, threads=2)

    def key(out):
        return {k: np.asarray(v).tobytes() for k, v in out.items()}

    full = run(None)
    assert len(full["object_seed"]) >= 2  # objects to compare
    # 4 bytes a pair: 1000 pairs is a few core points' neighbourhoods, abandoned part-built.
    for table_bytes in (0, 4000):
        assert key(run(table_bytes)) == key(full)


def test_add_keeps_derived_variables_the_series_length(small, tmp_path):
    folder, paths = small
    store = series_store(tmp_path, paths[:4], "d.zarr")
    assert main(["series", "smooth", str(store), "--window", "3"]) == 0
    assert main(["series", "add", str(store), str(paths[4]), "--quiet"]) == 0
    ds = xr.open_zarr(store)
    assert ds["smoothed_distance"].shape == ds["distance"].shape
    assert np.isnan(ds["smoothed_distance"].values[:, -1]).all()  # not smoothed yet: NaN, never stale


# ----------------------------------------------------------------------------------------------
# py4dgeo archive import

ARCHIVE = REPO / "tests" / "data" / "py4dgeo_series" / "analysis.zip"


def test_import_py4dgeo_archive(tmp_path):
    out = tmp_path / "imp.zarr"
    assert main(["series", "import", str(ARCHIVE), "-o", str(out)]) == 0
    ds = xr.open_zarr(out)
    with zipfile.ZipFile(ARCHIVE) as zf:
        d = np.load(io.BytesIO(zf.read("distances.npz")))["arr_0"]
        u = np.load(io.BytesIO(zf.read("uncertainties.npz")))["arr_0"]
    assert same(ds["distance"].values, d)
    assert same(ds["lod"].values, u["lodetection"])
    assert np.array_equal(ds["n2"].values, u["num_samples2"].astype(float))
    assert str(ds["time"].values[0]).startswith("2024-01-01T13:00")
    assert main(["series", "add", str(out), str(ARCHIVE)]) == 2  # parameters unknown: refused
