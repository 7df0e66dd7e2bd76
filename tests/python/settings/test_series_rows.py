"""The series steps' options are rows of the parameter table (settings/series_rows.py, issue 41):
each declared once, its default the engine struct's where the struct has one, and QGIS's
series_objects built from the same rows (parameters.json)."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from m3c2kit import _core
from m3c2kit.cli import series as cli
from m3c2kit.cli.options import OPTIONS
from m3c2kit.series.kalman import KalmanOptions, _kalman_params
from m3c2kit.series.tam3c2 import Tam3c2Options
from m3c2kit.settings.series_rows import SERIES_ROWS
from m3c2kit.settings.table import by_name, parameters_of

ROOT = Path(__file__).resolve().parents[3]
#: The forms' inputs and outputs (not parameters): the store, -o, the core point indices, the objects table.
IO_FLAGS = {"-h", "--help", "-o", "--output", "--core", "--objects"}
STEPS = {"series": cli.create_parser, "series smooth": cli.smooth_parser, "series kalman": cli.kalman_parser,
         "series tam3c2": cli.tam3c2_parser, "series objects": cli.objects_parser,
         "series changepoints": cli.changepoints_parser}
#: Options several commands share (cli/options.py's OPTIONS; the readers' --drop-nonfinite, io/files.py).
SHARED = {flag for option in OPTIONS.values() for flag in option.flags} | {"--drop-nonfinite"}


def _options(parser):
    return [a for a in parser._actions if a.option_strings]


@pytest.mark.parametrize("command", STEPS)
def test_every_option_of_a_series_step_is_a_table_row_or_a_shared_option(command):
    rows = by_name()
    for action in _options(STEPS[command]()):
        flags = set(action.option_strings)
        if flags & (IO_FLAGS | SHARED):
            continue
        assert action.dest in rows, f"m3c2 {command} {action.option_strings}: declared outside the parameter table"
        assert rows[action.dest].flag in flags


@pytest.mark.parametrize("command", [c for c in STEPS if c != "series"])
def test_each_row_of_a_step_is_an_option_of_its_parser(command):
    flags = {f for a in _options(STEPS[command]()) for f in a.option_strings}
    assert {r.flag for r in parameters_of(command)} <= flags


def test_the_objects_defaults_are_the_engines():
    """Parsed with no option, the objects form builds the engine's own ObjectsParams()."""
    built = cli.objects_params(cli.objects_parser().parse_args(["s.zarr", "-o", "o.csv"]))
    engine = _core.ObjectsParams()
    for name in dir(engine):
        if not name.startswith("_"):
            assert getattr(built, name) == getattr(engine, name), name


@pytest.mark.parametrize("flag, value", [("--window-width", "30"), ("--window-min-size", "5"), ("--window-jump", "2"),
                                         ("--window-penalty", "2.5"), ("--min-period", "3"),
                                         ("--height-threshold", "0.25"), ("--finished-only", None),
                                         ("--seed-subsampling", "4"), ("--neighbourhood-radius", "2"),
                                         ("--thresholds", "0.3,0.6"), ("--min-segments", "4"),
                                         ("--max-segments", "40"), ("--max-cv", "0.5"), ("--dtw", "py4dgeo")])
def test_every_objects_row_reaches_the_engine(flag, value):
    argv = ["s.zarr", "-o", "o.csv", flag, *([] if value is None else [value])]
    built = cli.objects_params(cli.objects_parser().parse_args(argv))
    row = next(r for r in SERIES_ROWS if r.flag == flag and "series objects" in r.commands)
    default = _core.ObjectsParams()
    assert any(getattr(built, f) != getattr(default, f) for f in row.engine.fields), flag


def test_the_python_options_take_the_command_lines_defaults():
    kalman = cli.kalman_parser().parse_args(["s.zarr"])
    for field in ("model", "process_noise", "noise", "observation", "from_scratch"):
        assert getattr(KalmanOptions(), field) == getattr(kalman, field), field
    tam = cli.tam3c2_parser().parse_args(["s.zarr"])
    o = Tam3c2Options()
    assert (list(o.window_ratios), o.min_points, o.weights, o.fallback, o.breaks) == (
        list(tam.window_ratio), tam.required_points, tam.weights, tam.fallback, tam.window_breaks)


def test_the_kalman_and_tam3c2_defaults_are_the_engines_where_it_has_them():
    o = KalmanOptions()
    built, engine = _kalman_params(o.model, o.noise, 0.0, o.observation), _core.KalmanParams()
    assert (built.order, built.discrete_noise, built.observation) == (engine.order, engine.discrete_noise,
                                                                     engine.observation)
    t, tam = Tam3c2Options(), _core.Tam3c2Params()
    assert (t.min_points, t.weights, t.breaks) == (tam.min_points, tam.weights, tam.breaks)
    # ours, documented in the row: the epoch's own M3C2 where the windows fall short (the engine's
    # default is the authors' rule)
    assert (t.fallback, tam.fallback) == ("m3c2", "none")


def test_the_option_values_are_those_the_step_reads():
    args = cli.tam3c2_parser().parse_args(["s.zarr", "--window-ratio", "0.1,0.3", "--required-points", "7",
                                           "--break-width", "5", "--window-breaks", "changepoints"])
    assert (args.window_ratio, args.required_points, args.break_width) == ([0.1, 0.3], 7, 5)
    assert cli.kalman_parser().parse_args(["s.zarr", "--process-noise", "1e-4"]).process_noise == 1e-4
    assert cli.kalman_parser().parse_args(["s.zarr", "--process-noise", "auto"]).process_noise == "auto"
    # a row that acts only with another option stays unset, so that the step can refuse it alone
    assert cli.tam3c2_parser().parse_args(["s.zarr"]).break_width is None


def test_qgis_series_objects_is_built_from_the_same_rows():
    with open(ROOT / "qgis" / "m3c2kit_processing" / "parameters.json", encoding="utf-8") as f:
        exported = [r for r in json.load(f)["parameters"] if "series objects" in r["commands"]]
    rows = parameters_of("series objects")
    assert [r["flag"] for r in exported] == [r.flag for r in rows]
    by_flag = {r["flag"]: r for r in exported}
    assert "kalman" in by_flag["--use"]["choices"]
    for row in rows:
        assert by_flag[row.flag]["default_text"] == row.default_text()
        if by_flag[row.flag]["type"] == "integer":
            assert by_flag[row.flag]["minimum"] == row.kind.lo  # the command line's minimum
