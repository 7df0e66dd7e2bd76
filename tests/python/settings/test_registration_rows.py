"""m3c2 register's own options are rows of the parameter table (settings/registration_rows.py, issue
43): the parser's options come from the rows, their defaults are the engine's RegistrationParams'
where it has them (m3c2kit.register's RegistrationOptions take the same), --rounds acts only with
--auto-stable (the row's needs, for the command and the API alike), and QGIS's m3c2kit:register is
built from the same rows (parameters.json)."""
from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from m3c2kit import _core, engine
from m3c2kit.analysis.registration import RegistrationOptions, register
from m3c2kit.base.errors import UsageError
from m3c2kit.cli.main import main, make_parser
from m3c2kit.cli.options import OPTIONS, table_help, table_type
from m3c2kit.settings.registration_rows import REGISTER, REGISTRATION_ROWS
from m3c2kit.settings.table import by_name, parameters_of

ROOT = Path(__file__).resolve().parents[3]
#: register's inputs and outputs, and the stable areas' two forms (not parameters of the ICP).
OWN_FLAGS = {"-h", "--help", "-o", "--output", "--stable", "--auto-stable"}
#: Options several commands share (cli/options.py's OPTIONS; --threads is the table's compare row).
SHARED = {flag for option in OPTIONS.values() for flag in option.flags} | {"--threads"}


def _parser():
    sub = next(a for a in make_parser()._actions if isinstance(a, argparse._SubParsersAction))
    return sub.choices[REGISTER]


def _options():
    return {a.option_strings[-1]: a for a in _parser()._actions if a.option_strings}


def test_the_rows_are_registers():
    assert parameters_of(REGISTER) == REGISTRATION_ROWS
    assert [r.flag for r in REGISTRATION_ROWS] == ["--max-distance", "--reject", "--max-iterations", "--max-points",
                                                  "--rounds"]


def test_every_option_of_register_is_a_row_or_a_shared_option():
    rows = {r.flag: r for r in parameters_of(REGISTER)}
    for flag, action in _options().items():
        if set(action.option_strings) & (OWN_FLAGS | SHARED):
            continue
        assert flag in rows, f"m3c2 register {flag}: declared outside the parameter table"
        row = rows[flag]
        # declared from the row: its dest, type (range), help and default
        assert action.dest == row.name and action.type is table_type(row), flag
        assert action.help == table_help(row, False), flag
        assert action.default == (None if row.needs else row.default_for()), flag
    assert set(rows) <= set(_options())


def test_the_defaults_are_the_engines_registration_params():
    params = _core.RegistrationParams()
    fields = engine.default_fields("RegistrationParams")
    for row in REGISTRATION_ROWS:
        if row.engine is not None and row.default is not None:
            assert row.engine.struct == "RegistrationParams"
            (field,) = row.engine.fields
            assert row.default_for() == getattr(params, field) == fields[field], row.name
    assert {r.name for r in REGISTRATION_ROWS if r.engine is not None and r.default is not None} == {
        "reject", "max_iterations", "max_points"}


def test_the_parser_and_the_api_take_the_rows_defaults():
    args = _parser().parse_args(["a.las", "b.las", "-o", "t.json"])
    options = RegistrationOptions()
    for row in REGISTRATION_ROWS:
        assert getattr(options, row.name) == row.default_for(), row.name
        if not row.needs:
            assert getattr(args, row.name) == row.default_for(), row.name
    assert args.rounds is None and options.rounds == by_name()["rounds"].default_for() == 5
    assert args.max_distance is None and options.max_distance is None  # D, the normal scale
    assert {f.name for f in dataclasses.fields(RegistrationOptions)} >= {r.name for r in REGISTRATION_ROWS}


def test_the_values_are_those_the_command_reads():
    args = _parser().parse_args(["a.las", "b.las", "-o", "t.json", "--max-distance", "0.5", "--reject", "0",
                                 "--max-iterations", "7", "--max-points", "100", "--auto-stable", "--rounds", "2"])
    assert (args.max_distance, args.reject, args.max_iterations, args.max_points, args.rounds) == (0.5, 0.0, 7, 100, 2)


@pytest.mark.parametrize("flag, value", [("--max-distance", "0"), ("--reject", "-1"), ("--max-iterations", "0"),
                                         ("--max-iterations", "1001"), ("--max-points", "99"), ("--rounds", "21")])
def test_the_ranges_are_todays(flag, value, tmp_path, capsys):
    extra = ["--auto-stable"] if flag == "--rounds" else []
    code = main(["register", "a.las", "b.las", "-o", str(tmp_path / "t.json"), flag, value, *extra])
    err = capsys.readouterr().err
    assert code == 2 and f"{flag} must be" in err and len(err.strip().splitlines()) == 1, err


def test_rounds_without_auto_stable_is_refused_by_the_command_and_the_api(tmp_path, capsys):
    code = main(["register", "a.las", "b.las", "-o", str(tmp_path / "t.json"), "--rounds", "5"])
    err = capsys.readouterr().err
    assert code == 2 and "--rounds would change nothing in this run: it applies only with --auto-stable" in err, err
    points = np.random.default_rng(0).uniform(0, 1, (50, 3))
    with pytest.raises(UsageError, match="--rounds would change nothing"):
        register(points, points, rounds=3)


def test_qgis_register_is_built_from_the_same_rows():
    with open(ROOT / "qgis" / "m3c2kit_processing" / "parameters.json", encoding="utf-8") as f:
        exported = [r for r in json.load(f)["parameters"] if REGISTER in r["commands"]]
    assert [r["flag"] for r in exported] == [r.flag for r in REGISTRATION_ROWS]
    by_flag = {r["flag"]: r for r in exported}
    for row in REGISTRATION_ROWS:
        assert by_flag[row.flag]["default_text"] == row.default_text() and by_flag[row.flag]["help"] == row.help
        if by_flag[row.flag]["type"] == "integer":
            assert (by_flag[row.flag]["minimum"], by_flag[row.flag]["maximum"]) == (row.kind.lo, row.kind.hi)
    source = (ROOT / "qgis" / "m3c2kit_processing" / "algorithms" / "register.py").read_text(encoding="utf-8")
    assert 'COMMAND = "register"' in source and "table.rows(self.COMMAND)" in source
