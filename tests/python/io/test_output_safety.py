"""Issue 15, point 1: no output of a run may be, hard-link to or be reached through a symlink to
any of its inputs; a read-only existing output is refused, not replaced. Checked before any work:
the exit status is 2 and every input is left byte-identical."""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from m3c2kit.cli.main import main
from m3c2kit.io import Cloud, write_cloud_table
from synthetic import noisy_plane_pair

PARAMS = ["--normal-scale", "0.3", "--projection-scale", "0.2", "--max-depth", "0.5"]


@pytest.fixture
def pair(tmp_path):
    ref, cmp = noisy_plane_pair(n=20)
    like = Cloud(ref[:1], scale=(0.001,) * 3, offset=(0.0,) * 3)
    write_cloud_table(tmp_path / "ref.las", ref, {}, like=like)
    write_cloud_table(tmp_path / "cmp.las", cmp, {}, like=like)
    return tmp_path


def _refused(capsys, *argv, protected) -> str:
    before = {p: Path(p).read_bytes() for p in protected}
    code = main([str(a) for a in argv])
    err = capsys.readouterr().err
    assert code == 2, err
    for p, data in before.items():
        assert Path(p).read_bytes() == data, f"{p} was changed"
    return err


@pytest.mark.parametrize("how", ["same", "hardlink", "symlink"])
def test_output_equal_to_the_reference_is_refused(pair, capsys, how):
    ref = pair / "ref.las"
    out = ref
    if how == "hardlink":
        out = pair / "link.las"
        os.link(ref, out)
    elif how == "symlink":
        out = pair / "sym.las"
        out.symlink_to(ref)
    err = _refused(capsys, "compare", ref, pair / "cmp.las", "-o", out, *PARAMS, protected=[ref])
    assert f"-o '{out}' is the reference cloud '{ref}'" in err


def test_report_over_the_compared_cloud_is_refused(pair, capsys):
    err = _refused(capsys, "compare", pair / "ref.las", pair / "cmp.las", "-o", pair / "out.las", "--report",
                   pair / "cmp.las", *PARAMS, protected=[pair / "cmp.las"])
    assert "--report" in err and "compared cloud" in err
    assert not (pair / "out.las").exists()


def test_subsample_and_normals_in_place_are_refused(pair, capsys):
    ref = pair / "ref.las"
    _refused(capsys, "subsample", ref, "-o", ref, "--spacing", "5", protected=[ref])
    _refused(capsys, "normals", ref, "-o", ref, "--normal-scale", "0.3", protected=[ref])


def test_a_read_only_output_is_refused_not_replaced(pair, capsys):
    out = pair / "out.las"
    out.write_bytes(b"older result")
    out.chmod(0o444)
    err = _refused(capsys, "compare", pair / "ref.las", pair / "cmp.las", "-o", out, *PARAMS, protected=[out])
    assert "read-only" in err
    out.chmod(0o644)
    assert main([str(a) for a in ("compare", pair / "ref.las", pair / "cmp.las", "-o", out, *PARAMS, "-q")]) == 0
    assert out.read_bytes() != b"older result" and np.isfinite(out.stat().st_size)


# ------------------------------------------------- every other subcommand that writes (issue 12)

def _analysis_cases(d: Path):
    ref, cmp = d / "ref.las", d / "cmp.las"
    clf = d / "classifier.json"
    return {
        "roughness -o": (["roughness", ref, "--normal-scale", "0.2,0.4", "-o", ref], ref, "-o", "input cloud"),
        "roughness --plot": (["roughness", ref, "--normal-scale", "0.2,0.4", "-o", d / "r.csv", "--plot", ref], ref,
                             "--plot", "input cloud"),
        "roughness --core": (["roughness", ref, "--core", cmp, "--normal-scale", "0.2,0.4", "-o", cmp], cmp, "-o",
                             "core points file"),
        "calibrate -o": (["calibrate", ref, "--projection-scales", "0.2", "-o", ref], ref, "-o", "input cloud"),
        "calibrate --plot": (["calibrate", ref, "--projection-scales", "0.2", "-o", d / "c.csv", "--plot", ref], ref,
                             "--plot", "input cloud"),
        "c2c -o reference": (["c2c", ref, cmp, "-o", ref], ref, "-o", "reference cloud"),
        "c2c -o compared": (["c2c", ref, cmp, "-o", cmp], cmp, "-o", "compared cloud"),
        "simplify -o": (["simplify", ref, "--projection-scale", "0.2", "-o", ref], ref, "-o", "input cloud"),
        "simplify --orient": (["simplify", ref, "--projection-scale", "0.2", "--orient", cmp, "-o", cmp], cmp, "-o",
                              "orientation file"),
        "classify train -o": (["classify", "train", f"{ref}=ground", f"{cmp}=rock", "-o", ref], ref, "-o",
                              f"sample {ref}=ground"),
        "classify train --plot": (["classify", "train", f"{ref}=ground", f"{cmp}=rock", "-o", clf, "--plot", cmp],
                                  cmp, "--plot", f"sample {cmp}=rock"),
        "classify apply -o cloud": (["classify", "apply", ref, "--classifier", clf, "-o", ref], ref, "-o",
                                    "input cloud"),
        "classify apply -o classifier": (["classify", "apply", ref, "--classifier", clf, "-o", clf], clf, "-o",
                                         "classifier file"),
    }


@pytest.mark.parametrize("case", list(_analysis_cases(Path("."))))
def test_every_writing_subcommand_refuses_an_output_that_is_an_input(pair, capsys, case):
    (pair / "classifier.json").write_text("{}\n")  # never read: the check comes first
    argv, victim, option, label = _analysis_cases(pair)[case]
    err = _refused(capsys, *argv, protected=[pair / "ref.las", pair / "cmp.las", pair / "classifier.json"])
    assert f"{option} '{victim}' is the {label} '" in err and "would destroy the input" in err


def test_a_hard_link_to_an_analysis_input_is_refused(pair, capsys):
    link = pair / "link.las"
    os.link(pair / "ref.las", link)
    err = _refused(capsys, "c2c", pair / "ref.las", pair / "cmp.las", "-o", link, protected=[pair / "ref.las"])
    assert f"-o '{link}' is the reference cloud '{pair / 'ref.las'}'" in err



def _series_cases(d: Path):
    ref, cmp = d / "ref.las", d / "cmp.las"
    store, archive, table = d / "store.zarr", d / "analysis.zip", d / "objects.csv"
    compare = ["--normal-scale", "0.3", "--projection-scale", "0.2", "--max-depth", "0.5"]
    return {
        "series -o reference": (["series", ref, cmp, "-o", ref, *compare], ref, "-o", "reference cloud"),
        "series -o epoch": (["series", ref, cmp, "-o", cmp, *compare], cmp, "-o", f"epoch {cmp}"),
        "series import -o archive": (["series", "import", archive, "-o", archive], archive, "-o", "archive"),
        "series report -o objects": (["series", "report", store, "-o", table, "--objects", table], table, "-o",
                                     "objects table"),
    }


@pytest.mark.parametrize("case", list(_series_cases(Path("."))))
def test_the_series_subcommands_refuse_an_output_that_is_an_input(pair, capsys, case):
    # Checked before the series extra (xarray, zarr) is needed: it refuses without it too.
    (pair / "store.zarr").mkdir()
    (pair / "analysis.zip").write_bytes(b"PK\x05\x06" + bytes(18))  # never read: the check comes first
    (pair / "objects.csv").write_text("object\n")
    argv, victim, option, label = _series_cases(pair)[case]
    err = _refused(capsys, *argv, protected=[pair / "ref.las", pair / "cmp.las", pair / "analysis.zip",
                                             pair / "objects.csv"])
    assert f"{option} '{victim}' is the {label} '" in err, err
