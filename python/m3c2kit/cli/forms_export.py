"""The options of the `m3c2 series` forms that QGIS offers, as JSON read from the command line's own
parsers, for the QGIS plugin (qgis/m3c2kit_processing/series_forms.json), which runs in QGIS's
Python without m3c2kit: its `series_objects` algorithm builds its parameters from this file, so
it cannot drift from `m3c2 series objects` (issue 41: its `--use` lacked `kalman` and three of
its minimums differed from the command line's). tests/python/cli/test_forms_export.py checks the
committed file is the generated one.

    python -m m3c2kit.cli.forms_export qgis/m3c2kit_processing/series_forms.json
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

__all__ = ["FORMS", "exported", "to_json", "main"]

#: The forms QGIS offers, and the options each leaves to the plugin: the store and -o are its
#: inputs and outputs, --threads is the parameter table's row, --quiet a terminal's.
FORMS = {"objects": ("store", "output", "threads", "quiet", "help")}
#: Bumped when the file's layout changes; the plugin refuses a layout it does not know.
FORMAT = 1


def _kind(action: argparse.Action) -> dict:
    """The value's type as a dialog needs it (the argparse type's bounds, see cli/integers.py)."""
    if isinstance(action, (argparse._StoreTrueAction, argparse._StoreFalseAction)):
        return {"type": "flag"}
    if action.choices is not None:
        return {"type": "choice", "choices": list(action.choices)}
    bounds = getattr(action.type, "bounds", None)
    name = getattr(action.type, "__name__", "")
    if name == "integer" and bounds is not None:
        return {"type": "integer", "minimum": bounds[0], "maximum": bounds[1]}
    if name == "positive":
        return {"type": "real", "minimum": 0.0, "minimum_included": False}
    if name == "non_negative":
        return {"type": "real", "minimum": 0.0, "minimum_included": True}
    if action.type is float:
        return {"type": "real", "minimum": None, "minimum_included": True}
    return {"type": "text"}  # lists and the like: passed to m3c2 verbatim, which checks them


def _default(action: argparse.Action):
    value = action.default
    if isinstance(value, (list, tuple)):
        return ",".join(str(v) for v in value)
    return value if isinstance(value, (bool, int, float, str)) or value is None else str(value)


def form_options(parser: argparse.ArgumentParser, left_out) -> list[dict]:
    """Every option of `parser` but those `left_out` (by dest), in the parser's order."""
    out = []
    for action in parser._actions:
        if not action.option_strings or action.dest in left_out:
            continue
        flag = max(action.option_strings, key=len)
        out.append(dict(name=action.dest.upper(), flag=flag, help=action.help or "", default=_default(action),
                        required=bool(action.required), **_kind(action)))
    return out


def exported() -> dict:
    from .series import PARSERS
    forms = {form: form_options(PARSERS[form](), left_out) for form, left_out in FORMS.items()}
    return {"format": FORMAT, "generated_by": "python -m m3c2kit.cli.forms_export", "forms": forms}


def to_json() -> str:
    return json.dumps(exported(), indent=1, ensure_ascii=False, allow_nan=False) + "\n"


def main(argv=None) -> int:
    path = Path((argv or sys.argv[1:] or ["qgis/m3c2kit_processing/series_forms.json"])[0])
    path.write_text(to_json(), encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
