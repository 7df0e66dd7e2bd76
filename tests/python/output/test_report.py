"""The visual report (--report HTML, --report-png PREFIX): self-contained, complete, fast, and it
renders in a headless browser (chromium, when installed)."""
import base64
import re
import shutil
import subprocess
import time

import numpy as np
import pytest

pytest.importorskip("matplotlib")

from m3c2kit.cli.main import main  # noqa: E402
from m3c2kit.output.report import FIGURES, build_report, png_paths, render_html  # noqa: E402
from m3c2kit.engine.result import Result  # noqa: E402

from synthetic import noisy_plane_pair, write_xyz  # noqa: E402

PNG = b"\x89PNG\r\n\x1a\n"
OPTS = ["--normal-scale", "0.5", "--projection-scale", "0.3", "--max-depth", "0.5", "--quiet"]


def bumpy_pair(n=60, seed=5):
    """A plane pair whose second epoch has a mound (+) and a pit (-): both colours on the map."""
    ref, cmp = noisy_plane_pair(n=n, offset=0.0, seed=seed)
    x, y = cmp[:, 0], cmp[:, 1]
    cmp[:, 2] += 0.2 * np.exp(-((x - 0.8) ** 2 + (y - 0.8) ** 2) / 0.1) - 0.15 * np.exp(-((x - 2.2) ** 2 + (y - 2.0) ** 2) / 0.1)
    return ref, cmp


@pytest.fixture(scope="module")
def report_run(tmp_path_factory):
    d = tmp_path_factory.mktemp("report")
    ref, cmp = bumpy_pair()
    write_xyz(d / "ref.xyz", ref)
    write_xyz(d / "cmp.xyz", cmp)
    assert main(["compare", str(d / "ref.xyz"), str(d / "cmp.xyz"), "-o", str(d / "out.csv"), "--core-spacing", "0.1",
                 "--report", str(d / "report.html"), "--report-png", str(d / "figs")] + OPTS) == 0
    return d


@pytest.mark.slow
def test_html_is_self_contained(report_run):
    page = (report_run / "report.html").read_text(encoding="utf-8")
    assert page.startswith("<!DOCTYPE html>")
    # The only scripts are inline (plotly.js for the 3D view, test_report_paper.py renders it
    # offline in Chromium); none is loaded from anywhere.
    assert not re.search(r"<script[^>]*\bsrc\s*=", page, re.I)
    text = re.sub(r"<script\b.*?</script>", "", page, flags=re.S | re.I)
    assert not re.search(r"""(?:src|href)\s*=\s*["']?\s*(?:https?:|//)""", text, re.I)
    assert not re.search(r"https?://", text)
    assert "<script" not in text and "<link" not in text and "@import" not in text and "url(" not in text
    srcs = re.findall(r'<img[^>]*src="([^"]*)"', text)
    assert len(srcs) == len(FIGURES)
    for src in srcs:
        assert src.startswith("data:image/png;base64,")
        assert base64.b64decode(src.split(",", 1)[1]).startswith(PNG)


def test_html_has_the_tables_and_thresholds(report_run):
    text = (report_run / "report.html").read_text(encoding="utf-8")
    for needle in ("core points", "significant", "median distance", "median LOD", "too_few_normal_points",
                   "projection_scale", "max_depth", "normal_scale", "xi = D / sigma(D) &gt; 20", "Fig. 10",
                   "core points plotted"):
        assert needle in text, needle


def test_png_files_next_to_the_html(report_run):
    for key, path in png_paths(report_run / "figs").items():
        assert path.name == f"figs_{key}.png"
        assert path.read_bytes().startswith(PNG)
    assert (report_run / "out.csv").exists()
    assert not [p for p in report_run.iterdir() if p.name.startswith(".")]


@pytest.mark.slow
def test_report_without_html_only_pngs(tmp_path):
    ref, cmp = bumpy_pair(n=30)
    write_xyz(tmp_path / "ref.xyz", ref)
    write_xyz(tmp_path / "cmp.xyz", cmp)
    assert main(["compare", str(tmp_path / "ref.xyz"), str(tmp_path / "cmp.xyz"), "-o", str(tmp_path / "o.csv"),
                 "--report-png", str(tmp_path / "p")] + OPTS) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        ["ref.xyz", "cmp.xyz", "o.csv"] + [f"p_{k}.png" for k in FIGURES])


@pytest.mark.slow
def test_grid_mode_report(tmp_path):
    ref, cmp = bumpy_pair(n=40)
    write_xyz(tmp_path / "ref.xyz", ref)
    write_xyz(tmp_path / "cmp.xyz", cmp)
    assert main(["compare", str(tmp_path / "ref.xyz"), str(tmp_path / "cmp.xyz"), "-o", str(tmp_path / "g.csv"),
                 "--grid", "0.2", "--max-depth", "0.5", "--quiet", "--report", str(tmp_path / "g.html")]) == 0
    text = (tmp_path / "g.html").read_text()
    assert "Raster of" in text and "normals imposed (vertical)" not in text  # the latter is in a PNG, not text
    assert len(re.findall(r'<img[^>]*src="data:image/png;base64,', text)) == len(FIGURES)
    assert (tmp_path / "g_distance.tif").exists()


def test_unwritable_report_leaves_no_output(tmp_path):
    ref, cmp = bumpy_pair(n=20)
    write_xyz(tmp_path / "ref.xyz", ref)
    write_xyz(tmp_path / "cmp.xyz", cmp)
    code = main(["compare", str(tmp_path / "ref.xyz"), str(tmp_path / "cmp.xyz"), "-o", str(tmp_path / "o.csv"),
                 "--report", str(tmp_path / "missing" / "r.html")] + OPTS)
    assert code == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cmp.xyz", "ref.xyz"]


def fake_result(n, seed=1):
    """A Result with the engine's layout, without running the engine (for speed tests)."""
    rng = np.random.default_rng(seed)
    core = np.column_stack([rng.uniform(0, 1000, n), rng.uniform(0, 600, n), rng.normal(0, 1, n)])
    d = 0.5 * np.sin(core[:, 0] / 80) * np.cos(core[:, 1] / 60) ** 3 + rng.normal(0, 0.02, n)
    lod = np.abs(rng.normal(0.05, 0.02, n)) + 0.01
    status = np.where(rng.random(n) < 0.05, 4, 0).astype(np.uint8)
    d[status == 4] = np.nan
    lod[status == 4] = np.nan
    n1 = rng.integers(4, 50, n).astype(np.uint32)
    scale = rng.choice([1.0, 2.0, 4.0], n)
    return Result(core=core, distance=d, lod=lod, significant=np.abs(d) > lod,
                  p_value=np.where(np.isnan(lod), np.nan, np.where(np.abs(d) > lod, 0.01, 0.5)), n1=n1, n2=n1, sigma1=lod, sigma2=lod,
                  i1=np.zeros(n), i2=d, normal=np.tile([0, 0, 1.0], (n, 1)), normal_scale=scale,
                  roughness=scale / np.exp(rng.normal(3.3, 0.5, n)), status=status,
                  params={"normal_scale": [1.0, 2.0, 4.0], "projection_scale": 1.0, "max_depth": 2.0})


@pytest.mark.slow
def test_large_clouds_are_subsampled_with_a_fixed_seed():
    r = fake_result(5000)
    rep = build_report(r, max_points=1000)
    caption = dict((k, c) for k, _, _, c in rep.figures)["distance"]
    assert "1,000 of 5,000 core points plotted" in caption and "seed 0" in caption
    again = build_report(r, max_points=1000)
    assert [f[2] for f in rep.figures[:3]] == [f[2] for f in again.figures[:3]]  # same subsample, same pixels


@pytest.mark.slow
def test_one_million_core_points_is_fast():
    r = fake_result(1_000_000)
    build_report(fake_result(100))  # imports and font cache
    t = time.perf_counter()
    html = render_html(build_report(r))
    elapsed = time.perf_counter() - t
    assert elapsed < 60, elapsed
    assert len(html) < 10_000_000


def _chromium():
    return shutil.which("chromium") or shutil.which("chromium-browser") or shutil.which("google-chrome")


@pytest.mark.slow
@pytest.mark.skipif(_chromium() is None, reason="no headless browser (Debian: apt-get install -y chromium)")
def test_renders_in_a_headless_browser(report_run, tmp_path):
    from matplotlib.image import imread
    shot = tmp_path / "shot.png"
    html = (report_run / "report.html").resolve()
    proc = subprocess.run([_chromium(), "--headless", "--disable-gpu", "--no-sandbox", f"--screenshot={shot}",
                           "--window-size=1200,2000", "--hide-scrollbars", f"file://{html}"],
                          capture_output=True, timeout=180)
    assert shot.exists(), proc.stderr.decode(errors="replace")[-2000:]
    img = imread(shot)[..., :3]
    assert img.shape[:2] == (2000, 1200)
    r, g, b = img[..., 0], img[..., 1], img[..., 2]
    reddish = np.sum((r > 0.6) & (g < 0.45) & (b < 0.45))
    bluish = np.sum((b > 0.5) & (r < 0.35))
    assert reddish > 500 and bluish > 500, (reddish, bluish)  # the distance map is drawn, both signs


# ------------------------------------------------------- --uncertainty pm|ep section (issue 16)

@pytest.mark.slow
def test_an_eq1_run_has_no_uncertainty_section(report_run):
    text = (report_run / "report.html").read_text(encoding="utf-8")
    assert 'id="uncertainty"' not in text and build_report(fake_result(50), view3d=False).uncertainty is None


@pytest.mark.slow
def test_the_uncertainty_section_gives_the_model_its_inputs_and_the_spreads():
    from dataclasses import replace
    r = fake_result(400, seed=3)
    rng = np.random.default_rng(7)
    spread1, spread2 = rng.uniform(0.001, 0.01, 400), rng.uniform(0.002, 0.02, 400)
    spread2[:10] = np.nan  # core points without a LOD: not counted
    r = replace(r, spread1=spread1, spread2=spread2,
                params=dict(r.params, uncertainty="pm", precision_fields="px,py,pz", precision_scales=[2.0, 0.5]))
    section = build_report(r, view3d=False).uncertainty
    assert section.model.startswith("M3C2-PM")
    inputs = dict(section.inputs)
    assert inputs["precision fields (sx, sy, sz)"] == "px,py,pz"
    assert inputs["precision scales (reference, compared)"] == "2, 0.5"
    assert inputs["precision rule"] == "nearest"  # not given: the default the run used
    rows = {row[0]: row for row in section.distribution}
    assert rows["spread1 (reference)"][1] == "400" and rows["spread2 (compared)"][1] == "390"
    assert float(rows["spread1 (reference)"][4]) == pytest.approx(np.median(spread1), rel=1e-5)
    assert float(rows["spread2 (compared)"][6]) == pytest.approx(np.nanmax(spread2), rel=1e-5)
    lod = r.lod[np.isfinite(r.lod)]
    assert rows["LOD"][1] == str(lod.size) and float(rows["LOD"][3]) == pytest.approx(np.quantile(lod, 0.05), rel=1e-5)
    page = render_html(build_report(r, view3d=False))
    assert '<h2 id="uncertainty">Uncertainty model</h2>' in page and "px,py,pz" in page


@pytest.mark.slow
def test_the_ep_section_names_every_input_and_what_was_absent():
    from dataclasses import replace
    r = fake_result(100, seed=4)
    r = replace(r, spread1=np.full(100, 0.01), spread2=np.full(100, 0.02),
                params=dict(r.params, uncertainty="ep", scan_positions="sps.json", scan_position_field="scan",
                            transform="tfM.csv", reduction_point="1,2,0"))
    section = build_report(r, view3d=False).uncertainty
    inputs = dict(section.inputs)
    assert section.model.startswith("M3C2-EP")
    assert inputs["scan positions (reference[, compared])"] == "sps.json"
    assert inputs["scan-position id field"] == "scan"
    assert inputs["transformation tfM (compared epoch)"] == "tfM.csv"
    assert inputs["transformation already applied"] == "no"
    assert inputs["alignment covariance Cxx (12 x 12)"] == "none (no alignment uncertainty)"
    assert inputs["reduction point"] == "1,2,0"
    assert {"covariance of a centre of gravity", "weights of the centres of gravity", "level of detection"} <= set(inputs)
