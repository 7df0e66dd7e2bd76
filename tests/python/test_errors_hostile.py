"""docs/errors.md, issue 15 points 6, 10 and 11 (the parts in modules the front end wires in):
`m3c2 suggest` on 2 or 3 points, a parameter-file value of 5,000 digits, lengths that are
denormal floats, non-real coordinate arrays, terminal escapes in what is printed."""
from __future__ import annotations

import datetime

import numpy as np
import pytest

from m3c2kit.analysis.suggest import suggest as suggest_parameters
from m3c2kit.cli import main
from m3c2kit.cloudcompare_params import read_cloudcompare_params
from m3c2kit.errors import M3C2Error, UsageError, printable
from m3c2kit.io.arrays import as_coordinates
from m3c2kit.limits import check_tile_size, usable_length


@pytest.mark.parametrize("n", [1, 2, 3, 4, 9])
def test_suggest_on_a_few_points_is_a_clear_error(tmp_path, capsys, n):
    """It raised IndexError (a traceback) on 2 or 3 points."""
    path = tmp_path / "few.xyz"
    np.savetxt(path, np.random.default_rng(n).uniform(0, 1, (n, 3)))
    assert main(["suggest", str(path), str(path)]) == 1
    assert capsys.readouterr().err == (f"m3c2: error: {path}: {n} points; suggest needs at least 10 "
                                       f"(sigma(D) is fitted to 10 neighbours, section 5.1)\n")


def test_suggest_on_a_line_or_a_sparse_cloud_is_a_clear_error():
    line = np.column_stack([np.arange(50.0), np.zeros(50), np.zeros(50)])
    with pytest.raises(M3C2Error, match=r"the reference cloud: the points span no surface"):
        suggest_parameters(line, line)
    sparse = np.random.default_rng(0).uniform(0, 1000, (12, 3))
    with pytest.raises(M3C2Error, match=r"no candidate D .* holds 10 neighbours"):
        suggest_parameters(sparse, sparse)


@pytest.mark.parametrize("key", ["MinPoints4Stat", "MaxThreadCount", "SearchDepth"])
def test_a_parameter_value_of_5000_digits_is_a_usage_error(tmp_path, key):
    """int() of 5,000 digits raised ValueError (Python's 4300-digit limit): a traceback."""
    path = tmp_path / "params.txt"
    path.write_text(f"[General]\n{key}={'9' * 5000}\n")
    with pytest.raises(UsageError) as err:
        read_cloudcompare_params(path)
    message = str(err.value)
    assert message.startswith(f"{path}: ") and "(5000 characters)" in message and len(message) < 300


@pytest.mark.parametrize("value", [5e-324, 1e-310, "5e-324"])
def test_denormal_lengths_are_refused_naming_the_option(value):
    with pytest.raises(UsageError, match=r"^--tile-size .* is too small to be a length \(below 2.23e-308"):
        usable_length("--tile-size", value)


@pytest.mark.parametrize("value", [0, -1, float("nan"), float("inf"), "1e400", "x", None])
def test_non_lengths_are_refused_naming_the_option(value):
    with pytest.raises(UsageError, match=r"^--grid must be"):
        usable_length("--grid", value)


def test_huge_and_normal_lengths_are_kept():
    assert usable_length("--tile-size", 1e300) == 1e300
    assert usable_length("--tile-size", "2.5") == 2.5


def test_a_tile_much_smaller_than_the_halo_is_refused():
    with pytest.raises(UsageError, match=r"^--tile-size 0.5 is too small for the halo of 30 .* read about 1.46e\+04 "
                                         r"times its own area; use --tile-size 15 or more"):
        check_tile_size(0.5, 30.0)
    check_tile_size(15.0, 30.0)


@pytest.mark.parametrize("values, what", [
    (np.ones((4, 3), dtype=bool), "booleans"),
    (np.ones((4, 3), dtype=complex), "complex numbers"),
    (np.full((4, 3), np.datetime64("2024-01-01")), "datetimes"),
    (np.full((4, 3), np.timedelta64(1, "s")), "timedeltas"),
    (np.full((4, 3), "1.5"), "strings"),
    (np.array([[1, 2, None]] * 4, dtype=object), "Python objects"),
    ([[datetime.date(2024, 1, 1)] * 3], "Python objects"),
])
def test_non_real_coordinate_arrays_are_refused_naming_the_argument(values, what):
    """np.asarray(..., dtype=float64) accepted complex (imaginary part dropped), bool, datetime."""
    with pytest.raises(UsageError, match=rf"^reference must be an \(N, 3\) array of real numbers, got {what}"):
        as_coordinates("reference", values)


def test_real_coordinate_arrays_are_viewed_or_converted():
    a = np.arange(12.0).reshape(4, 3)
    assert as_coordinates("reference", a) is a or np.shares_memory(as_coordinates("reference", a), a)
    np.testing.assert_array_equal(as_coordinates("reference", a.astype(np.int16)), a)
    np.testing.assert_array_equal(as_coordinates("reference", a.astype(np.float32)), a)
    with pytest.raises(UsageError, match=r"got shape \(12,\)"):
        as_coordinates("reference", a.ravel())


@pytest.mark.parametrize("raw, shown", [
    ("ok\tstill ok\nnext line", "ok\tstill ok\nnext line"),
    ("\x1b]0;pwned\x07title", "\\x1b]0;pwned\\x07title"),
    ("\x1b[2J\x1b[31mred", "\\x1b[2J\\x1b[31mred"),
    ("c1 csi \x9b31m", "c1 csi \\x9b31m"),
    ("del\x7f cr\r bs\x08", "del\\x7f cr\\x0d bs\\x08"),
    ("evil\u202etxt.exe", "evil\\u202etxt.exe"),
    ("caf\u00e9 \u6e2c", "caf\u00e9 \u6e2c"),
])
def test_printable_escapes_terminal_controls_and_keeps_text(raw, shown):
    assert printable(raw) == shown
