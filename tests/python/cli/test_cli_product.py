"""Command-line habits and options of issue 13: --version, --orient -z, m3c2 info (--json),
--crs / --allow-angular / a CRS on one cloud only, --field-names / --float64, the normals
summary, and the warnings on stderr (Toronto's shoreline)."""
from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

import m3c2kit
from m3c2kit.cli.main import main, make_parser
from m3c2kit.io import Cloud, write_cloud_table
from m3c2kit.io.crs import assign_crs

REPO = Path(__file__).resolve().parents[3]
TORONTO = REPO / "data" / "toronto-ttp"
BASE = ["--normal-scale", "2", "--projection-scale", "1", "--max-depth", "1", "--quiet"]


def _pair(d: Path):
    rng = np.random.default_rng(2)
    xy = rng.uniform(0, 20, (3000, 2)) + [630000, 4830000]
    ref = np.column_stack([xy, 0.01 * rng.standard_normal(3000)])
    cmp_ = np.column_stack([xy[::-1], 0.1 + 0.01 * rng.standard_normal(3000)])
    np.savetxt(d / "ref.xyz", ref, fmt="%.4f")
    np.savetxt(d / "cmp.xyz", cmp_, fmt="%.4f")
    return d / "ref.xyz", d / "cmp.xyz"


def test_version(capsys):
    # answered before any parser is built (issue 45); within other words, argparse's action answers
    assert main(["--version"]) == 0 and capsys.readouterr().out.strip() == f"m3c2 (m3c2kit) {m3c2kit.__version__}"
    with pytest.raises(SystemExit) as e:
        main(["--version", "--version"])
    assert e.value.code == 0 and capsys.readouterr().out.strip() == f"m3c2 (m3c2kit) {m3c2kit.__version__}"


def test_orient_minus_z_as_help_writes_it(tmp_path):
    ref, cmp_ = _pair(tmp_path)
    assert make_parser().parse_args(["compare", "r", "c", "--orient", "-z", "-o", "x"]).orient == "-z"
    assert main(["compare", ref, cmp_, "-o", tmp_path / "a.csv", "--orient", "-z", *BASE]) == 0
    assert main(["compare", ref, cmp_, "-o", tmp_path / "b.csv", "--orient=-z", *BASE]) == 0
    assert main(["compare", ref, cmp_, "-o", tmp_path / "c.csv", *BASE]) == 0
    a, b, c = (np.genfromtxt(tmp_path / f"{k}.csv", delimiter=",", names=True) for k in "abc")
    np.testing.assert_array_equal(a["distance"], b["distance"])
    np.testing.assert_allclose(a["distance"], -c["distance"], atol=1e-6)  # normals flipped
    assert np.nanmedian(c["distance"]) == pytest.approx(0.1, abs=0.01)


def test_crs_assignment_info_json_and_field_names(tmp_path, capsys):
    ref, cmp_ = _pair(tmp_path)
    out = tmp_path / "o.laz"
    assert main(["compare", ref, cmp_, "-o", out, "--crs", "EPSG:32617", "--field-names", "cloudcompare",
                 *BASE]) == 0
    back = m3c2kit.read(out)
    # LAS: the distance as an integer count of 0.1 mm, read back as float64 (m3c2kit.io.quantised)
    assert "M3C2 distance" in back.fields and back.fields["M3C2 distance"].dtype == np.float64
    capsys.readouterr()
    assert main(["info", out, "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["crs"]["epsg"] == 32617 and d["crs"]["name"] == "WGS 84 / UTM zone 17N" and d["point_count"] == len(back)
    assert main(["info", out]) == 0
    text = capsys.readouterr().out
    assert "CRS:     WGS 84 / UTM zone 17N (EPSG:32617)" in text and "PROJCRS" not in text and "{'" not in text
    assert main(["compare", ref, cmp_, "-o", tmp_path / "w.laz", "--float64", *BASE]) == 0
    assert m3c2kit.read(tmp_path / "w.laz").fields["distance"].dtype == np.float64
    # --crs on a file that has another CRS is refused.
    las = tmp_path / "ref26917.las"
    write_cloud_table(las, np.loadtxt(ref), {}, like=Cloud(np.zeros((1, 3)), crs=assign_crs("EPSG:26917")))
    capsys.readouterr()
    assert main(["compare", las, cmp_, "-o", tmp_path / "x.csv", "--crs", "EPSG:32617", *BASE]) == 1
    assert "already has a CRS" in capsys.readouterr().err


def test_one_crs_only_and_angular_units(tmp_path, capsys):
    ref, cmp_ = _pair(tmp_path)
    las = tmp_path / "ref.las"
    write_cloud_table(las, np.loadtxt(ref), {}, like=Cloud(np.zeros((1, 3)), crs=assign_crs("EPSG:32617")))
    assert main(["compare", las, cmp_, "-o", tmp_path / "a.csv", *BASE]) == 1
    err = capsys.readouterr().err
    assert "only one cloud has a CRS" in err and str(cmp_) in err
    assert main(["compare", las, cmp_, "-o", tmp_path / "a.csv", "--ignore-crs", *BASE]) == 0
    assert main(["compare", las, cmp_, "-o", tmp_path / "b.csv", "--crs", "EPSG:32617", *BASE]) == 0
    geo = np.loadtxt(ref) * [1e-5, 1e-5, 1] + [-79.0 - 6.3, 43.0, 0]
    for name, xyz in (("g1.las", geo), ("g2.las", geo + [0, 0, 0.1])):
        write_cloud_table(tmp_path / name, xyz, {}, like=Cloud(np.zeros((1, 3)), crs=assign_crs("EPSG:4326"),
                                                             scale=(1e-7, 1e-7, 0.001), offset=(0, 0, 0)))
    capsys.readouterr()
    argv = ["compare", tmp_path / "g1.las", tmp_path / "g2.las", "-o", tmp_path / "g.csv",
            "--normal-scale", "0.0002", "--projection-scale", "0.0001", "--max-depth", "1", "--quiet"]
    assert main(argv) == 1 and "angular coordinates" in capsys.readouterr().err
    assert main(argv + ["--allow-angular"]) == 0


def test_normals_prints_a_summary(tmp_path, capsys):
    ref, _ = _pair(tmp_path)
    assert main(["normals", ref, "-o", tmp_path / "n.csv", "--normal-scale", "2"]) == 0
    captured = capsys.readouterr()
    line = captured.out.strip().splitlines()[-1]
    assert line.startswith(f"wrote {tmp_path / 'n.csv'}: normals at 3,000 of 3,000 points (100.0 %); median roughness ")
    assert line.endswith("columns nx, ny, nz, normal_scale, roughness, count, status")
    assert captured.err == ""  # not a terminal: no progress bar


def test_normals_progress_covers_every_phase(tmp_path, capsys):
    ref, _ = _pair(tmp_path)
    assert main(["normals", ref, "-o", tmp_path / "n.csv", "--normal-scale", "2", "--progress"]) == 0
    err = capsys.readouterr().err
    for phase in ("reading", "indexing, normals", "writing"):
        assert f"{phase}:" in err
    # -q shows no bar: --progress with it would change nothing, refused (docs/errors.md, issue 31)
    assert main(["normals", ref, "-o", tmp_path / "q.csv", "--normal-scale", "2", "--progress", "-q"]) == 2
    assert "--progress would change nothing" in capsys.readouterr().err


def test_toronto_no_overlap_warning_never_advises_depth(tmp_path, capsys):
    for depth in ("20", "100"):
        assert main(["compare", TORONTO / "TTP_15.laz", TORONTO / "TTP_23.laz", "-o", tmp_path / "t.laz",
                     "--core-spacing", "8", "--normal-scale", "10", "--projection-scale", "5", "--max-depth", depth,
                     "--quiet"]) == 0
        captured = capsys.readouterr()
        assert captured.out == ""
        assert "the surveys do not overlap there" in captured.err and "cannot help" in captured.err
        assert "consider a larger --max-depth" not in captured.err


def test_progress_over_every_phase_when_forced(tmp_path, capsys):
    ref, cmp_ = _pair(tmp_path)
    args = ["compare", ref, cmp_, "-o", tmp_path / "p.csv", "--normal-scale", "2", "--projection-scale", "1",
            "--max-depth", "1"]
    assert main(args) == 0
    assert "reading" not in capsys.readouterr().err  # stderr is not a terminal here: no bars
    assert main(args + ["--progress"]) == 0
    err = capsys.readouterr().err
    for phase in ("reading", "indexing, normals, distances", "writing"):
        assert phase in err, phase
    assert "3000/3000" in err  # the engine's core points done


def test_progress_json_is_one_line_per_update_and_monotone(tmp_path, capsys, monkeypatch):
    """`--progress json` (issue 44: what the QGIS runner reads): valid JSON lines only, every phase,
    the run's percent never going back, from 0 to 100; the engine's updates reach it."""
    import json

    from m3c2kit.base import phases
    monkeypatch.setattr(phases.Phases.__init__, "__defaults__", (None, None, 0.0, False))  # no throttle: every update
    ref, cmp_ = _pair(tmp_path)
    assert main(["compare", ref, cmp_, "-o", tmp_path / "p.csv", "--normal-scale", "2", "--projection-scale", "1",
                 "--max-depth", "1", "--progress", "json"]) == 0
    lines = [json.loads(line) for line in capsys.readouterr().err.splitlines()]
    assert {line["phase"] for line in lines} == {"reading", "indexing, normals, distances", "writing"}
    percents = [line["percent"] for line in lines]
    assert percents == sorted(percents) and percents[0] == 0.0 and percents[-1] == 100.0
    compute = [line for line in lines if line["phase"] == "indexing, normals, distances"]
    assert len({line["done"] for line in compute}) >= 3 and compute[-1]["done"] == compute[-1]["total"] == 3000


def test_verbose_says_where_the_time_went(tmp_path, capsys):
    """Issue 45: one line of each phase's wall time under --verbose, in the order they ran."""
    ref, cmp_ = _pair(tmp_path)
    assert main(["compare", ref, cmp_, "-o", tmp_path / "p.csv", "--normal-scale", "2", "--projection-scale", "1",
                 "--max-depth", "1", "--verbose"]) == 0
    line = [x for x in capsys.readouterr().out.splitlines() if x.startswith("time: ")]
    assert len(line) == 1 and re.fullmatch(r"time: reading [0-9.]+ s; indexing, normals, distances [0-9.]+ s; "
                                           r"writing [0-9.]+ s", line[0]), line
