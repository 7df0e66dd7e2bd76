"""m3c2 suggest: D from the xi >= 25 rule, d from median n >= 30, max depth from a first pass."""
from __future__ import annotations

import importlib

import numpy as np
import pytest

from m3c2kit.analysis import suggest
from m3c2kit.analysis.synthetic import noisy_plane
from m3c2kit.cli.main import main


@pytest.fixture(scope="module")
def pair():
    ref = noisy_plane(100, 100, 0.1, noise=0.005, seed=1)
    cmp_ = noisy_plane(100, 100, 0.1, noise=0.005, z=0.05, x_shift=0.03, seed=2)
    return ref, cmp_


def test_choices_follow_the_rules(pair):
    res = suggest(*pair, sample=400, seed=0)
    assert res["spacing"] == pytest.approx(0.1, rel=0.1)
    t = res["normal_table"]
    assert t["D"][0] == pytest.approx(3 * res["spacing"])
    np.testing.assert_allclose(t["D"][1:] / t["D"][:-1], np.sqrt(2))
    assert t["D"][-1] <= res["extent"] / 4 * (1 + 1e-9)
    k = int(np.nonzero(t["D"] == res["D"])[0][0])
    assert res["normal_scale"] == res["D"]
    assert t["share_xi_ge_25"][k] >= 0.95 and np.all(t["share_xi_ge_25"][:k] < 0.95)
    p = res["projection_table"]
    assert res["projection_scale"] == p["d"][-1]
    assert p["median_n1"][-1] >= 30 and p["median_n2"][-1] >= 30
    assert np.all(np.minimum(p["median_n1"][:-1], p["median_n2"][:-1]) < 30)
    dep = res["depth"]
    assert dep["max_depth"] == pytest.approx(max(3 * dep["p99"], dep["first_pass_d"] / 2))
    assert 0.05 <= dep["p99"] < 0.08  # the true change is 0.05
    # fixed seed: the same answer twice
    again = suggest(*pair, sample=400, seed=0)
    assert again["D"] == res["D"] and again["depth"]["max_depth"] == dep["max_depth"]


def test_multiscale_fallback_when_no_scale_is_smooth_enough():
    rng = np.random.default_rng(0)
    ref = rng.random((3000, 3)) * [10, 10, 3]  # a thick random slab: xi stays small at every scale
    res = suggest(ref, ref + [0, 0, 0.01], sample=200)
    t = res["normal_table"]
    assert np.all(t["share_xi_ge_25"] < 0.5)
    # MIN:MAX:STEP from the smallest candidate (none reaches 50 %) to the largest, step MIN
    assert res["normal_scale"] == f"{t['D'][0]:.6g}:{t['D'][-1]:.6g}:{t['D'][0]:.6g}"
    assert "multi-scale" in res["normal_rule"]


def test_command_line(pair, tmp_path, capsys):
    np.save(tmp_path / "a.npy", pair[0])
    np.save(tmp_path / "b.npy", pair[1])
    assert main(["suggest", str(tmp_path / "a.npy"), str(tmp_path / "b.npy"), "--sample", "300"]) == 0
    text = capsys.readouterr().out
    for needle in ("share_xi_ge_25", "=> --normal-scale", "=> --max-depth", "median_n1", "=> --projection-scale"):
        assert needle in text


def test_real_pair(autzen_pair, capsys):
    pair = autzen_pair
    assert main(["suggest", str(pair / "autzen-bmx-2010.las"), str(pair / "autzen-bmx-2023.las"), "--sample",
                 "300"]) == 0
    assert "=> --max-depth" in capsys.readouterr().out


S = importlib.import_module("m3c2kit.analysis.suggest")  # the module (the package exports the function)


def test_proposal_is_rounded_and_printed_as_a_command(pair, tmp_path, capsys):
    assert S.round_sig(0.4242640687) == 0.42 and S.round_sig(1234.5) == 1200.0
    assert S.round_sig(0.1501, up=True) == 0.16 and S.round_sig(3.0, up=True) == 3.0
    res = suggest(*pair, sample=400, seed=0)
    p = S.proposal(res, "a.laz", "b.laz")
    for key in ("projection_scale", "max_depth"):
        assert p[key] == S.round_sig(p[key])  # 2 significant digits
    assert p["max_depth"] >= res["depth"]["max_depth"]  # rounded up: the depth never shrinks
    assert p["command"] == (f"m3c2 compare a.laz b.laz -o change.laz --normal-scale {p['normal_scale']} "
                            f"--projection-scale {p['projection_scale']:g} --max-depth {p['max_depth']:g}")
    np.save(tmp_path / "a.npy", pair[0])
    np.save(tmp_path / "b.npy", pair[1])
    assert main(["suggest", str(tmp_path / "a.npy"), str(tmp_path / "b.npy"), "--sample", "400"]) == 0
    out = capsys.readouterr().out.splitlines()
    command = out[out.index("command to run:") + 1].strip()
    assert command.startswith(f"m3c2 compare {tmp_path / 'a.npy'} {tmp_path / 'b.npy'} -o change.laz --normal-scale ")


def test_multiscale_proposal_has_few_round_scales():
    from m3c2kit.settings.parsers import normal_scales
    res = {"normal_scale": "0.3:4.80833:0.3", "projection_scale": 0.4242, "projection_table": {"d": [0.4242]},
           "depth": {"max_depth": 0.1234}}
    p = S.proposal(res)
    assert p["normal_scale"] == "0.3:4.8:0.65"
    assert len(normal_scales(p["normal_scale"])) <= S.MAX_PROPOSED_SCALES
    assert p["projection_scale"] == 0.42 and p["max_depth"] == 0.13
