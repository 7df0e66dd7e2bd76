"""`m3c2 series report` after `m3c2 series kalman` (series/report_kalman.py; docs/series.md, "py4dgeo
archives and the report"): each chosen core point's numbers are embedded in the page and are the
store's smoothed series, its band is kalman_distance +- z sigma at the run's confidence, the page
states the run and the share flagged at the last epoch; a store without the filter gets the
report it always got, byte for byte (against a digest of the report before the Kalman part)."""
from __future__ import annotations

import dataclasses
import hashlib
import json
import re
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

xr = pytest.importorskip("xarray")
pytest.importorskip("zarr")
pytest.importorskip("matplotlib")

from m3c2kit.base import fault_hook  # noqa: E402
from m3c2kit.cli.main import main  # noqa: E402
from m3c2kit.series import report  # noqa: E402

REPO = Path(__file__).resolve().parents[3]
sys.path.insert(0, str(REPO / "validation"))
import series_synthetic as ss  # noqa: E402

Z95, Z80 = 1.959963984540054, 1.2815515655446004  # normal quantiles, scipy.stats.norm.ppf(0.975 / 0.9)
PARAMS = ["--core-spacing", "0.5", "--normal-scale", "1", "--projection-scale", "1", "--max-depth", "1",
          "--lod", "z", "--quiet"]
SCENARIO = ss.Scenario(extent=10.0, density=12.0, epochs=8, offset_epoch=20,
                       blobs=(ss.Blob(5.0, 5.0, 2.5, 0.4, 2, 6),),
                       landslide=ss.Landslide(2.0, 2.0, 1.0, 1.0, 0.0, 0.0, 2))
HOURS = [0, 1, 2, 3, 27, 28, 28.5, 30]  # irregular: a day's gap, half an hour
CORES = ["--core", "0", "--core", "43", "--core", "120"]
#: sha256 of the report of the store below (no Kalman variables) made by series/report.py as it
#: was before the Kalman part, with the store's path written STORE and each figure described by
#: `describe` instead of its PNG (so the digest does not hang on the renderer's pixels).
BEFORE = "2bd1027058befc3320ad1f2e85da4cc00782a65e24a7726dba317d607ce7c353"


@pytest.fixture(scope="module")
def plain(tmp_path_factory):
    """A store of 7 epochs at irregular times, no Kalman run."""
    folder = tmp_path_factory.mktemp("epochs")
    paths = ss.write(SCENARIO, folder)
    lines = [f"{p.name}, {np.datetime64('2024-01-01T00:00') + np.timedelta64(int(h * 60), 'm')}\n"
             for p, h in zip(paths[1:], HOURS[1:])]
    (folder / "list.txt").write_text("".join(lines))
    out = tmp_path_factory.mktemp("store") / "s.zarr"
    assert main(["series", str(paths[0]), str(folder / "list.txt"), "-o", str(out), *PARAMS]) == 0
    return out


def copy(store: Path, tmp_path: Path) -> Path:
    out = tmp_path / "s.zarr"
    shutil.copytree(store, out)
    return out


def embedded(page: str, kind: str = "kalman") -> dict[int, dict]:
    """The JSON blocks of the page of class m3c2-KIND (kalman, tam3c2), by core point."""
    blocks = re.findall(rf'<script type="application/json" class="m3c2-{kind}" data-core="(\d+)">(.*?)</script>',
                        page)
    return {int(c): json.loads(text) for c, text in blocks}


def floats(values) -> np.ndarray:
    return np.array([np.nan if v is None else v for v in values], dtype=np.float64)


def test_the_report_embeds_each_core_points_smoothed_series_and_states_the_run(plain, tmp_path):
    store = copy(plain, tmp_path)
    assert main(["series", "kalman", str(store), "--process-noise", "0.5", "--quiet"]) == 0
    page_path = tmp_path / "r.html"
    assert main(["series", "report", str(store), "-o", str(page_path), *CORES]) == 0
    page = page_path.read_text()
    ds = xr.open_zarr(store).load()
    blocks = embedded(page)
    assert sorted(blocks) == [0, 43, 120] and page.count("<img") == 3
    for core, data in blocks.items():
        smoothed, sigma = ds["kalman_distance"].values[core], ds["kalman_distance_sigma"].values[core]
        assert np.isfinite(smoothed).sum() >= 5  # a series worth comparing
        # the same bits as the store (JSON's float is repr's: it reads back exactly)
        assert floats(data["kalman_distance"]).tobytes() == smoothed.tobytes()
        assert floats(data["kalman_distance_sigma"]).tobytes() == sigma.tobytes()
        assert floats(data["distance"]).tobytes() == ds["distance"].values[core].tobytes()
        assert floats(data["lod"]).tobytes() == ds["lod"].values[core].tobytes()
        np.testing.assert_allclose(floats(data["band_low"]), smoothed - Z95 * sigma, rtol=0, atol=1e-12)
        np.testing.assert_allclose(floats(data["band_high"]), smoothed + Z95 * sigma, rtol=0, atol=1e-12)
        assert data["time"][3].startswith("2024-01-02T03:00")  # the epochs are the list's, from 1 h
    # a core point whose smoothed series moves: not a constant that any series would match
    assert np.nanstd(floats(blocks[43]["kalman_distance"])) > 0.01
    flags = np.nan_to_num(ds["kalman_significant"].values[:, -1], nan=-1)
    estimated, flagged = int((flags >= 0).sum()), int((flags == 1).sum())
    assert 0 < flagged < estimated
    assert "model velocity" in page and "continuous process noise q = 0.5 (given)" in page
    assert "(state [d, d', b]), shared observation" in page  # the default model, named
    assert f"{flagged} of the {estimated} core points with an estimate ({100 * flagged / estimated:.1f} %)" in page
    assert "the 95 % level" in page and "95 % band" not in page  # the legend is in the figure, not the text


def test_the_band_is_at_the_runs_recorded_confidence(plain, tmp_path):
    store = copy(plain, tmp_path)
    assert main(["series", "kalman", str(store), "--process-noise", "0.5", "--confidence", "0.8", "--quiet"]) == 0
    page_path = tmp_path / "r.html"
    assert main(["series", "report", str(store), "-o", str(page_path), "--core", "43"]) == 0
    data = embedded(page_path.read_text())[43]
    ds = xr.open_zarr(store).load()
    smoothed, sigma = ds["kalman_distance"].values[43], ds["kalman_distance_sigma"].values[43]
    assert data["confidence"] == 0.8
    np.testing.assert_allclose(floats(data["band_high"]), smoothed + Z80 * sigma, rtol=0, atol=1e-12)
    assert "the 80 % level" in page_path.read_text()


def test_epochs_added_after_the_run_are_said_and_not_drawn_as_estimates(plain, tmp_path):
    store = copy(plain, tmp_path)
    assert main(["series", "kalman", str(store), "--process-noise", "0.5", "--quiet"]) == 0
    epochs = ss.write(dataclasses.replace(SCENARIO, seed=7), tmp_path / "more")  # not an epoch of the store
    extra = tmp_path / "more" / "extra.txt"
    extra.write_text(f"{epochs[7].name}, 2024-01-03T00:00\n")
    assert main(["series", "add", str(store), str(extra), "--quiet"]) == 0
    page_path = tmp_path / "r.html"
    assert main(["series", "report", str(store), "-o", str(page_path), "--core", "43"]) == 0
    page = page_path.read_text()
    assert "covers the first 7 of the 8 epochs" in page
    assert "0 of the 0 core points with an estimate" in page
    assert embedded(page)[43]["kalman_distance"][7] is None


def describe(fig) -> bytes:
    """A figure as text: sizes, labels, colours and the drawn data (to 1e-6), not pixels."""
    out = [f"figure {fig.get_size_inches().tolist()}"]
    rounded = lambda a: hashlib.sha256((np.round(np.asarray(a, dtype=np.float64), 6) + 0.0).tobytes()).hexdigest()
    for ax in fig.axes:
        out += [f"axes {ax.get_title()!r} {ax.get_xlabel()!r} {ax.get_ylabel()!r} {ax.get_position().bounds}"]
        legend = ax.get_legend()
        out += [f"legend {t.get_text()!r}" for t in (legend.get_texts() if legend else [])]
        out += [f"line {ln.get_label()!r} {ln.get_color()!r} {ln.get_linewidth()} {rounded(ln.get_xydata())}"
                for ln in ax.get_lines()]
        out += [f"collection {type(c).__name__} {c.get_label()!r} {c.get_facecolor().tolist()} "
                f"{[rounded(p.vertices) for p in c.get_paths()]}" for c in ax.collections]
    return "\n".join(out).encode()


def digest(store: Path, page: Path) -> str:
    return hashlib.sha256(page.read_text().replace(str(store), "STORE").encode()).hexdigest()


def test_a_store_without_the_filter_gets_the_report_it_always_got(plain, tmp_path, monkeypatch):
    store = copy(plain, tmp_path)
    real = tmp_path / "real.html"
    assert main(["series", "report", str(store), "-o", str(real), *CORES]) == 0
    assert "kalman" not in real.read_text().lower()
    monkeypatch.setattr(report, "png", describe)
    page = tmp_path / "r.html"
    assert main(["series", "report", str(store), "-o", str(page), *CORES]) == 0
    assert digest(store, page) == BEFORE
    # and after a Kalman run (on a copy) the page does change: the digest can fail
    filtered = copy(plain, tmp_path / "k")
    assert main(["series", "kalman", str(filtered), "--process-noise", "0.5", "--quiet"]) == 0
    assert main(["series", "report", str(filtered), "-o", str(page), *CORES]) == 0
    assert digest(filtered, page) != BEFORE


@pytest.mark.parametrize("first", [True, False], ids=["first-run", "rerun"])
def test_half_written_kalman_variables_are_refused_naming_the_fix_and_write_no_page(plain, tmp_path, capsys,
                                                                                    monkeypatch, first):
    # a first run killed inside its publication leaves its variables marked and not yet committed
    store = copy(plain, tmp_path)
    if not first:
        assert main(["series", "kalman", str(store), "--process-noise", "0.5", "--quiet"]) == 0
    monkeypatch.setenv(fault_hook.ENV, "store-commit:SIGTERM")  # killed inside the publication: all marked
    monkeypatch.setattr(fault_hook, "_fired", set())
    assert main(["series", "kalman", str(store), "--process-noise", "2", "--from-scratch", "--quiet"]) == 1
    monkeypatch.delenv(fault_hook.ENV)
    capsys.readouterr()
    page = tmp_path / "r.html"
    assert main(["series", "report", str(store), "-o", str(page), "--core", "43"]) == 1
    err = capsys.readouterr().err
    assert "half-written" in err and f"m3c2 series kalman {store} --from-scratch" in err, err
    assert not page.exists()
