"""`m3c2 series kalman` on a store (series/kalman.py; docs/series.md, "Kalman filter"): the
variables equal the engine's filter on the store's distances with variances (LOD / z)^2 computed
here, the store stays sound, a rerun after `add` resumes and equals a from-scratch run, a kill
at every write phase leaves the previous variables or all of them marked (never a mix), and
4D-OBC can segment the filtered series (--use kalman)."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

xr = pytest.importorskip("xarray")
pytest.importorskip("zarr")

from m3c2kit import engine  # noqa: E402
from m3c2kit.base import fault_hook  # noqa: E402
from m3c2kit.cli.main import main  # noqa: E402
from m3c2kit.series import kalman as km  # noqa: E402
from m3c2kit.series import store as st  # noqa: E402

REPO = Path(__file__).resolve().parents[3]
sys.path.insert(0, str(REPO / "validation"))
sys.path.insert(0, str(Path(__file__).resolve().parent))
import series_synthetic as ss  # noqa: E402
from test_kalman import engine_smoother  # noqa: E402
from test_series_trust import copy, run  # noqa: E402  (the store tests' helpers)

Z95 = 1.959963984540054
PARAMS = ["--core-spacing", "0.5", "--normal-scale", "1", "--projection-scale", "1", "--max-depth", "1",
          "--lod", "z"]
SCENARIO = ss.Scenario(extent=10.0, density=12.0, epochs=13, offset_epoch=20,
                       blobs=(ss.Blob(5.0, 5.0, 2.5, 0.4, 3, 9),),
                       landslide=ss.Landslide(2.0, 2.0, 1.0, 1.0, 0.0, 0.0, 2))


def list_file(folder: Path, name: str, lines: list[str]) -> Path:
    path = folder / name
    path.write_text("".join(lines))
    return path


@pytest.fixture(scope="module")
def epochs(tmp_path_factory):
    folder = tmp_path_factory.mktemp("epochs")
    paths = ss.write(SCENARIO, folder)
    # Irregular times (hours): a two-day gap after epoch 5, half an hour between epochs 7 and 8.
    hours = [0, 1, 2, 3, 4, 5, 53, 54, 54.5, 56, 57, 63, 64]
    lines = [f"{p.name}, {np.datetime64('2024-01-01T00:00') + np.timedelta64(int(h * 60), 'm')}\n"
             for p, h in zip(paths, hours)]
    first = list_file(folder, "first.txt", lines[1:8])
    second = list_file(folder, "second.txt", lines[8:])
    return paths, first, second


@pytest.fixture(scope="module")
def base(epochs, tmp_path_factory):
    """A store of epochs 1-7 (chunks of 2 epochs and 150 core points: partial last chunks)."""
    paths, first, _ = epochs
    out = tmp_path_factory.mktemp("base") / "base.zarr"
    assert main(["series", str(paths[0]), str(first), "-o", str(out), *PARAMS, "--quiet",
                 "--epoch-chunk", "2", "--core-chunk", "150"]) == 0
    return out


def test_the_variables_are_the_engines_filter_of_the_stores_series(base, tmp_path, capsys):
    store = copy(base, tmp_path)
    code, out, err = run(capsys, "series", "kalman", store, "--process-noise", "0.5", "--observation", "independent")
    assert code == 0, err
    assert "from the first epoch" in out and "q = 0.5 (given)" in out
    ds = xr.open_zarr(store).load()
    days = (ds["time"].values - ds["time"].values[0]) / np.timedelta64(1, "D")
    var = (ds["lod"].values / Z95) ** 2  # --lod z: the LOD is z (sqrt(...) + reg)
    expect = engine_smoother(ds["distance"].values, var, days, "velocity", 0.5, "continuous")
    np.testing.assert_allclose(ds["kalman_distance"].values, expect["mean"][:, :, 0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(ds["kalman_rate_sigma"].values, expect["sd"][:, :, 1], rtol=0, atol=1e-12)
    d, s = expect["mean"][:, :, 0], expect["sd"][:, :, 0]
    flag = np.where(np.isnan(d), -1, np.abs(d) > Z95 * s)
    # xarray reads the fill value -1 (no estimate) as NaN, as for `significant`
    assert np.array_equal(np.nan_to_num(ds["kalman_significant"].values, nan=-1), flag)
    assert 0 < (flag == 1).sum() < (flag >= 0).sum()
    assert np.isfinite(ds["kalman_distance"].values).mean() > 0.9
    assert "kalman_acceleration" not in ds
    assert run(capsys, "series", "check", store)[0] == 0
    # Another confidence: nothing to filter (resumed at the end), the flags at z_0.8.
    code, out, err = run(capsys, "series", "kalman", store, "--process-noise", "0.5", "--confidence", "0.8",
                         "--observation", "independent")
    assert code == 0 and "resumed after epoch 6" in out and "significant at 0.8" in out, (out, err)
    again = xr.open_zarr(store).load()
    assert again["kalman_distance"].values.tobytes() == ds["kalman_distance"].values.tobytes()
    z80 = 1.2815515655446004
    assert np.array_equal(np.nan_to_num(again["kalman_significant"].values, nan=-1),
                          np.where(np.isnan(d), -1, np.abs(d) > z80 * s))
    assert again["kalman_significant"].attrs["confidence"] == 0.8


def test_the_acceleration_model_replaces_the_velocity_variables_and_back(base, tmp_path, capsys):
    store = copy(base, tmp_path)
    assert run(capsys, "series", "kalman", store, "--model", "acceleration", "--process-noise", "0.1")[0] == 0
    ds = xr.open_zarr(store)
    assert {"kalman_acceleration", "kalman_acceleration_sigma"} <= set(ds)
    assert ds["kalman_moments"].shape[2] == 14  # [d, d', d'', b]: 4 means, 10 covariances
    assert ds["kalman_moments"].attrs["observation"] == "shared"
    assert ds["kalman_distance"].attrs["step_false_alarm"] == 1e-4  # the engine's, which the estimates depend on
    assert run(capsys, "series", "kalman", store, "--process-noise", "0.1", "--observation", "independent")[0] == 0
    ds = xr.open_zarr(store)
    assert "step_false_alarm" not in ds["kalman_distance"].attrs  # the independent model has no step test
    assert "kalman_acceleration" not in ds and ds["kalman_moments"].shape[2] == 5
    assert run(capsys, "series", "check", store)[0] == 0


def test_auto_and_a_rerun_after_add_resumes_equal_to_from_scratch(base, epochs, tmp_path, capsys):
    _, _, second = epochs
    store = copy(base, tmp_path)
    code, out, err = run(capsys, "series", "kalman", store, "--observation", "independent")
    assert code == 0 and "maximum likelihood" in out, err
    q = float(xr.open_zarr(store)["kalman_moments"].attrs["process_noise"])
    assert run(capsys, "series", "add", store, second, "--quiet")[0] == 0
    ds = xr.open_zarr(store)
    assert ds["kalman_distance"].shape[1] == 12 and np.isnan(ds["kalman_distance"].values[:, 7:]).all()
    assert run(capsys, "series", "check", store)[0] == 0  # kept the length of the series by add
    scratch = copy(store, tmp_path, "scratch.zarr")
    # a shared run in between is not resumed from (another model), nor does it resume
    code, out, err = run(capsys, "series", "kalman", store, "--observation", "independent")
    assert code == 0 and "resumed after epoch 6" in out, (out, err)
    assert run(capsys, "series", "kalman", scratch, "--from-scratch", "--process-noise", repr(q),
               "--observation", "independent")[0] == 0
    a, b = xr.open_zarr(store).load(), xr.open_zarr(scratch).load()
    for name in km.variables("velocity"):
        np.testing.assert_allclose(a[name].values, b[name].values, rtol=0, atol=1e-12, err_msg=name)
        assert a[name].values.tobytes() == b[name].values.tobytes(), name  # in fact the same bits
    assert float(a["kalman_moments"].attrs["process_noise"]) == q


def test_objects_segment_the_kalman_series(base, tmp_path, capsys):
    store = copy(base, tmp_path)
    objects = ["--window-width", "4", "--window-min-size", "2", "--min-period", "2", "--min-segments", "3",
               "--max-cv", "5", "--thresholds", "0.5,0.9", "--quiet"]
    code, _, err = run(capsys, "series", "objects", store, "-o", tmp_path / "o.csv", "--use", "kalman", *objects)
    assert code == 2 and "m3c2 series kalman" in err  # a usage error, as --use smoothed without smooth
    assert run(capsys, "series", "kalman", store, "--process-noise", "1")[0] == 0
    assert run(capsys, "series", "objects", store, "-o", tmp_path / "o.csv", "--use", "kalman", *objects)[0] == 0
    assert xr.open_zarr(store)["object"].attrs["source_variable"] == "kalman_distance"


def test_a_store_without_times_is_refused(epochs, tmp_path, capsys):
    paths, _, _ = epochs
    store = tmp_path / "untimed.zarr"
    assert main(["series", str(paths[0]), *map(str, paths[1:3]), "-o", str(store), *PARAMS, "--quiet"]) == 0
    code, _, err = run(capsys, "series", "kalman", store)
    assert code == 2 and "has no time" in err
    code, _, err = run(capsys, "series", "kalman", store, "--process-noise", "-1")
    assert code == 2 and "--process-noise" in err


@pytest.mark.slow
def test_a_kill_at_every_write_phase_keeps_the_previous_variables_or_marks_them_all(base, tmp_path, capsys,
                                                                                     monkeypatch):
    store = copy(base, tmp_path)
    assert run(capsys, "series", "kalman", store, "--process-noise", "0.5")[0] == 0
    before = xr.open_zarr(store).load()
    names = km.variables("velocity")
    for phase in ("store-write", "store-commit"):
        monkeypatch.setenv(fault_hook.ENV, f"{phase}:SIGTERM")
        monkeypatch.setattr(fault_hook, "_fired", set())
        code, _, err = run(capsys, "series", "kalman", store, "--process-noise", "2", "--from-scratch")
        monkeypatch.delenv(fault_hook.ENV)
        assert code == 1 and "interrupted by SIGTERM" in err, err
        if phase == "store-write":  # before any chunk: the previous variables whole and in use
            assert "Kalman variables" in err and "unchanged" in err
            after = xr.open_zarr(store).load()
            for name in names:
                assert after[name].equals(before[name]) and after[name].attrs == before[name].attrs
            assert run(capsys, "series", "check", store)[0] == 0
        else:  # inside the publication: every variable marked, refused, the rerun named
            assert "half-written" in err and "--from-scratch" in err
            assert set(names) <= set(st.rewriting(st.open_group(store)))
            code, out, _ = run(capsys, "series", "check", store)
            assert code == 1 and "m3c2 series kalman" in out
            code, _, err = run(capsys, "series", "kalman", store, "--process-noise", "2")
            assert code == 1 and "half-written" in err  # resuming from marked moments is refused
            assert run(capsys, "series", "kalman", store, "--process-noise", "2", "--from-scratch")[0] == 0
            assert run(capsys, "series", "check", store)[0] == 0


def test_an_imported_py4dgeo_store_is_filtered_with_its_lod_as_z(tmp_path, capsys):
    """py4dgeo keeps no parameters; its LOD is 1.96 (...), so the observation variance is (LOD / z)^2."""
    archive = REPO / "tests" / "data" / "py4dgeo_series" / "analysis.zip"
    store = tmp_path / "imp.zarr"
    assert main(["series", "import", str(archive), "-o", str(store)]) == 0
    capsys.readouterr()
    code, out, err = run(capsys, "series", "kalman", store, "--process-noise", "0.01", "--observation", "independent")
    assert code == 0, err
    ds = xr.open_zarr(store).load()
    days = (ds["time"].values - ds["time"].values[0]) / np.timedelta64(1, "D")
    expect = engine_smoother(ds["distance"].values, (ds["lod"].values / Z95) ** 2, days, "velocity", 0.01,
                             "continuous")
    np.testing.assert_allclose(ds["kalman_distance"].values, expect["mean"][:, :, 0], rtol=0, atol=1e-12)
    assert np.isfinite(ds["kalman_distance"].values).any()


def test_the_shared_run_is_the_engines_on_the_stores_spreads_and_always_from_scratch(base, epochs, tmp_path, capsys):
    """The default model: the engine's shared filter on the store's distance, sigma1, n1, sigma2, n2
    (pooled there), anchored at the reference's recorded time; after `add` the rerun filters from
    the first epoch (the pooled scatter changed) and equals a --from-scratch run bit for bit."""
    _, _, second = epochs
    store = copy(base, tmp_path)
    code, out, err = run(capsys, "series", "kalman", store, "--process-noise", "0.5")
    assert code == 0 and "shared observation" in out and "from the first epoch" in out, (out, err)
    ds = xr.open_zarr(store).load()
    assert ds["kalman_distance"].attrs["observation"] == "shared" and ds["kalman_moments"].shape[2] == 9
    days = (ds["time"].values - ds["time"].values[0]) / np.timedelta64(1, "D")
    text = ds.attrs["reference_time"]
    ref_time = (np.datetime64(text) - ds["time"].values[0]) / np.timedelta64(1, "D") if text else None
    counts = lambda a: np.where(np.isfinite(a), a, np.nan).astype(np.float64)  # noqa: E731  (NaN: fill)
    spread = tuple(np.ascontiguousarray(a) for a in (ds["sigma1"].values, counts(ds["n1"].values),
                                                       ds["sigma2"].values, counts(ds["n2"].values)))
    p = engine.kalman_params(order=2, discrete_noise=False, process_noise=0.5, reference=(ref_time, None))
    z = np.ascontiguousarray(ds["distance"].values)
    expect = engine.kalman_smooth(z, None, days, np.full((*z.shape, 9), np.nan), p, spread=spread)
    np.testing.assert_allclose(ds["kalman_distance"].values, expect["mean"][:, :, 0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(ds["kalman_distance_sigma"].values, expect["sd"][:, :, 0], rtol=0, atol=1e-12)
    # every core point with a distance has an estimate at every epoch from the first one
    assert np.isfinite(ds["kalman_distance"].values).sum() >= np.isfinite(z).sum()
    assert run(capsys, "series", "add", store, second, "--quiet")[0] == 0
    scratch = copy(store, tmp_path, "scratch.zarr")
    code, out, err = run(capsys, "series", "kalman", store, "--process-noise", "0.5")
    assert code == 0 and "from the first epoch" in out, (out, err)
    assert run(capsys, "series", "kalman", scratch, "--from-scratch", "--process-noise", "0.5")[0] == 0
    a, b = xr.open_zarr(store).load(), xr.open_zarr(scratch).load()
    for name in km.variables("velocity"):
        assert a[name].values.tobytes() == b[name].values.tobytes(), name
    assert run(capsys, "series", "check", store)[0] == 0


def test_the_reference_file_as_an_epoch_is_the_anchor_not_an_observation(epochs, tmp_path, capsys):
    """Permanent laser scanning: the reference file is also epoch 0 (the same SHA-256). Its
    distance is the reference against itself; the shared run anchors d = 0 there (sigma 0, never
    significant) and estimates every later epoch with a positive sigma."""
    paths, _, _ = epochs
    lines = [f"{p.name}, {np.datetime64('2024-01-01T00:00') + np.timedelta64(h, 'h')}\n"
             for p, h in zip(paths[:4], (0, 1, 2, 4))]
    listing = list_file(paths[0].parent, "with_reference.txt", lines)
    store = tmp_path / "pls.zarr"
    assert main(["series", str(paths[0]), str(listing), "-o", str(store), *PARAMS, "--quiet"]) == 0
    capsys.readouterr()
    assert run(capsys, "series", "kalman", store, "--process-noise", "0.5")[0] == 0
    ds = xr.open_zarr(store).load()
    d, s = ds["kalman_distance"].values, ds["kalman_distance_sigma"].values
    has = np.isfinite(d[:, 0])
    assert has.mean() > 0.9 and (d[has, 0] == 0).all() and (s[has, 0] == 0).all()
    assert (s[has, 1:] > 0).all() and (ds["kalman_significant"].values[has, 0] == 0).all()


def test_a_process_noise_whose_variance_overflows_is_refused(tmp_path, capsys):
    """Hostile round 2: --process-noise 1e290 over epochs 8,000 years apart overflowed q dt^3 and
    published every estimate as NaN with exit 0. Refused, naming q, the span and the power; a q
    just inside the bound still estimates every cell."""
    rng = np.random.default_rng(5)
    xy = np.stack(np.meshgrid(np.arange(12) * 0.25, np.arange(12) * 0.25), -1).reshape(-1, 2)
    for k, dz in enumerate((0.0, 0.0, 0.02)):
        np.savetxt(tmp_path / f"e{k}.xyz", np.column_stack([xy, dz + rng.normal(0, 0.002, len(xy))]))
    (tmp_path / "list.txt").write_text(f"{tmp_path / 'e1.xyz'}, 1900-01-02T00:00:00Z\n"
                                       f"{tmp_path / 'e2.xyz'}, 9999-12-31T00:00:00Z\n")
    store = tmp_path / "s.zarr"
    assert main(["series", str(tmp_path / "e0.xyz"), str(tmp_path / "list.txt"), "-o", str(store), "--normal-scale",
                 "1", "--projection-scale", "1", "--max-depth", "1", "-q"]) == 0
    assert main(["series", "kalman", str(store), "--process-noise", "1e290", "-q"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("m3c2: error: --process-noise 1e+290 over epochs spanning 2.9") and "q dt^3 = inf" in err, err
    assert "kalman_distance" not in st.open_group(store)
    assert main(["series", "kalman", str(store), "--process-noise", "3e280", "-q"]) == 0
    assert np.isfinite(st.open_group(store)["kalman_distance"][:]).all()


def test_auto_process_noise_without_any_distance_says_so(tmp_path, capsys):
    """Hostile round 2: epochs that never meet the core points (no distance anywhere) gave
    "--process-noise: --process-noise auto needs ... distinct times and ... a variance"."""
    xy = np.stack(np.meshgrid(np.arange(8) * 0.25, np.arange(8) * 0.25), -1).reshape(-1, 2)
    np.savetxt(tmp_path / "ref.xyz", np.column_stack([xy, np.zeros(len(xy))]))
    lines = []
    for k in range(3):
        np.savetxt(tmp_path / f"far{k}.xyz", np.column_stack([xy + 100.0, np.zeros(len(xy))]))
        lines.append(f"{tmp_path / f'far{k}.xyz'}, 2024-01-0{k + 1}T00:00:00Z")
    (tmp_path / "list.txt").write_text("\n".join(lines) + "\n")
    store = tmp_path / "s.zarr"
    assert main(["series", str(tmp_path / "ref.xyz"), str(tmp_path / "list.txt"), "-o", str(store), "--normal-scale",
                 "1", "--projection-scale", "1", "--max-depth", "1", "-q"]) == 0
    capsys.readouterr()
    assert main(["series", "kalman", str(store), "-q"]) == 2
    assert capsys.readouterr().err == ("m3c2: error: --process-noise auto needs observations with a variance, and no "
                                       "core point has a distance with one; give --process-noise Q\n")
