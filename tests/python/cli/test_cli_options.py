"""Issue 32: every subcommand's shared options declared once (m3c2kit.cli.options), option values
that start with "-" (m3c2kit.cli.parser.ArgumentParser), and no function of the command line or
the analysis toolkit over 12 parameters.

Walks every argparse parser the command line builds, the forms of `m3c2 series` included (they
parse their own words), so that the next option declared twice with two help texts fails here."""
from __future__ import annotations

import argparse
import re
from collections import defaultdict
from pathlib import Path

import numpy as np
import pytest

import m3c2kit
from m3c2kit.base.errors import UsageError
from m3c2kit.cli.main import main
from every_parser import every_parser


PARSERS = dict(every_parser())
OWN_OPTIONS = {"-h", "--help", "--version"}


def _declarations():
    """{option string: {declaration: [where]}}; a declaration is what the user sees of it."""
    found = defaultdict(lambda: defaultdict(list))
    for where, parser in PARSERS.items():
        for action in parser._actions:
            for flag in set(action.option_strings) - OWN_OPTIONS:
                found[flag][_declaration(action)].append(where)
    return found


def _declaration(action) -> tuple:
    # The default is each command's own: a value the formatter shows, or the "(default ...)" the
    # command adds to the shared help (m3c2kit.cli.options.add's default_text).
    shared_help = re.sub(r" \(default\b[^()]*(\([^()]*\)[^()]*)*\)$", "", action.help or "")
    return (shared_help, _type_key(action.type), tuple(action.choices or ()), type(action).__name__,
            tuple(sorted(action.option_strings)))


def _type_key(kind) -> tuple:
    """A type by what it does: its name and the values it closes over (bounds, table row)."""
    if kind is None:
        return ()
    cells = tuple(repr(c.cell_contents) for c in getattr(kind, "__closure__", None) or ())
    return (kind.__module__, kind.__qualname__, cells)


#: Option strings that mean different things in different subcommands, with the number of
#: distinct declarations each has and why. A new subcommand that declares one of these anew, or
#: any other option a second time with its own help or type, fails test_every_shared_option_is_declared_once.
SEVERAL_MEANINGS = {
    "--core": (2, "a core points file; m3c2 series changepoints and report: a core point's index"),
    "--core-spacing": (2, "compare's (the table's) subsamples the reference; the analysis commands their own cloud"),
    "--seed": (2, "the table's bootstrap seed (compare, series); the analysis and classify commands' draws"),
    "--bootstrap": (2, "the table's LOD statistic (implies --lod bootstrap); calibrate's extra column, default 100"),
    "--min-points": (3, "the table's points per cylinder for a LOD (compare, series, calibrate); roughness's "
                        "neighbours for sigma(D); classify train's neighbours of a scale"),
    "--max-depth": (2, "the table's, required by compare; calibrate and simplify default it to d"),
    "--normal-scale": (3, "the table's; roughness's scales, each measured; calibrate's and simplify's D, with "
                          "defaults of their own"),
    "--orient": (2, "the table's (default: the sensor or +z); calibrate's and simplify's (+z)"),
    "--classifier": (2, "compare's vegetation filter (the table's); m3c2 classify apply's input"),
    "--label-field": (2, "classify train reads labels from it; classify apply writes class codes to it"),
    "--model": (2, "c2c's local model (none, plane); m3c2 series kalman's state (velocity, acceleration)"),
    "--confidence": (2, "the table's LOD confidence (compare, series); m3c2 aggregate's intervals (the row's range)"),
    "--error-model": (2, "the table's LOD under correlated errors (compare, series); m3c2 aggregate's intervals"),
    "--lod": (2, "the table's LOD statistic (compare, series); series tam3c2's, without the bootstrap it cannot "
                 "resample (issue 42: its help offered it)"),
}
#: Each command's output is its own.
PER_COMMAND = {"-o", "--output"}


def test_every_subcommand_is_walked():
    for sub in ("compare", "normals", "subsample", "info", "roughness", "calibrate", "c2c", "simplify",
                "suggest", "classify train", "classify apply", "series REFERENCE", "series add", "series objects"):
        assert f"m3c2 {sub}" in PARSERS


def test_every_shared_option_is_declared_once():
    wrong = []
    for flag, declarations in sorted(_declarations().items()):
        if flag in PER_COMMAND:
            continue
        expected = SEVERAL_MEANINGS.get(flag, (1, ""))[0]
        if len(declarations) != expected:
            shown = "\n".join(f"    {where}: {d[0]!r} type {d[1]}" for d, where in declarations.items())
            wrong.append(f"{flag}: {len(declarations)} declarations, {expected} expected:\n{shown}")
    assert not wrong, "\n".join(wrong)


def test_the_shared_options_are_where_the_issue_found_them():
    found = _declarations()
    for flag, least in (("--threads", 13), ("--quiet", 10), ("--drop-nonfinite", 12), ("--seed", 6),
                        ("--plot", 3), ("--fit-range", 2), ("--ignore-crs", 3), ("--core-normals", 2)):
        assert sum(len(w) for w in found[flag].values()) >= least, flag


def _commands_with(flag):
    return [where for where, parser in PARSERS.items() if flag in parser._option_string_actions]


@pytest.mark.parametrize("where", _commands_with("--threads"))
def test_threads_is_the_tables_everywhere(where):
    """One range and one message, that of the parameter table (and of a --params file's value)."""
    parser = PARSERS[where]
    for value, words in (("-1", "got -1"), (str(2**31), "at most 2147483647")):
        with pytest.raises(UsageError, match=rf"^--threads must be 0 \(all\) or a positive integer.*{words}"):
            parser.parse_args(["--threads", value])
    action = parser._option_string_actions["--threads"]
    assert "LAZ decoding" in action.help and "(default 0)" in action.help


# ------------------------------------------------------------- values that start with "-"

def _value_options():
    for where, parser in PARSERS.items():
        for action in parser._actions:
            if action.option_strings and action.nargs in (None, 1):
                yield pytest.param(where, action.option_strings[-1], id=f"{where} {action.option_strings[-1]}")


@pytest.mark.parametrize("where, flag", list(_value_options()))
@pytest.mark.parametrize("value", ["-1", "-10,5,3", "-z", "-1:2"])
def test_every_value_option_takes_a_value_that_starts_with_a_dash(where, flag, value):
    parser = PARSERS[where]
    assert parser.dash_values_joined([flag, value]) == [f"{flag}={value}"]
    try:
        parser.parse_args([flag, value])
    except UsageError as e:  # refused by its type or range, or a missing argument: never unread
        assert "expected one argument" not in str(e) and "unrecognized arguments" not in str(e), str(e)


def test_an_option_of_the_parser_is_never_a_value():
    parser = PARSERS["m3c2 compare"]
    assert parser.dash_values_joined(["--orient", "-q"]) == ["--orient", "-q"]
    assert parser.dash_values_joined(["--orient", "--quiet"]) == ["--orient", "--quiet"]
    assert parser.dash_values_joined(["--orient", "--qui"]) == ["--orient", "--qui"]  # an abbreviation
    assert parser.dash_values_joined(["--orient", "-ox.csv"]) == ["--orient", "-ox.csv"]  # -o with its value
    assert parser.dash_values_joined(["--ori", "-z"]) == ["--ori=-z"]
    assert parser.dash_values_joined(["--orient=-z", "-q"]) == ["--orient=-z", "-q"]
    assert parser.dash_values_joined(["--quiet", "-z"]) == ["--quiet", "-z"]  # a flag takes no value
    assert parser.dash_values_joined(["--", "--orient", "-z"]) == ["--", "--orient", "-z"]
    assert parser.dash_values_joined(["--core", "-"]) == ["--core", "-"]  # argparse's own: a value
    with pytest.raises(UsageError, match="expected one argument"):
        parser.parse_args(["a", "b", "-o", "c", "--orient", "-q"])


def _pair(d: Path):
    rng = np.random.default_rng(7)
    xy = rng.uniform(0, 10, (600, 2))
    ref = np.column_stack([xy, 0.01 * rng.standard_normal(600)])
    cmp_ = np.column_stack([xy[::-1], 0.1 + 0.01 * rng.standard_normal(600)])
    np.savetxt(d / "ref.xyz", ref, fmt="%.4f")
    np.savetxt(d / "cmp.xyz", cmp_, fmt="%.4f")
    return d / "ref.xyz", d / "cmp.xyz"


BASE = ["--normal-scale", "2", "--projection-scale", "1", "--max-depth", "1", "--quiet"]


def test_orient_at_a_negative_point_as_with_an_equals_sign(tmp_path):
    ref, cmp_ = _pair(tmp_path)
    for name, orient in (("a", ["--orient", "-10,5,3"]), ("b", ["--orient=-10,5,3"]), ("c", ["--orient", "-z"]),
                         ("d", ["--orient=-z"])):
        assert main(["compare", ref, cmp_, "-o", tmp_path / f"{name}.csv", *orient, *BASE]) == 0
    assert (tmp_path / "a.csv").read_bytes() == (tmp_path / "b.csv").read_bytes()
    assert (tmp_path / "c.csv").read_bytes() == (tmp_path / "d.csv").read_bytes()
    below = np.genfromtxt(tmp_path / "a.csv", delimiter=",", names=True)
    down = np.genfromtxt(tmp_path / "c.csv", delimiter=",", names=True)
    # The scanner at (-10, 5, 3) is above the plane z ~ 0: normals towards it point up, the rise is +0.1.
    assert np.nanmedian(below["distance"]) == pytest.approx(0.1, abs=0.01)
    assert np.nanmedian(down["distance"]) == pytest.approx(-0.1, abs=0.01)


def test_normals_orient_at_a_negative_point_as_with_an_equals_sign(tmp_path):
    ref, _ = _pair(tmp_path)
    for name, orient in (("a", ["--orient", "-10,5,3"]), ("b", ["--orient=-10,5,3"]), ("c", ["--orient", "-z"])):
        assert main(["normals", ref, "-o", tmp_path / f"{name}.csv", "--normal-scale", "2", "--quiet", *orient]) == 0
    assert (tmp_path / "a.csv").read_bytes() == (tmp_path / "b.csv").read_bytes()
    up, down = (np.genfromtxt(tmp_path / f"{k}.csv", delimiter=",", names=True)["nz"] for k in "ac")
    fitted = ~np.isnan(up)  # an edge point may have too few neighbours
    assert fitted.sum() > 590 and np.all(up[fitted] > 0.9) and np.all(down[fitted] < -0.9)  # towards the scanner above


@pytest.mark.parametrize("argv, message", [
    (["compare", "R", "C", "-o", "O", "--precision-scales", "-1,1"], "--precision-scales must be finite and > 0, got '-1'"),
    (["compare", "R", "C", "-o", "O", "--normal-scale", "-1"], "--normal-scale must be finite and > 0, got '-1'"),
    (["normals", "R", "-o", "O", "--normal-scale", "-1,2"], "--normal-scale must be finite and > 0, got '-1'"),
    (["roughness", "R", "-o", "O", "--normal-scale", "-1:2:1"], "--normal-scale must be finite and > 0, got '-1'"),
    (["calibrate", "R", "-o", "O", "--projection-scales", "1", "--normal-scale", "-1"],
     "--normal-scale must be finite and > 0, got '-1'"),
    (["simplify", "R", "-o", "O", "--projection-scale", "-0.5"], "--projection-scale must be finite and > 0, got -0.5"),
    (["simplify", "R", "-o", "O", "--projection-scale", "1", "--max-depth", "-1"],
     "--max-depth must be finite and > 0, got -1.0"),
    (["c2c", "R", "C", "-o", "O", "--core-spacing", "-2"], "--core-spacing must be finite and > 0, got -2.0"),
    (["suggest", "R", "C", "--threads", "-3"], "--threads must be 0 (all) or a positive integer, got -3"),
    (["series", "R", "E", "-o", "S", "--projection-scale", "1", "--max-depth", "1", "--threads", "-1"],
     "--threads must be 0 (all) or a positive integer, got -1"),
])
def test_a_negative_value_meets_its_range_check(argv, message, tmp_path, capsys):
    names = {"R": tmp_path / "r.xyz", "C": tmp_path / "c.xyz", "E": tmp_path / "e.xyz", "O": tmp_path / "o.csv",
             "S": tmp_path / "s.zarr"}
    assert main([names.get(a, a) for a in argv]) == 2
    err = capsys.readouterr().err
    assert err.strip().splitlines()[-1] == f"m3c2: error: {message}", err
    assert not any(p.exists() for p in names.values())


@pytest.mark.parametrize("argv, message", [
    (["--min-period", "0"], "--min-period must be an integer >= 1, got '0'"),
    (["--seed-subsampling", "0"], "--seed-subsampling must be an integer >= 1, got '0'"),
    (["--window-width", "1"], "--window-width must be an integer >= 2, got '1'"),
    (["--window-jump", "0"], "--window-jump must be an integer >= 1, got '0'"),
    (["--window-penalty", "0"], "--window-penalty must be finite and > 0, got '0'"),
    (["--neighbourhood-radius", "-1"], "--neighbourhood-radius must be finite and > 0, got '-1'"),
    (["--neighbourhood-radius", "nan"], "--neighbourhood-radius must be finite and > 0, got 'nan'"),
    (["--thresholds", "0.5,1.5"], "--thresholds must be numbers in (0, 1], comma-separated, at least one, got '0.5,1.5'"),
    (["--thresholds", ","], "--thresholds must be a list of numbers like 0.1,0.2, got ','"),
])
def test_objects_options_are_checked_where_they_are_read(argv, message, tmp_path, capsys):
    """The engine checks these too, in its own terms (min_period, thresholds...); the command line
    refuses them first, naming its option (exit 2, nothing read or written)."""
    out = tmp_path / "objects.csv"
    assert main(["series", "objects", str(tmp_path / "missing.zarr"), "-o", str(out), *argv]) == 2
    assert message in capsys.readouterr().err
    assert not out.exists()


def test_every_command_that_writes_or_runs_takes_quiet():
    """Issue 42: `m3c2 series smooth -q` was refused. Every command takes -q and --quiet but the
    group parsers and the two whose printed text is their whole result (info, suggest)."""
    runnable = [where for where, parser in PARSERS.items()
                if where not in ("m3c2", "m3c2 series", "m3c2 classify", "m3c2 info", "m3c2 suggest")]
    missing = [where for where in runnable
               if not {"-q", "--quiet"} <= set(PARSERS[where]._option_string_actions)]
    assert not missing, missing


def test_a_library_warning_is_one_line_without_source(capsys):
    """Issue 42: numpy's warnings reached the user with Python's file and source line."""
    import warnings

    from m3c2kit.cli import main as cli_main
    cli_main._show_warning(RuntimeWarning("invalid value encountered in divide"), RuntimeWarning,
                           "/somewhere/m3c2kit/x.py", 12, line="y = a / b")
    err = capsys.readouterr().err
    assert err == "m3c2: warning: RuntimeWarning: invalid value encountered in divide\n"
    assert warnings.showwarning is not cli_main._show_warning  # installed only while main runs


def test_tam3c2_offers_only_the_lods_it_computes():
    """Issue 42: tam3c2's help offered the bootstrap LOD, which it then refused."""
    parser = PARSERS["m3c2 series tam3c2"]
    action = parser._option_string_actions["--lod"]
    assert tuple(action.choices) == ("z", "t", "auto") and "bootstrap" not in " ".join(action.choices)
    with pytest.raises(UsageError, match="--lod must be one of z, t, auto, got 'bootstrap'"):
        parser.parse_args(["s.zarr", "--lod", "bootstrap"])
