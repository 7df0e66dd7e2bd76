"""`m3c2 compare --uncertainty pm|ep` end to end (issue 16): the flags of the contract, the
clouds' fields read by the readers, the spread1/spread2 columns, the same numbers as the engine
called directly, the params-file keys, and clear errors naming the missing inputs (tiled and Dask runs: test_run_modes.py)."""
from __future__ import annotations

import csv
import json

import numpy as np
import pytest

import m3c2kit
from m3c2kit.run import uncertainty_inputs as ui
from m3c2kit.cli.main import main
from m3c2kit.base.errors import UsageError
from m3c2kit.io import read_cloud
from m3c2kit.engine.result import COLUMNS

BASE = ["--normal-scale", "1", "--projection-scale", "0.5", "--max-depth", "0.5", "--quiet"]


def write_table(path, columns: dict):
    names = list(columns)
    with open(path, "w") as f:
        f.write(" ".join(names) + "\n")
        for row in zip(*columns.values()):
            f.write(" ".join(repr(float(v)) for v in row) + "\n")


def read_csv(path):
    with open(path) as f:
        rows = list(csv.reader(f))
    return rows[0], {name: np.array([float(r[k]) for r in rows[1:]]) for k, name in enumerate(rows[0])}


@pytest.fixture
def pair(tmp_path):
    rng = np.random.default_rng(4)
    clouds = {}
    for name, dz in (("ref", 0.0), ("cmp", 0.01)):
        xy = rng.uniform(0, 4, (3000, 2))
        xyz = np.column_stack([xy, dz + rng.normal(0, 0.003, 3000)])
        s = rng.uniform(0.002, 0.01, (3000, 3))
        ids = rng.integers(1, 3, 3000)
        write_table(tmp_path / f"{name}.xyz", {"x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2], "px": s[:, 0],
                                               "py": s[:, 1], "pz": s[:, 2], "scan": ids})
        clouds[name] = (xyz, s, ids)
    core = np.column_stack([rng.uniform(1, 3, (40, 2)), np.zeros(40)])
    write_table(tmp_path / "core.xyz", {"x": core[:, 0], "y": core[:, 1], "z": core[:, 2]})
    (tmp_path / "sps.json").write_text(json.dumps({
        "1": {"origin": [-10, 2, 2], "sigma_range": 0.003, "sigma_scan": 0.0003, "sigma_yaw": 0.0003},
        "2": {"origin": [12, 1, 3], "sigma_range": 0.004, "sigma_scan": 0.0002, "sigma_yaw": 0.0004}}))
    np.savetxt(tmp_path / "tfM.csv", np.eye(3, 4) + 1e-4, delimiter=",")
    np.savetxt(tmp_path / "Cxx.csv", np.diag([1e-8] * 9 + [1e-6] * 3), delimiter=",")
    return tmp_path, clouds, core


def test_pm_from_the_command_line(pair):
    d, clouds, core = pair
    out = d / "pm.csv"
    assert main(["compare", str(d / "ref.xyz"), str(d / "cmp.xyz"), "--core", str(d / "core.xyz"), "-o", str(out),
                 *BASE, "--uncertainty", "pm", "--precision-fields", "px,py,pz", "--precision-scales", "2,0.5"]) == 0
    header, cols = read_csv(out)
    assert tuple(header) == COLUMNS + ("spread1", "spread2")
    api = m3c2kit.compare(read_cloud(d / "ref.xyz"), read_cloud(d / "cmp.xyz"), core, normal_scale=1,
                          projection_scale=0.5, max_depth=0.5, uncertainty="pm", precision_fields="px,py,pz",
                          precision_scales="2,0.5")
    np.testing.assert_allclose(cols["spread1"], api.spread1, rtol=1e-6)
    np.testing.assert_allclose(cols["lod"], api.lod, rtol=1e-6)
    np.testing.assert_allclose(api.lod, 1.959963984540054 * np.hypot(api.spread1, api.spread2), rtol=1e-14)


def test_ep_from_the_command_line(pair):
    d, clouds, core = pair
    out = d / "ep.csv"
    flags = ["--uncertainty", "ep", "--scan-positions", str(d / "sps.json"), "--scan-position-field", "scan",
             "--transform", str(d / "tfM.csv"), "--alignment-covariance", str(d / "Cxx.csv"),
             "--reduction-point", "1,2,0"]
    assert main(["compare", str(d / "ref.xyz"), str(d / "cmp.xyz"), "--core", str(d / "core.xyz"), "-o", str(out),
                 *BASE, *flags]) == 0
    header, cols = read_csv(out)
    assert tuple(header) == COLUMNS + ("spread1", "spread2")
    assert np.isfinite(cols["lod"]).all()
    # The same numbers as the engine given the arrays directly.
    table = ui.load_scan_positions(d / "sps.json")
    p = m3c2kit.engine.make_params({"normal_diameters": [1.0], "projection_diameter": 0.5, "max_depth": 0.5,
                                    "uncertainty": "ep", "orientation_direction": [0.0, 0.0, 1.0]})
    raw = ui.compute(clouds["ref"][0], clouds["cmp"][0], core, p, ep=ui.EpInputs(
        table, table, clouds["ref"][2].astype(np.uint32), clouds["cmp"][2].astype(np.uint32),
        np.loadtxt(d / "tfM.csv", delimiter=","), np.loadtxt(d / "Cxx.csv", delimiter=","), np.array([1.0, 2, 0])))
    np.testing.assert_allclose(cols["distance"], raw["distance"], rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(cols["spread2"], raw["spread2"], rtol=1e-6)
    # Without --transform-applied the compared cloud moved: given moved, the flag gives the same.
    moved = d / "moved.xyz"
    xyz, s, ids = clouds["cmp"]
    tfm = np.loadtxt(d / "tfM.csv", delimiter=",")
    m = (xyz - [1, 2, 0]) @ tfm[:, :3].T + tfm[:, 3] + [1, 2, 0]
    write_table(moved, {"x": m[:, 0], "y": m[:, 1], "z": m[:, 2], "scan": ids})
    out2 = d / "ep2.csv"
    assert main(["compare", str(d / "ref.xyz"), str(moved), "--core", str(d / "core.xyz"), "-o", str(out2),
                 *BASE, *flags, "--transform-applied"]) == 0
    np.testing.assert_allclose(read_csv(out2)[1]["lod"], cols["lod"], rtol=1e-6)


@pytest.mark.parametrize("output", ["out.csv", "out.laz", "out.ply"])
def test_an_lod_float32_cannot_hold_is_an_error_not_infinity(pair, output):
    """Issue 42: a 1e300 alignment covariance gave LODs of 1e147, written as inf (float32) with
    numpy's overflow warning and exit 0. Now an error naming the file and the column, nothing
    written; with --float64 the same run stores them."""
    d, _, _ = pair
    np.savetxt(d / "Cxx.csv", np.diag([1e-8] * 9 + [1e-6] * 3) * 1e300, delimiter=",")
    run = ["compare", str(d / "ref.xyz"), str(d / "cmp.xyz"), "--core", str(d / "core.xyz"), "-o", str(d / output),
           *BASE, "--uncertainty", "ep", "--scan-positions", str(d / "sps.json"), "--scan-position-field", "scan",
           "--transform", str(d / "tfM.csv"), "--alignment-covariance", str(d / "Cxx.csv"), "--reduction-point", "1,2,0"]
    assert main(run) == 1
    assert not (d / output).exists()
    assert main([*run, "--float64"]) == 0
    lod = read_cloud(d / output).fields["lod"]
    assert np.isfinite(lod).all() and lod.min() > 1e140


def test_missing_inputs_are_named(pair):
    d, clouds, core = pair
    run = ["compare", str(d / "ref.xyz"), str(d / "cmp.xyz"), "--core", str(d / "core.xyz"), "-o", str(d / "x.csv"),
           *BASE]
    assert main([*run, "--uncertainty", "pm"]) == 2  # no sx, sy, sz fields
    assert main([*run, "--uncertainty", "ep", "--scan-positions", str(d / "sps.json")]) == 2  # no point_source_id
    assert not (d / "x.csv").exists()
    with pytest.raises(UsageError, match="no precision field sx"):
        m3c2kit.compare(read_cloud(d / "ref.xyz"), read_cloud(d / "cmp.xyz"), core, normal_scale=1,
                        projection_scale=0.5, max_depth=0.5, uncertainty="pm")
    with pytest.raises(UsageError, match="not a bare array"):
        m3c2kit.compare(clouds["ref"][0], clouds["cmp"][0], core, normal_scale=1, projection_scale=0.5,
                        max_depth=0.5, uncertainty="pm")


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["pm", "ep"])
def test_the_report_of_a_pm_or_ep_run_has_its_uncertainty_section(pair, kind):
    pytest.importorskip("matplotlib")
    d, clouds, core = pair
    flags = {"pm": ["--uncertainty", "pm", "--precision-fields", "px,py,pz", "--precision-scales", "2,0.5"],
             "ep": ["--uncertainty", "ep", "--scan-positions", str(d / "sps.json"), "--scan-position-field", "scan",
                    "--transform", str(d / "tfM.csv"), "--alignment-covariance", str(d / "Cxx.csv"),
                    "--reduction-point", "1,2,0"]}[kind]
    out, html = d / f"{kind}.csv", d / f"{kind}.html"
    assert main(["compare", str(d / "ref.xyz"), str(d / "cmp.xyz"), "--core", str(d / "core.xyz"), "-o", str(out),
                 "--report", str(html), *BASE, *flags]) == 0
    page = html.read_text(encoding="utf-8")
    _, cols = read_csv(out)
    assert '<h2 id="uncertainty">Uncertainty model</h2>' in page
    assert ("M3C2-PM" if kind == "pm" else "M3C2-EP") in page
    for given in flags[3::2]:
        assert given in page, given  # every input the run was given
    spread1 = cols["spread1"][np.isfinite(cols["spread1"])]
    assert f'<td class="num">{np.median(spread1):.6g}</td>' in page  # median spread1, from the written table


def test_a_transform_moving_the_cloud_beyond_the_index_is_named(pair, capsys):
    """Hostile round 2: a translation of 1e300 was reported as a 300-digit coordinate of the compared
    file, with advice to remove its outliers; the file is fine, --transform moved it."""
    d, _, _ = pair
    far = np.eye(3, 4)
    far[0, 3] = 1e300
    np.savetxt(d / "far.csv", far, delimiter=",")
    assert main(["compare", str(d / "ref.xyz"), str(d / "cmp.xyz"), "--core", str(d / "core.xyz"), "-o",
                 str(d / "o.csv"), *BASE, "--uncertainty", "ep", "--scan-positions", str(d / "sps.json"),
                 "--scan-position-field", "scan", "--transform", str(d / "far.csv")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("m3c2: error: --transform moves the compared cloud to a coordinate (1e+300) beyond +-"), err
    assert err.count("\n") == 1 and not (d / "o.csv").exists()
