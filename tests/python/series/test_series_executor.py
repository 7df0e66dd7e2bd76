"""`m3c2 series` on the one executor's rules (issue 32): every epoch of a store equals `m3c2 compare`
of the reference with that epoch, bit for bit, for LAS inputs, for an E57 reference whose scan
pose gives the default orientation (section 3.1.2: towards the scanner), for an explicit
--orient, a FILE of points, the core points' barycentre and --normal-source core; a bad option
gives compare's message, in create and in add; the store records the orientation it used."""
from __future__ import annotations

import csv
import json
import warnings
from pathlib import Path

import numpy as np
import pytest

xr = pytest.importorskip("xarray")
pytest.importorskip("zarr")

from m3c2kit.cli.main import main  # noqa: E402
from m3c2kit.io import write_cloud_table  # noqa: E402

PARAMS = ["--core-spacing", "0.5", "--normal-scale", "1", "--projection-scale", "1", "--max-depth", "1"]
COLUMNS = ("distance", "lod", "significant", "n1", "n2", "sigma1", "sigma2", "status")
PER_CORE = ("x", "y", "z", "nx", "ny", "nz", "normal_scale", "roughness")
#: Below the surface: the default orientation (towards it) points the normals down, +z up.
SCANNER = np.array([5.0, 5.0, -6.0])


def _surface(rng, n: int, shift: float) -> np.ndarray:
    xy = rng.uniform(0.0, 10.0, (n, 2))
    z = 0.3 * np.sin(xy[:, 0]) + 0.2 * np.cos(1.3 * xy[:, 1]) + rng.normal(0.0, 0.01, n) + shift * (xy[:, 0] > 5)
    return np.column_stack([xy, z])


def _write(path: Path, xyz: np.ndarray, fields=None) -> Path:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # LAS quantisation notes
        write_cloud_table(path, xyz, fields or {})
    return path


@pytest.fixture(scope="module")
def clouds(tmp_path_factory):
    """A reference and two epochs (a step of 5 and 10 cm on half the area) as LAS, the reference
    also as an E57 scan posed at SCANNER, core points with upward normals, an orientation FILE."""
    folder = tmp_path_factory.mktemp("executor")
    rng = np.random.default_rng(32)
    ref = _surface(rng, 8000, 0.0)
    files = {"ref": _write(folder / "ref.las", ref),
             "epochs": [_write(folder / f"e{k}.las", _surface(rng, 8000, 0.05 * (k + 1))) for k in range(2)]}
    core = ref[::40]
    files["core"] = _write(folder / "core.ply", core, {"nx": np.zeros(len(core)), "ny": np.zeros(len(core)),
                                                       "nz": np.ones(len(core))})
    files["core_plain"] = _write(folder / "core_plain.ply", core)
    files["orient_file"] = _write(folder / "scanner.ply", SCANNER.reshape(1, 3))
    try:
        import pye57
    except ImportError:
        files["e57"] = None
    else:
        files["e57"] = folder / "ref.e57"
        local = ref - SCANNER
        with pye57.E57(str(files["e57"]), mode="w") as out:
            out.write_scan_raw({"cartesianX": local[:, 0], "cartesianY": local[:, 1], "cartesianZ": local[:, 2]},
                               name="scan", rotation=np.array([1.0, 0.0, 0.0, 0.0]), translation=SCANNER)
    return files


def _same(a, b) -> bool:
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    return a.shape == b.shape and np.array_equal(np.nan_to_num(a, nan=7e300).view(np.uint64),
                                                 np.nan_to_num(b, nan=7e300).view(np.uint64))


def _compare_table(tmp_path, reference, epoch, options) -> dict:
    out = tmp_path / f"compare-{Path(reference).suffix[1:]}-{Path(epoch).stem}.csv"
    assert main(["compare", str(reference), str(epoch), "-o", str(out), *options, "--quiet", "--float64"]) == 0
    rows = list(csv.DictReader(open(out)))
    return {name: np.array([float(r[name]) if r[name] not in ("", "nan") else np.nan for r in rows])
            for name in rows[0]}


def _series(tmp_path, reference, epochs, options, name="s.zarr", *extra) -> Path:
    store = tmp_path / name
    assert main(["series", str(reference), *map(str, epochs), "-o", str(store), *options, "--quiet", *extra]) == 0
    return store


def _assert_equals_compare(tmp_path, store: Path, reference, epochs, options) -> None:
    ds = xr.open_zarr(store)
    assert ds.sizes["epoch"] == len(epochs)
    for k, epoch in enumerate(epochs):
        table = _compare_table(tmp_path, reference, epoch, options)
        for name in COLUMNS + PER_CORE:
            got = ds[name].values[:, k] if name in COLUMNS else ds[name].values
            assert _same(got, table[name]), (k, name)


def _recorded(store: Path) -> dict:
    return json.loads(xr.open_zarr(store).attrs["parameters"])


def test_las_inputs_equal_compare(clouds, tmp_path):
    store = _series(tmp_path, clouds["ref"], clouds["epochs"], PARAMS)
    _assert_equals_compare(tmp_path, store, clouds["ref"], clouds["epochs"], PARAMS)
    assert _recorded(store)["orient"] == "+z"  # no scan position: +z, recorded as stores always have


def test_add_equals_compare_and_create(clouds, tmp_path):
    whole = _series(tmp_path, clouds["ref"], clouds["epochs"], PARAMS, "whole.zarr")
    grown = _series(tmp_path, clouds["ref"], clouds["epochs"][:1], PARAMS, "grown.zarr")
    assert main(["series", "add", str(grown), str(clouds["epochs"][1]), "--quiet"]) == 0
    a, b = xr.open_zarr(whole), xr.open_zarr(grown)
    for name in COLUMNS:
        assert _same(a[name].values, b[name].values), name


def _e57(clouds):
    if clouds["e57"] is None:
        pytest.skip("pye57 is not installed")
    return clouds["e57"]


def test_e57_scan_pose_is_the_default_orientation(clouds, tmp_path):
    reference = _e57(clouds)
    store = _series(tmp_path, reference, clouds["epochs"], PARAMS)
    _assert_equals_compare(tmp_path, store, reference, clouds["epochs"], PARAMS)
    assert _recorded(store)["orient"] == [SCANNER.tolist()]
    ds = xr.open_zarr(store)
    assert (ds["nz"].values < 0).all()  # towards the scanner below the surface, not +z
    # add rebuilds the same orientation from the store's record, and --orient sensor is the same
    assert main(["series", "add", str(store), str(clouds["ref"]), "--orient", "sensor", "--quiet"]) == 0
    assert xr.open_zarr(store).sizes["epoch"] == 3


def test_e57_with_a_core_file_without_pose_uses_the_references(clouds, tmp_path):
    reference = _e57(clouds)
    options = [a for a in PARAMS if a not in ("--core-spacing", "0.5")] + ["--core", str(clouds["core_plain"])]
    store = _series(tmp_path, reference, clouds["epochs"][:1], options)
    _assert_equals_compare(tmp_path, store, reference, clouds["epochs"][:1], options)
    assert _recorded(store)["orient"] == [SCANNER.tolist()]


@pytest.mark.slow
@pytest.mark.parametrize("orient", ["-z", "sensor", "barycentre", "away:1,2,30"])
def test_explicit_orientations_equal_compare(clouds, tmp_path, orient):
    reference = _e57(clouds) if orient == "sensor" else clouds["ref"]
    options = PARAMS + [f"--orient={orient}"]
    store = _series(tmp_path, reference, clouds["epochs"][:1], options)
    _assert_equals_compare(tmp_path, store, reference, clouds["epochs"][:1], options)
    recorded = _recorded(store)["orient"]
    assert recorded == ([SCANNER.tolist()] if orient == "sensor" else orient)


def test_an_orientation_file_is_recorded_as_its_points(clouds, tmp_path):
    options = PARAMS + ["--orient", f"away:{clouds['orient_file']}"]
    store = _series(tmp_path, clouds["ref"], clouds["epochs"][:1], options)
    _assert_equals_compare(tmp_path, store, clouds["ref"], clouds["epochs"][:1], options)
    assert _recorded(store)["orient"] == {"away": [SCANNER.tolist()]}  # the store needs no file to grow
    assert main(["series", "add", str(store), str(clouds["epochs"][1]), "--orient", f"away:{clouds['orient_file']}",
                 "--quiet"]) == 0


def test_add_refuses_another_orientation(clouds, tmp_path, capsys):
    store = _series(tmp_path, clouds["ref"], clouds["epochs"][:1], PARAMS)
    assert main(["series", "add", str(store), str(clouds["epochs"][1]), "--orient", "-z"]) == 2
    assert "was computed with orient = '+z', not '-z'" in capsys.readouterr().err


def test_core_normals_equal_compare(clouds, tmp_path):
    base = ["--projection-scale", "1", "--max-depth", "1", "--normal-source", "core"]
    for options in (base + ["--core", str(clouds["core"])],
                    base + ["--core", str(clouds["core_plain"]), "--core-normals", str(clouds["core"])]):
        store = _series(tmp_path, clouds["ref"], clouds["epochs"][:1], options, f"c{len(options)}.zarr")
        _assert_equals_compare(tmp_path, store, clouds["ref"], clouds["epochs"][:1], options)
        assert "orient" not in _recorded(store)  # given normals are used as they are


def _error(capsys, argv) -> str:
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2, err
    lines = [line for line in err.splitlines() if "error:" in line]
    assert lines, err
    return lines[-1].split("error:", 1)[1].strip()


@pytest.mark.slow
@pytest.mark.parametrize("bad", [["--max-depth", "-1"], ["--normal-scale", "0"], ["--projection-scale", "nan"],
                                 ["--first-pass-depth", "2"], ["--normal-source", "vertical"]])
def test_a_bad_option_gives_compares_message(clouds, tmp_path, capsys, bad):
    def replaced(options):
        out = list(options)
        if bad[0] in out:
            i = out.index(bad[0])
            del out[i:i + 2]
        return out + bad

    ref, epoch = str(clouds["ref"]), str(clouds["epochs"][0])
    expected = _error(capsys, ["compare", ref, epoch, "-o", str(tmp_path / "c.csv"), *replaced(PARAMS)])
    assert _error(capsys, ["series", ref, epoch, "-o", str(tmp_path / "bad.zarr"), *replaced(PARAMS)]) == expected
    assert not (tmp_path / "bad.zarr").exists()
    if bad[0] in ("--max-depth", "--normal-scale", "--projection-scale"):  # add checks a value as compare does
        store = _series(tmp_path, ref, [epoch], PARAMS)
        assert _error(capsys, ["series", "add", str(store), str(clouds["epochs"][1]), *bad]) == expected


def test_core_normals_errors_are_compares(clouds, tmp_path, capsys):
    ref, epoch = str(clouds["ref"]), str(clouds["epochs"][0])
    for options in (["--normal-source", "core", "--core", str(clouds["core_plain"])],
                    PARAMS + ["--core-normals", str(clouds["core"])]):
        options = [*options, "--projection-scale", "1", "--max-depth", "1"] if "--max-depth" not in options else options
        expected = _error(capsys, ["compare", ref, epoch, "-o", str(tmp_path / "c.csv"), *options])
        assert _error(capsys, ["series", ref, epoch, "-o", str(tmp_path / "b.zarr"), *options]) == expected


@pytest.mark.slow
def test_dask_uses_the_recorded_orientation(clouds, tmp_path):
    distributed = pytest.importorskip("distributed")
    reference = _e57(clouds)
    serial = _series(tmp_path, reference, clouds["epochs"], PARAMS + ["--orient", "barycentre"], "serial.zarr")
    with distributed.LocalCluster(n_workers=1, processes=True, threads_per_worker=1, dashboard_address=None,
                                  silence_logs=50) as cluster:
        on_dask = _series(tmp_path, reference, clouds["epochs"], PARAMS + ["--orient", "barycentre"], "dask.zarr",
                          "--dask-scheduler", cluster.scheduler_address, "--threads", "1")
    a, b = xr.open_zarr(serial), xr.open_zarr(on_dask)
    for name in COLUMNS + PER_CORE:
        assert _same(a[name].values, b[name].values), name
