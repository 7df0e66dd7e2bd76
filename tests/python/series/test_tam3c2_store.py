"""`m3c2 series tam3c2` on a store (series/tam3c2.py; docs/series.md, "TAM3C2"): the variables
equal the engine's TAM3C2 on the store's recorded files and times, more core points get a distance
than plain per-epoch M3C2 on sparse epochs (the paper's completeness gain, seeded simulation) and,
with the fallback, never fewer in any epoch, the window breaks keep a step out of the epoch before
it, the store stays sound, bad input is refused naming it, and a kill at every write phase keeps the
previous variables or marks all of them half-written (never a mix)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

xr = pytest.importorskip("xarray")
pytest.importorskip("zarr")

from m3c2kit import engine as facade  # noqa: E402
from m3c2kit.base import fault_hook  # noqa: E402
from m3c2kit.cli.main import main  # noqa: E402
from m3c2kit.series import store as st  # noqa: E402
from test_series_trust import copy, run  # noqa: E402  (the store tests' helpers)

PARAMS = ["--core-spacing", "0.6", "--normal-scale", "1", "--projection-scale", "0.6", "--max-depth", "1",
          "--lod", "z"]
REF_TIME = "2024-01-01T00:00"
RISE = 0.01  # m per hour, everywhere: the truth


def surface(rng, n, hours):
    x, y = rng.uniform(0, 6, n), rng.uniform(0, 6, n)
    z = 0.1 * x + 0.05 * np.sin(2 * y) + RISE * hours + rng.normal(0, 0.005, n)
    return np.column_stack([x, y, z])


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    """A dense reference and 10 sparse epochs (about 1.5 points per cylinder), irregular hours."""
    folder = tmp_path_factory.mktemp("tam_epochs")
    rng = np.random.default_rng(35)
    np.save(folder / "ref.npy", surface(rng, 36 * 60, 0.0))
    hours = [1, 2, 3, 5, 6, 9, 10, 11, 14, 15]
    lines = []
    for k, h in enumerate(hours):
        np.save(folder / f"e{k:02d}.npy", surface(rng, int(36 * 5.5), h))
        lines.append(f"e{k:02d}.npy, {np.datetime64(REF_TIME) + np.timedelta64(h, 'h')}\n")
    (folder / "epochs.txt").write_text("".join(lines))
    out = tmp_path_factory.mktemp("tam_base") / "base.zarr"
    assert main(["series", str(folder / "ref.npy"), str(folder / "epochs.txt"), "-o", str(out), *PARAMS,
                 "--quiet", "--core-chunk", "40", "--epoch-chunk", "4"]) == 0
    return out, folder, hours


def test_the_variables_are_the_engines_tam3c2_on_the_recorded_files(base, tmp_path, capsys):
    store0, folder, hours = base
    store = copy(store0, tmp_path)
    code, out, _ = run(capsys, "series", "tam3c2", store, "--reference-time", REF_TIME, "--required-points", "6",
                       "--window-ratio", "0.5,1", "--weights", "gaussian")
    assert code == 0 and "TAM3C2 over 10 epochs" in out
    ds = xr.open_zarr(store).load()
    core = np.column_stack([ds["x"].values, ds["y"].values, ds["z"].values])
    clouds = [np.load(folder / "ref.npy")] + [np.load(folder / f"e{k:02d}.npy") for k in range(10)]
    pool = facade.tam3c2_pool(clouds, [0.0] + [h / 24.0 for h in hours])
    s = dict(normal_radii=[0.5], window_ratios=[0.5, 1.0], min_points=6, cylinder_radius=0.3, max_distance=1.0,
             weights="gaussian", sigma_ratio=1.0, space_time_ratio=1.0, registration_error=0.0,
             orientation=[0.0, 0.0, 1.0], lod="z", confidence=0.95)
    towards = np.column_stack([ds["nx"].values, ds["ny"].values, ds["nz"].values])
    # the store's own M3C2 as the engine's pool columns (the reference's: distance 0)
    own = {k: np.column_stack([np.zeros(len(core)) if k == "distance" else np.full(len(core), np.nan),
                               ds[k].values.astype(float)]) for k in facade.TAM3C2_EPOCHWISE}
    want = facade.tam3c2(pool, core, 0, range(1, 11), dict(s, fallback="m3c2"), orientations=towards, epochwise=own)
    np.testing.assert_array_equal(ds["tam3c2_distance"].values, want["distance"])
    np.testing.assert_array_equal(ds["tam3c2_lod"].values, want["lod"])
    np.testing.assert_array_equal(ds["tam3c2_n2"].values, want["n2"])
    from_epoch = want["source"] == facade.TAM3C2_SOURCE_EPOCH
    assert from_epoch.any() and (want["source"] == facade.TAM3C2_SOURCE_WINDOWS).any()
    window = np.where(from_epoch, 0, want["epochs1"] + want["epochs2"]).astype(np.int32)
    window[np.isnan(want["distance"])] = -1
    np.testing.assert_array_equal(np.nan_to_num(ds["tam3c2_window"].values, nan=-1), window)  # xarray: -1 is NaN
    np.testing.assert_array_equal(ds["tam3c2_distance"].values[from_epoch], ds["distance"].values[from_epoch])
    sig = ds["tam3c2_significant"].values
    # xarray decodes the fill (-1: no distance, or the epoch's own M3C2 without a significance: its
    # LOD NaN at one point on a side) to NaN
    untested = from_epoch & np.isnan(ds["significant"].values)
    assert untested.any() and np.array_equal(np.isnan(sig), np.isnan(want["distance"]) | untested)
    ok = ~np.isnan(sig)
    np.testing.assert_array_equal(sig[ok], want["significant"][ok])
    assert np.array_equal(sig[ok & ~from_epoch] == 1, (np.abs(want["distance"]) > want["lod"])[ok & ~from_epoch])
    np.testing.assert_array_equal(sig[from_epoch], ds["significant"].values[from_epoch])
    assert (sig == 1).any()
    # --fallback none: the authors' rule, the engine without the epochs' own M3C2
    assert run(capsys, "series", "tam3c2", store, "--reference-time", REF_TIME, "--required-points", "6",
               "--window-ratio", "0.5,1", "--weights", "gaussian", "--fallback", "none")[0] == 0
    authors = facade.tam3c2(pool, core, 0, range(1, 11), s, orientations=towards)
    np.testing.assert_array_equal(xr.open_zarr(store)["tam3c2_distance"].values, authors["distance"])
    assert ds["tam3c2_distance"].attrs["weights"] == "gaussian"
    assert ds["tam3c2_distance"].attrs["lod"] == "z"  # the store's (PARAMS: --lod z)
    assert run(capsys, "series", "check", store)[0] == 0


def test_the_distances_share_the_sign_of_the_stores_oriented_normals(base, tmp_path, capsys):
    """A store whose normals were turned down (--orient -z) measures the rise as negative, and
    TAM3C2 on it too: the same magnitudes as on the +z store, the opposite sign."""
    _, folder, _ = base
    down = tmp_path / "down.zarr"
    assert main(["series", str(folder / "ref.npy"), str(folder / "epochs.txt"), "-o", str(down), *PARAMS,
                 "--orient", "-z", "--quiet", "--core-chunk", "40", "--epoch-chunk", "4"]) == 0
    up = copy(base[0], tmp_path)
    options = ["--reference-time", REF_TIME, "--required-points", "6", "--window-ratio", "0.5,1"]
    assert run(capsys, "series", "tam3c2", down, *options)[0] == 0
    assert run(capsys, "series", "tam3c2", up, *options)[0] == 0
    d_down, d_up = (xr.open_zarr(s)["tam3c2_distance"].values for s in (down, up))
    plain = xr.open_zarr(down)["distance"].values
    assert np.nanmedian(plain) < 0 and np.nanmedian(d_down) < 0 < np.nanmedian(d_up)
    np.testing.assert_allclose(d_down, -d_up, rtol=0, atol=1e-12)


def test_more_core_points_get_a_distance_than_with_plain_m3c2_on_sparse_epochs(base, tmp_path, capsys):
    """The paper's completeness gain: per-epoch M3C2 needs points of that epoch in the cylinder;
    TAM3C2 borrows the nearest epochs. The truth (RISE per hour) stays within a few LODs."""
    store = copy(base[0], tmp_path)
    assert run(capsys, "series", "tam3c2", store, "--reference-time", REF_TIME, "--required-points", "5",
               "--window-ratio", "1")[0] == 0
    ds = xr.open_zarr(store).load()
    plain, tam = np.isfinite(ds["distance"].values), np.isfinite(ds["tam3c2_distance"].values)
    assert tam.sum() > 1.1 * plain.sum(), (tam.sum(), plain.sum())
    truth = RISE * np.array(base[2])[None, :] * np.ones_like(ds["tam3c2_distance"].values)
    error = np.abs(ds["tam3c2_distance"].values - truth)[tam]
    assert np.median(error) < 0.02


def make_store(folder: Path, hours, z_of_hour, seed: int, density: float = 5.5) -> Path:
    """A store of a dense reference at hour 0 and sparse epochs (`density` points per m²: about
    1.5 per cylinder at 5.5) at `hours`, the surface at height z_of_hour(h) plus a slope
    (validation/tam3c2_fallback.py uses it too)."""
    rng = np.random.default_rng(seed)

    def cloud(n, h):
        x, y = rng.uniform(0, 6, n), rng.uniform(0, 6, n)
        return np.column_stack([x, y, 0.1 * x + 0.05 * np.sin(2 * y) + z_of_hour(h) + rng.normal(0, 0.005, n)])

    np.save(folder / "ref.npy", cloud(36 * 60, 0.0))
    lines = []
    for k, h in enumerate(hours):
        np.save(folder / f"e{k:02d}.npy", cloud(int(36 * density), h))
        lines.append(f"e{k:02d}.npy, {np.datetime64(REF_TIME) + np.timedelta64(int(round(h * 60)), 'm')}\n")
    (folder / "epochs.txt").write_text("".join(lines))
    out = folder / "store.zarr"
    assert main(["series", str(folder / "ref.npy"), str(folder / "epochs.txt"), "-o", str(out), *PARAMS,
                 "--quiet", "--core-chunk", "40", "--epoch-chunk", "4"]) == 0
    return out


#: The scenes of the fallback and breaks tests (and of validation/tam3c2_fallback.py): epochs close
#: to the reference's time, whose windows (|t - t_r| x 0.2) hold no other epoch; and no change,
#: then a 5 cm step from hour 7 on, epochs every hour, so that --required-points 10 borrows about
#: 6 epochs.
NEAR_HOURS = [0.25, 0.5, 1, 2, 4, 6, 9, 12, 18, 24]
STEP_HOURS, STEP_AT, STEP = list(range(1, 13)), 7, 0.05


def step_height(h):
    return STEP * (h >= STEP_AT)


@pytest.fixture(scope="module")
def near_reference(tmp_path_factory):
    return make_store(tmp_path_factory.mktemp("tam_near"), NEAR_HOURS, lambda h: RISE * h, 41)


def test_with_the_fallback_no_epoch_has_fewer_distances_than_plain_m3c2(near_reference, tmp_path, capsys):
    """Issue 41: near the reference's time W is tiny, a side cannot reach --required-points, and
    the authors' rule leaves cells NaN where the epoch's own M3C2 has a distance; the fallback
    gives those the epoch's own, so TAM3C2 >= M3C2 in every epoch (and the authors' rule is
    below it in some epoch here: this test can fail)."""
    counts = {}
    for fallback in ("none", "m3c2"):
        store = copy(near_reference, tmp_path / fallback)
        code, out, _ = run(capsys, "series", "tam3c2", store, "--reference-time", REF_TIME, "--fallback", fallback)
        assert code == 0
        ds = xr.open_zarr(store).load()
        counts[fallback] = np.isfinite(ds["tam3c2_distance"].values).sum(axis=0)
        plain = np.isfinite(ds["distance"].values).sum(axis=0)
        assert ds["tam3c2_distance"].attrs["fallback"] == fallback
        window = ds["tam3c2_window"].values
        assert ((window == 0).any()) == (fallback == "m3c2")
    assert (counts["m3c2"] >= plain).all(), (counts, plain)
    assert (counts["none"] < plain).any(), (counts, plain)


@pytest.fixture(scope="module")
def step(tmp_path_factory):
    return make_store(tmp_path_factory.mktemp("tam_step"), STEP_HOURS, step_height, 43)


def test_the_window_breaks_keep_a_step_out_of_the_epoch_before_it(step, tmp_path, capsys):
    """With --window-breaks none, the epoch before the step (hour 6, truth 0) borrows epochs after
    it: its median error is over 1 cm; with changepoints the windows stop at the step detected in
    each core point's per-epoch M3C2 series: under 0.5 cm."""
    errors = {}
    for breaks in ("none", "changepoints"):
        store = copy(step, tmp_path / breaks)
        assert run(capsys, "series", "tam3c2", store, "--reference-time", REF_TIME, "--window-ratio", "1",
                   "--window-breaks", breaks)[0] == 0
        d = xr.open_zarr(store)["tam3c2_distance"].values
        k = STEP_HOURS.index(STEP_AT)
        before, after = d[:, k - 1], d[:, k]  # hours 6 and 7
        errors[breaks] = (float(np.nanmedian(np.abs(before))), float(np.nanmedian(np.abs(after - STEP))))
        assert np.isfinite(before).mean() > 0.9
    assert errors["none"][0] > 0.01 and errors["changepoints"][0] < 0.005, errors
    assert errors["changepoints"][1] < 0.005, errors  # and the epoch after it: its own side of the step


def test_a_reference_after_every_epoch_is_said(base, tmp_path, capsys):
    """Hostile round 2: --reference-time after every epoch (a mistyped year) ran without a word."""
    store = copy(base[0], tmp_path)
    code, _, err = run(capsys, "series", "tam3c2", store, "--reference-time", "2034-01-01T00:00")
    assert code == 0 and "is after every epoch (the last: 2024-01-01T15:00" in err and "--reference-time" in err, err
    code, _, err = run(capsys, "series", "tam3c2", store, "--reference-time", REF_TIME)
    assert code == 0 and "after every epoch" not in err, err


class _Recorded:
    """A store view whose store records its reference's time."""

    def __init__(self, recorded):
        self.shown, self.group = Path("s.zarr"), type("G", (), {"attrs": {"reference_time": recorded}})()

    def times(self, needed_by):
        return np.array([np.datetime64("2024-01-02T00:00", "us").astype(np.int64)])


def test_a_reference_time_that_contradicts_the_stores_is_refused():
    from m3c2kit.base.errors import UsageError
    from m3c2kit.series.tam3c2 import _reference_microseconds
    view = _Recorded("2024-01-01T00:00")
    expected = np.datetime64("2024-01-01T00:00", "us").astype(np.int64)
    assert _reference_microseconds(view, None) == expected == _reference_microseconds(view, "2024-01-01T00:00")
    with pytest.raises(UsageError, match="--reference-time 2024-01-01T06:00 contradicts s.zarr's recorded reference "
                                         "time 2024-01-01T00:00: the option is for a store that has none"):
        _reference_microseconds(view, "2024-01-01T06:00")


def test_bad_input_is_refused_naming_it(base, tmp_path, capsys):
    store = copy(base[0], tmp_path)
    code, _, err = run(capsys, "series", "tam3c2", store)
    assert code == 2 and "--reference-time" in err  # the .npy reference has no time
    code, _, err = run(capsys, "series", "tam3c2", store, "--reference-time", REF_TIME, "--window-ratio", "1.5")
    assert code == 2 and "--window-ratio" in err
    code, _, err = run(capsys, "series", "tam3c2", store, "--reference-time", "yesterday")
    assert code == 2 and "--reference-time" in err
    code, _, err = run(capsys, "series", "tam3c2", store, "--reference-time", REF_TIME, "--window-breaks", "steps")
    assert code == 2 and "--window-breaks" in err
    code, _, err = run(capsys, "series", "tam3c2", store, "--reference-time", REF_TIME, "--break-width", "1")
    assert code == 2 and "--break-width" in err
    assert not any(name in st.open_group(store) for name in st.TAM3C2_VARIABLES)


@pytest.mark.slow
def test_a_kill_at_every_write_phase_keeps_the_previous_variables_or_marks_them_all(base, tmp_path, capsys,
                                                                                     monkeypatch):
    store = copy(base[0], tmp_path)
    args = ["series", "tam3c2", store, "--reference-time", REF_TIME]
    assert run(capsys, *args)[0] == 0
    before = xr.open_zarr(store).load()
    names = st.TAM3C2_VARIABLES
    for phase in ("store-write", "store-commit"):
        monkeypatch.setenv(fault_hook.ENV, f"{phase}:SIGTERM")
        monkeypatch.setattr(fault_hook, "_fired", set())
        code, _, err = run(capsys, *args, "--required-points", "20")
        monkeypatch.delenv(fault_hook.ENV)
        assert code == 1 and "interrupted by SIGTERM" in err, err
        if phase == "store-write":
            assert "TAM3C2 variables" in err and "unchanged" in err
            after = xr.open_zarr(store).load()
            for name in names:
                assert after[name].equals(before[name]) and after[name].attrs == before[name].attrs
            assert run(capsys, "series", "check", store)[0] == 0
        else:
            assert "half-written" in err and "m3c2 series tam3c2" in err
            assert set(names) <= set(st.rewriting(st.open_group(store)))
            code, out, _ = run(capsys, "series", "check", store)
            assert code == 1 and "m3c2 series tam3c2" in out
            assert run(capsys, *args, "--required-points", "20")[0] == 0  # the rerun replaces them whole
            assert run(capsys, "series", "check", store)[0] == 0
            assert xr.open_zarr(store)["tam3c2_distance"].attrs["min_points"] == 20


def test_add_extends_the_variables_unset_until_the_step_reruns(base, tmp_path, capsys):
    store0, folder, _ = base
    store = copy(store0, tmp_path)
    args = ["series", "tam3c2", store, "--reference-time", REF_TIME]
    assert run(capsys, *args)[0] == 0
    late = tmp_path / "late.npy"
    np.save(late, surface(np.random.default_rng(36), int(36 * 5.5), 20))
    (tmp_path / "late.txt").write_text(f"{late}, {np.datetime64(REF_TIME) + np.timedelta64(20, 'h')}\n")
    assert run(capsys, "series", "add", store, tmp_path / "late.txt", "--quiet")[0] == 0
    ds = xr.open_zarr(store)
    assert ds["tam3c2_distance"].shape == (ds.sizes["core"], 11)
    assert np.isnan(ds["tam3c2_distance"].values[:, 10]).all()
    assert run(capsys, "series", "check", store)[0] == 0
    assert run(capsys, *args)[0] == 0
    assert np.isfinite(xr.open_zarr(store)["tam3c2_distance"].values[:, 10]).any()


def test_an_epoch_file_changed_since_it_was_added_is_refused_naming_it(base, tmp_path, capsys):
    store = copy(base[0], tmp_path)
    ds = xr.open_zarr(store)
    first = Path(str(ds["source"].values[0]))
    assert first.is_file()
    original = first.read_bytes()
    try:
        np.save(first, np.load(first) + 0.001)
        code, _, err = run(capsys, "series", "tam3c2", store, "--reference-time", REF_TIME)
        assert code == 1 and str(first) in err and "SHA-256" in err
        assert "tam3c2_distance" not in st.open_group(store)
    finally:
        first.write_bytes(original)


def test_each_file_is_read_once_whatever_the_blocks_and_no_spill_is_left(base, tmp_path, capsys, monkeypatch):
    """The store's core chunks make several blocks; each recorded file is decoded once (its crops
    spilled, series/epoch_crops.py), and the private spill folder is gone after the run."""
    from m3c2kit.series import tam3c2 as tam
    from m3c2kit.series.view import StoreView
    store = copy(base[0], tmp_path)
    reads = []
    real = tam.read_cloud
    monkeypatch.setattr(tam, "read_cloud", lambda path, *a, **k: reads.append(Path(path)) or real(path, *a, **k))
    blocks = tam._blocks(StoreView(store))
    assert len(blocks) > 1  # else the test would not test the spill
    assert run(capsys, "series", "tam3c2", store, "--reference-time", REF_TIME)[0] == 0
    assert len(reads) == 11 and len(set(reads)) == 11
    assert not [p.name for p in store.parent.iterdir() if p.name.startswith(".m3c2-tmp-")]


def test_a_full_disk_while_spilling_is_named_and_publishes_nothing(base, tmp_path, capsys, monkeypatch):
    from m3c2kit.series import epoch_crops
    store = copy(base[0], tmp_path)
    real_open = open

    def full(path, mode="r", *a, **k):
        if "a" in mode and Path(path).name.startswith("block-"):
            raise OSError(28, "No space left on device")
        return real_open(path, mode, *a, **k)

    monkeypatch.setattr(epoch_crops, "open", full, raising=False)
    code, _, err = run(capsys, "series", "tam3c2", store, "--reference-time", REF_TIME)
    assert code == 1 and "No space left on device" in err and str(store) in err, err
    assert not any(name in st.open_group(store) for name in st.TAM3C2_VARIABLES)
    assert run(capsys, "series", "check", store)[0] == 0
    assert not [p.name for p in store.parent.iterdir() if p.name.startswith(".m3c2-tmp-")]


def test_the_lod_follows_the_stores_statistic_unless_given(base, tmp_path, capsys):
    """The store says --lod z: TAM3C2's LOD is z; --lod t gives Welch's t (wider at these few
    points); a bootstrap is refused naming --lod. (--fallback none: a fallback cell holds the store's LOD.)"""
    store = copy(base[0], tmp_path)
    options = ["--reference-time", REF_TIME, "--required-points", "6", "--fallback", "none"]
    assert run(capsys, "series", "tam3c2", store, *options)[0] == 0
    z = xr.open_zarr(store)["tam3c2_lod"].values
    code, out, _ = run(capsys, "series", "tam3c2", store, *options, "--lod", "t")
    assert code == 0 and "LOD (t)" in out
    ds = xr.open_zarr(store)
    t = ds["tam3c2_lod"].values
    assert ds["tam3c2_lod"].attrs["lod"] == "t"
    ok = np.isfinite(z)
    assert np.array_equal(ok, np.isfinite(t)) and (t[ok] > z[ok]).all()
    code, _, err = run(capsys, "series", "tam3c2", store, *options, "--lod", "bootstrap")
    assert code == 2 and "--lod" in err and "bootstrap" in err, err


@pytest.mark.parametrize("extra, needs", [
    (["--sigma-ratio", "3"], "--weights gaussian"),
    (["--weights", "linear", "--sigma-ratio", "3"], "--weights gaussian"),
    (["--space-time-ratio", "5"], "--weights linear or gaussian"),
    (["--break-width", "4"], "--window-breaks changepoints"),
    (["--break-min-size", "2"], "--window-breaks changepoints"),
    (["--break-penalty", "1"], "--window-breaks changepoints"),
])
def test_an_option_its_mode_never_reads_is_refused(tmp_path, capsys, extra, needs):
    """Hostile round 2: --sigma-ratio 3 --space-time-ratio 5 under --weights none ran with the same
    bits and recorded both; the break options without --window-breaks changepoints changed nothing."""
    code, _, err = run(capsys, "series", "tam3c2", tmp_path / "none.zarr", *extra)
    assert code == 2 and err.endswith(f"would change nothing in this run: it applies only with {needs}\n"), err


def test_a_list_of_fractions_with_an_empty_item_is_refused(capsys):
    """Hostile round 2: --window-ratio 0.2,,0.3 dropped the empty item and ran."""
    code, _, err = run(capsys, "series", "tam3c2", "none.zarr", "--window-ratio", "0.2,,0.3")
    assert code == 2 and "must be a list of numbers like 0.1,0.2, got '0.2,,0.3'" in err
