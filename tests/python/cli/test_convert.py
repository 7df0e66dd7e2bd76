"""`m3c2 convert`: every field and the CRS kept, float64 exact in text, never over its input."""
from pathlib import Path

import numpy as np
import pytest

import m3c2kit
from m3c2kit.cli.main import main

DATA = Path(__file__).resolve().parents[2] / "data" / "pairs" / "autzen-bmx"
LAS = DATA / "autzen-bmx-2010.las"


def test_las_to_csv_keeps_every_field_exactly(tmp_path):
    out = tmp_path / "copy.csv"
    assert main(["convert", str(LAS), "-o", str(out)]) == 0
    original, copy = m3c2kit.read(LAS), m3c2kit.read(out)
    assert np.array_equal(original.xyz, copy.xyz)
    assert list(copy.fields) == list(original.fields)
    for name, values in original.fields.items():
        assert np.array_equal(np.asarray(values, dtype=np.float64), np.asarray(copy.fields[name], dtype=np.float64)), name


def test_las_to_laz_keeps_the_crs(tmp_path):
    out = tmp_path / "copy.laz"
    assert main(["convert", str(LAS), "-o", str(out)]) == 0
    assert m3c2kit.read(out).crs == m3c2kit.read(LAS).crs is not None


def test_never_writes_over_its_input(tmp_path, capsys):
    copy = tmp_path / "copy.csv"
    assert main(["convert", str(LAS), "-o", str(copy)]) == 0
    before = copy.read_bytes()
    assert main(["convert", str(copy), "-o", str(copy)]) != 0
    assert "would destroy the input" in capsys.readouterr().err
    assert copy.read_bytes() == before


def test_a_missing_input_names_the_file_and_writes_nothing(tmp_path, capsys):
    out = tmp_path / "copy.csv"
    assert main(["convert", str(tmp_path / "absent.laz"), "-o", str(out)]) != 0
    assert "absent.laz" in capsys.readouterr().err
    assert not out.exists()


def test_a_crs_dropping_conversion_says_so(tmp_path, capsys):
    """Issue 42: LAS -> CSV/TXT/PLY dropped the CRS silently."""
    for ext in (".csv", ".txt", ".ply"):
        assert main(["convert", str(LAS), "-o", str(tmp_path / f"copy{ext}")]) == 0
        err = capsys.readouterr().err
        assert f"copy{ext}: {ext} stores no CRS" in err and "write .las or .laz to keep it" in err
        assert err.count("\n") == 1  # one line
    assert main(["convert", str(LAS), "-o", str(tmp_path / "copy.laz")]) == 0
    assert "stores no CRS" not in capsys.readouterr().err


@pytest.mark.parametrize("ext", [".las", ".laz"])
def test_coordinates_las_cannot_hold_are_refused_not_moved(ext, tmp_path, capsys):
    """Issue 42: `convert` to LAS wrote points at +-1e300 at a scale of 1e291: every other point
    moved to 0, without a word. Text keeps them."""
    src = tmp_path / "far.xyz"
    np.savetxt(src, np.array([[0.0, 0.0, 0.0], [1e300, 0.0, 0.0], [1.0, 1.0, 1.0]]))
    out = tmp_path / f"far{ext}"
    assert main(["convert", str(src), "-o", str(out)]) == 1
    err = capsys.readouterr().err
    assert "LAS cannot store these coordinates" in err and "write .ply, .csv or .txt" in err and not out.exists()
    assert main(["convert", str(src), "-o", str(tmp_path / "far.csv"), "-q"]) == 0
    assert np.array_equal(m3c2kit.read(tmp_path / "far.csv").xyz, np.loadtxt(src))


@pytest.mark.parametrize("name, words", [("out", "has no extension to name its format"),
                                         ("out.xls", "cannot write '.xls' files")])
def test_an_output_format_it_cannot_write_is_refused_before_the_input_is_read(tmp_path, capsys, name, words):
    """Hostile round 2: `convert IN.las -o out` read the whole input, warned that the format stores
    no CRS, then failed with "cannot write '' files"."""
    from m3c2kit.cli.main import main
    las = Path(__file__).resolve().parents[2] / "data" / "pairs" / "autzen-bmx" / "autzen-bmx-2010.las"
    assert main(["convert", str(las), "-o", str(tmp_path / name)]) == 1
    err = capsys.readouterr().err
    assert err == f"m3c2: error: {tmp_path / name}: {words} (supported: .las .laz .ply .csv .txt .xyz .asc)\n", err
    assert list(tmp_path.iterdir()) == []

