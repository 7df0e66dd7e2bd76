"""`m3c2 compare REFERENCE COMPARED -o OUTPUT` alone (issue 44): D, d and the max depth not given
are chosen by `m3c2 suggest`'s rules, printed with their reasons, and the run is the run with
those values given; `--auto-scales` chooses them all and refuses a given one; a tiled run, which
never holds the clouds whole, asks for them."""
from __future__ import annotations

import re

import pytest

from m3c2kit.cli.main import main

CHOSEN = re.compile(r"^m3c2: scales chosen from the data by m3c2 suggest's rules \(\d+ sampled core points, point "
                    r"spacing [0-9.e+-]+\): (?P<options>.*)$", re.M)


def _chosen(out: str) -> list[str]:
    found = CHOSEN.search(out)
    assert found, out
    return found["options"].split()


@pytest.mark.slow
def test_only_the_two_clouds_and_an_output(autzen_pair, tmp_path, capsys):
    ref, cmp_ = autzen_pair / "autzen-bmx-2010.las", autzen_pair / "autzen-bmx-2023.las"
    assert main(["compare", str(ref), str(cmp_), "-o", str(tmp_path / "auto.csv")]) == 0
    out = capsys.readouterr().out
    options = _chosen(out)
    assert options[0::2] == ["--normal-scale", "--projection-scale", "--max-depth"], options
    for flag in options[0::2]:  # each with its reason, on its own line
        assert re.search(rf"^m3c2:   {flag} [0-9.:]+: \S", out, re.M), out
    # The same bytes as the run given those values.
    assert main(["compare", str(ref), str(cmp_), "-o", str(tmp_path / "given.csv"), *options, "-q"]) == 0
    assert (tmp_path / "auto.csv").read_bytes() == (tmp_path / "given.csv").read_bytes()
    # Only the missing ones are chosen; -q says nothing.
    assert main(["compare", str(ref), str(cmp_), "-o", str(tmp_path / "part.csv"), "--normal-scale", "8"]) == 0
    assert _chosen(capsys.readouterr().out)[0::2] == ["--projection-scale", "--max-depth"]
    assert main(["compare", str(ref), str(cmp_), "-o", str(tmp_path / "quiet.csv"), "-q"]) == 0
    assert capsys.readouterr().out == ""
    assert (tmp_path / "quiet.csv").read_bytes() == (tmp_path / "auto.csv").read_bytes()


def test_auto_scales_refuses_a_given_scale_and_a_tiled_run_asks_for_them(pair, capsys):
    base = ["compare", str(pair / "ref.xyz"), str(pair / "cmp.xyz"), "-o", str(pair / "out.csv")]
    assert main([*base, "--auto-scales", "--max-depth", "1"]) == 2
    assert capsys.readouterr().err == ("m3c2: error: --auto-scales chooses --max-depth from the data: give one or "
                                       "the other\n")
    assert main([*base, "--tile-size", "1", "--normal-scale", "0.5"]) == 2
    assert capsys.readouterr().err == ("m3c2: error: a tiled run needs its scales given (--projection-scale, "
                                       "--max-depth missing): 'm3c2 suggest' on the clouds or a crop of them proposes "
                                       "them\n")
    assert not (pair / "out.csv").exists()


def test_vertical_normals_need_no_normal_scale(pair, capsys):
    base = ["compare", str(pair / "ref.xyz"), str(pair / "cmp.xyz"), "-o", str(pair / "out.csv")]
    assert main([*base, "--normal-source", "vertical"]) == 0
    assert _chosen(capsys.readouterr().out)[0::2] == ["--projection-scale", "--max-depth"]


def test_another_parameter_is_checked_before_any_file_is_read(pair, capsys):
    assert main(["compare", str(pair / "missing.xyz"), str(pair / "cmp.xyz"), "-o", str(pair / "out.csv"),
                 "--min-points", "0"]) == 2
    assert "--min-points" in capsys.readouterr().err


def test_with_an_error_model_d_is_the_models(pair, capsys):
    """--error-model applies only at the d it was fitted at: that d, not the rules' (the placeholder
    d of the early checks made the run refuse its own model)."""
    from m3c2kit.analysis.error_model import Component, ErrorModel, save
    save(pair / "m.json", ErrorModel(1e-6, (Component("spherical", 1e-6, 1.0),), 0.3, "3d", "test", mean_u2=1e-6))
    assert main(["compare", str(pair / "ref.xyz"), str(pair / "cmp.xyz"), "-o", str(pair / "out.csv"), "--error-model",
                 str(pair / "m.json"), "--verbose"]) == 0
    out = capsys.readouterr().out
    assert _chosen(out)[0::2] == ["--normal-scale", "--max-depth"] and "parameter projection_scale: 0.3" in out


def test_too_few_points_to_choose_says_which_options_to_give(pair, capsys):
    (pair / "few.xyz").write_text("0 0 0\n1 0 0\n0 1 0\n")
    assert main(["compare", str(pair / "few.xyz"), str(pair / "cmp.xyz"), "-o", str(pair / "out.csv")]) == 1
    assert capsys.readouterr().err == (f"m3c2: error: {pair / 'few.xyz'}: 3 points; suggest needs at least 10 (sigma(D) "
                                       "is fitted to 10 neighbours, section 5.1); the scales cannot be chosen from the "
                                       "data: give --normal-scale, --projection-scale, --max-depth\n")
