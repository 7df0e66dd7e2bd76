"""`m3c2 series report` after `m3c2 series tam3c2` (series/report_tam3c2.py; docs/series.md, "py4dgeo
archives and the report"): each chosen core point's embedded numbers are the store's, the paragraph's
completeness and significance counts are an independent count of the store, a run older than the
store's last epochs is shown over the epochs it covered and said so, half-written variables are
refused naming the rerun, and a store without TAM3C2 (plain, or after Kalman) gets the report it
always got, byte for byte (against digests of the report before the TAM3C2 part)."""
from __future__ import annotations

import numpy as np
import pytest

xr = pytest.importorskip("xarray")
pytest.importorskip("zarr")
pytest.importorskip("matplotlib")

from m3c2kit.base import fault_hook  # noqa: E402
from m3c2kit.cli.main import main  # noqa: E402
from m3c2kit.series import report  # noqa: E402
from m3c2kit.series import store as st  # noqa: E402
from test_series_report_kalman import describe, digest, embedded, floats  # noqa: E402  (the Kalman report tests' helpers)
from test_series_trust import copy  # noqa: E402  (the store tests' helper)
from test_tam3c2_store import REF_TIME, base, surface  # noqa: E402, F401  (the TAM3C2 store's fixture)

Z90 = 1.6448536269514722  # scipy.stats.norm.ppf(0.95)
CORES = ["--core", "0", "--core", "33", "--core", "69"]
#: Non-default options, so that the paragraph's record is the run's, not the defaults.
OPTIONS = ["--reference-time", REF_TIME, "--required-points", "5", "--window-ratio", "0.5,1", "--weights",
           "gaussian", "--sigma-ratio", "0.5", "--confidence", "0.9", "--quiet"]
#: sha256 of the report of `base` (70 core points in core chunks of 40, 10 epochs; no TAM3C2
#: variables) with CORES, made by series/report.py as it was before the TAM3C2 part, with the
#: store's path written STORE and each figure described by `describe` instead of its PNG: of the
#: store as it is, and after `m3c2 series kalman --process-noise 0.5`. BEFORE_KALMAN was pinned
#: anew when the Kalman filter's default became the shared observation model (issue 41: other
#: numbers, and its paragraph names the model); the page holds no TAM3C2 text (asserted below).
BEFORE = "cb7808ab853345db159ddb23871794abdbae07f04c78b6a9a4e53017f538a4a8"
BEFORE_KALMAN = "4f72df5d9a93b39865645412f2d1809c5f38fc8ecedfde69555c0697a65e6e3b"


@pytest.fixture(scope="module")
def computed(base, tmp_path_factory):
    """The TAM3C2 store: `base` after `m3c2 series tam3c2` with OPTIONS."""
    store = copy(base[0], tmp_path_factory.mktemp("tam_report"))
    assert run_quiet("series", "tam3c2", store, *OPTIONS) == 0
    return store


def run_quiet(*argv) -> int:
    return main([str(a) for a in argv])


def raw(store, name: str) -> np.ndarray:
    """The stored values as written (xarray would decode the integer fill -1 to NaN)."""
    return np.asarray(st.open_group(store)[name][...])


def page_of(store, tmp_path, *cores) -> str:
    page = tmp_path / "r.html"
    assert run_quiet("series", "report", store, "-o", page, *(cores or CORES)) == 0
    return page.read_text()


def test_the_report_embeds_each_core_points_tam3c2_series_and_draws_a_row_for_it(computed, tmp_path,
                                                                                  monkeypatch):
    store = copy(computed, tmp_path)
    figures = []
    monkeypatch.setattr(report, "png", lambda fig: figures.append(fig) or b"")
    page = page_of(store, tmp_path)
    ds = xr.open_zarr(store).load()
    blocks = embedded(page, "tam3c2")
    assert sorted(blocks) == [0, 33, 69] and page.count("<img") == 3
    significant, window = raw(store, "tam3c2_significant"), raw(store, "tam3c2_window")
    borrowed = 0
    for core, data in blocks.items():
        tam = ds["tam3c2_distance"].values[core]
        # the same bits as the store (JSON's float is repr's: it reads back exactly)
        assert floats(data["tam3c2_distance"]).tobytes() == tam.tobytes()
        assert floats(data["tam3c2_lod"]).tobytes() == ds["tam3c2_lod"].values[core].tobytes()
        assert floats(data["distance"]).tobytes() == ds["distance"].values[core].tobytes()
        assert data["tam3c2_significant"] == significant[core].tolist()
        assert data["tam3c2_window"] == window[core].tolist()
        assert data["epochs"] == data["epochs_covered"] == 10 and data["time"][3].startswith("2024-01-01T05:00")
        assert data["confidence"] == 0.9 and abs(data["z"] - Z90) < 1e-12
        borrowed += int((np.isfinite(tam) & np.isnan(ds["distance"].values[core])).sum())
    assert borrowed > 0  # a cell only TAM3C2 fills: the blocks are not the M3C2 columns renamed
    flags = {v for d in blocks.values() for v in d["tam3c2_significant"]}
    assert 1 in flags and len(flags) > 1  # flagged and unflagged cells: the filled markers are a selection
    # each figure: the core point's plot, and under it the TAM3C2 row with the TAM3C2 distances drawn
    assert len(figures) == 3
    for fig, core in zip(figures, (0, 33, 69)):
        top, row = fig.axes
        assert top.get_title().startswith(f"core point {core} ") and row.get_title() == "TAM3C2"
        assert row.get_shared_x_axes().joined(top, row)
        drawn = [ln for ln in row.get_lines() if ln.get_label() == "tam3c2_significant"][0]
        flagged = significant[core] == 1
        np.testing.assert_array_equal(drawn.get_ydata(), ds["tam3c2_distance"].values[core][flagged])


def test_the_paragraph_states_the_options_and_counts_completeness_and_significance(computed, tmp_path):
    store = copy(computed, tmp_path)
    page = page_of(store, tmp_path, "--core", "1")
    ds = xr.open_zarr(store).load()
    cells = ds.sizes["core"] * 10
    m3c2 = int(np.isfinite(ds["distance"].values).sum())
    tam = int(np.isfinite(ds["tam3c2_distance"].values).sum())
    flagged = int(np.sum(ds["tam3c2_significant"].values == 1))  # decoded: -1 (no distance) is NaN
    assert m3c2 < tam < cells and 0 < flagged < tam  # distinct numbers: a swapped count fails
    assert (f"TAM3C2 gives a distance in {tam} of the {cells} (core point, epoch) cells ({100 * tam / cells:.1f} %), "
            f"per-epoch M3C2 in {m3c2} ({100 * m3c2 / cells:.1f} %); {flagged} of the {tam} TAM3C2 distances "
            f"({100 * flagged / tam:.1f} %) are tam3c2_significant") in page
    assert ("required points 5, window ratios 0.5, 1, normal radii 0.5, weights gaussian (sigma ratio 0.5, "
            "space-time ratio 1), LOD with z at the 90 % level (z = 1.6449)") in page
    assert "computed over the first" not in page


def test_the_report_names_the_fallback_cells(computed, tmp_path, monkeypatch):
    """--fallback m3c2 (the default): the paragraph counts the cells holding the epoch's own M3C2
    (tam3c2_window 0), each block lists them, and the row draws them apart."""
    store = copy(computed, tmp_path)
    figures = []
    monkeypatch.setattr(report, "png", lambda fig: figures.append(fig) or b"")
    page = page_of(store, tmp_path)
    window = raw(store, "tam3c2_window")
    tam = int(np.isfinite(xr.open_zarr(store)["tam3c2_distance"].values).sum())
    own = int((window == 0).sum())
    assert 0 < own < tam
    assert (f"Fallback: {own} of the {tam} distances ({100 * own / tam:.1f} %) are the epoch's own M3C2 (its "
            f"windows fell short of 5 points; tam3c2_window 0") in page
    for (core, data), fig in zip(sorted(embedded(page, "tam3c2").items()), figures):
        assert data["fallback"] == "m3c2" and data["tam3c2_from_epoch"] == (window[core] == 0).tolist()
        drawn = [ln for ln in fig.axes[1].get_lines() if ln.get_label().startswith("the epoch's own M3C2")]
        assert len(drawn) == int((window[core] == 0).any())
    assert any((window[c] == 0).any() for c in (0, 33, 69))  # a figure draws some


def test_a_run_older_than_the_last_epochs_is_shown_over_its_epochs_and_said(computed, tmp_path, monkeypatch):
    store = copy(computed, tmp_path)
    figures = []
    monkeypatch.setattr(report, "png", lambda fig: figures.append(fig) or b"")
    late = tmp_path / "late.npy"
    np.save(late, surface(np.random.default_rng(36), int(36 * 5.5), 20))
    (tmp_path / "late.txt").write_text(f"{late}, {np.datetime64(REF_TIME) + np.timedelta64(20, 'h')}\n")
    assert run_quiet("series", "add", store, tmp_path / "late.txt", "--quiet") == 0
    page = page_of(store, tmp_path, "--core", "33")
    assert f"computed over the first 10 of 11 epochs; rerun <code>m3c2 series tam3c2 {store}</code>" in page
    data = embedded(page, "tam3c2")[33]
    ds = xr.open_zarr(store).load()
    assert data["epochs"] == 11 and data["epochs_covered"] == 10
    assert len(data["time"]) == len(data["distance"]) == 11
    assert floats(data["tam3c2_distance"]).tobytes() == ds["tam3c2_distance"].values[33, :10].tobytes()
    # the counts are over the 10 epochs covered, though the 11th has M3C2 distances
    late_m3c2 = int(np.isfinite(ds["distance"].values[:, 10]).sum())
    m3c2 = int(np.isfinite(ds["distance"].values[:, :10]).sum())
    assert late_m3c2 > 0 and f"of the {ds.sizes['core'] * 10} (core point, epoch) cells" in page
    assert f"per-epoch M3C2 in {m3c2} (" in page
    row = figures[0].axes[1]  # the row says so too, and shades the epoch added since
    assert row.get_title() == "TAM3C2, computed over the first 10 of 11 epochs"
    assert "added since the run" in [p.get_label() for p in row.patches]


@pytest.mark.parametrize("first", [True, False], ids=["first-run", "rerun"])
def test_half_written_tam3c2_variables_are_refused_naming_the_rerun_and_write_no_page(base, computed, tmp_path,
                                                                                      capsys, monkeypatch, first):
    # a first run killed inside its publication leaves its variables marked and not yet committed
    store = copy(base[0] if first else computed, tmp_path)
    monkeypatch.setenv(fault_hook.ENV, "store-commit:SIGTERM")
    monkeypatch.setattr(fault_hook, "_fired", set())
    assert run_quiet("series", "tam3c2", store, *OPTIONS) == 1
    monkeypatch.delenv(fault_hook.ENV)
    assert "tam3c2_distance" in st.rewriting(st.open_group(store))
    capsys.readouterr()
    page = tmp_path / "r.html"
    assert run_quiet("series", "report", store, "-o", page, "--core", "33") == 1
    err = capsys.readouterr().err
    assert "half-written" in err and f"rerun m3c2 series tam3c2 {store}" in err, err
    assert not page.exists()


def test_a_store_without_tam3c2_gets_the_report_it_always_got(base, computed, tmp_path, monkeypatch):
    monkeypatch.setattr(report, "png", describe)
    store = copy(base[0], tmp_path / "plain")
    page = tmp_path / "r.html"
    assert run_quiet("series", "report", store, "-o", page, *CORES) == 0
    assert "tam3c2" not in page.read_text().replace(str(store), "STORE").lower()
    assert digest(store, page) == BEFORE
    filtered = copy(base[0], tmp_path / "kalman")
    assert run_quiet("series", "kalman", filtered, "--process-noise", "0.5", "--quiet") == 0
    assert run_quiet("series", "report", filtered, "-o", page, *CORES) == 0
    assert "tam3c2" not in page.read_text().replace(str(filtered), "STORE").lower()
    assert digest(filtered, page) == BEFORE_KALMAN
    # and with TAM3C2 (with or without Kalman) the page does change: the digests can fail
    assert run_quiet("series", "report", computed, "-o", page, *CORES) == 0
    assert digest(computed, page) != BEFORE
    assert run_quiet("series", "tam3c2", filtered, *OPTIONS) == 0
    assert run_quiet("series", "report", filtered, "-o", page, *CORES) == 0
    assert digest(filtered, page) != BEFORE_KALMAN and len(embedded(page.read_text(), "tam3c2")) == 3


def test_tam3c2_variables_without_their_runs_record_are_refused_naming_the_rerun(computed, tmp_path, capsys):
    store = copy(computed, tmp_path)
    _, zarr = st.require_extra()
    group = zarr.open_group(str(store), mode="r+", use_consolidated=False)
    del group["tam3c2_distance"].attrs["epochs"]
    zarr.consolidate_metadata(str(store))
    page = tmp_path / "r.html"
    assert run_quiet("series", "report", store, "-o", page, "--core", "33") == 1
    err = capsys.readouterr().err
    assert "lack their run's record" in err and f"rerun m3c2 series tam3c2 {store}" in err, err
    assert not page.exists()
