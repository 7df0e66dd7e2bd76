"""Every option of every subcommand has help text that shows its default, and none says "a
DIAMETERs" (issue 13, point 8): walks every argparse parser the command line builds, including
the forms of `m3c2 series`, which parse their own words."""
from __future__ import annotations

import argparse
import re

import pytest

from m3c2kit.cli.parser import HelpFormatter
from every_parser import every_parser


PARSERS = list(every_parser())
OPTIONS = [(where, action) for where, parser in PARSERS for action in parser._actions
           if not isinstance(action, (argparse._HelpAction, argparse._VersionAction, argparse._SubParsersAction))]
# Same names once: pytest ids.
IDS = [f"{where} {'/'.join(a.option_strings) or a.dest}" for where, a in OPTIONS]


def test_every_subcommand_is_walked():
    names = {where for where, _ in PARSERS}
    for sub in ("compare", "normals", "subsample", "info", "roughness", "calibrate", "c2c", "simplify",
                "suggest", "classify train", "classify apply"):
        assert f"m3c2 {sub}" in names
    assert len(OPTIONS) > 200


def _help(action) -> str:
    return HelpFormatter("m3c2")._get_help_string(action)


@pytest.mark.parametrize("where, action", OPTIONS, ids=IDS)
def test_option_has_help_with_its_default(where, action):
    text = action.help
    assert text and text != argparse.SUPPRESS and text.strip(), "no help text"
    default = action.default
    flag = isinstance(action, (argparse._StoreTrueAction, argparse._StoreFalseAction, argparse._StoreConstAction))
    if default not in (None, False, argparse.SUPPRESS) and not flag and not action.required:
        assert "default" in _help(action).lower(), f"default {default!r} not shown"
    assert not re.search(r"\b(a|an) [A-Z][A-Z_]+s\b", text), f"grammar: {text!r}"  # "a DIAMETERs"
    assert "  " not in text.strip(), f"double space: {text!r}"


def test_the_formatter_shows_a_default_the_help_leaves_out(capsys):
    p = argparse.ArgumentParser(prog="x", formatter_class=HelpFormatter)
    p.add_argument("--window", type=int, default=24, help="epochs in the window")
    p.add_argument("--said", type=int, default=3, help="fewest points (default 3)")
    p.print_help()
    out = " ".join(capsys.readouterr().out.split())
    assert "epochs in the window (default 24)" in out and "(default 3)" in out and "(default 3) (default" not in out
