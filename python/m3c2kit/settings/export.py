"""The parameter table as JSON, for programs that cannot import m3c2kit: the QGIS plugin
(qgis/m3c2kit_processing/parameters.json) runs in QGIS's own Python and builds its compare
dialog from this file, so a parameter added to the table reaches QGIS by regenerating it
(tests/python/settings/test_export.py checks the committed file is up to date).

    python -m m3c2kit.settings.export qgis/m3c2kit_processing/parameters.json
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

from .groups import GROUPS, group_of
from .parsers import Choice, Flag, Integer, Real
from .table import PARAMETERS, Parameter, _shown

__all__ = ["exported", "to_json", "main"]

#: Bumped when the file's layout (not its rows) changes; the plugin refuses a layout it does not know.
FORMAT = 1


def _kind(p: Parameter) -> dict:
    """The value's type as a dialog needs it: a number with its bounds, a choice, a flag or text
    (lists, ranges, orientations and files: passed to m3c2 verbatim, which checks them)."""
    kind = p.kind
    if isinstance(kind, Flag):
        return {"type": "flag"}
    if isinstance(kind, Choice):
        return {"type": "choice", "choices": list(kind.values)}
    if isinstance(kind, Integer):
        return {"type": "integer", "minimum": kind.lo, "maximum": kind.hi}
    if isinstance(kind, Real):
        return {"type": "real", "minimum": kind.lo, "minimum_included": bool(kind.closed), "below": kind.below}
    return {"type": "text"}


def _default(p: Parameter):
    value = p.default_for()
    return value if isinstance(value, (bool, int, float, str)) or value is None else _shown(value)


def exported() -> dict:
    """Every row of the table, in the table's order, with its dialog group (m3c2kit.settings.groups;
    None for a row compare does not take), and the groups in the order dialogs show them."""
    rows = [dict(name=p.name, flag=p.flag, label=p.title(), help=p.help, range=p.kind.describe(), default=_default(p),
                 default_text=p.default_text(), commands=list(p.commands), section=p.section, scope=p.scope,
                 metavar=p.metavar, group=group_of(p.name), **_kind(p)) for p in PARAMETERS]
    return {"format": FORMAT, "generated_by": "python -m m3c2kit.settings.export",
            "groups": [title for title, _ in GROUPS], "parameters": rows}


def to_json() -> str:
    return json.dumps(exported(), indent=1, ensure_ascii=False, allow_nan=False) + "\n"


def main(argv=None) -> int:
    path = Path((argv or sys.argv[1:] or ["qgis/m3c2kit_processing/parameters.json"])[0])
    path.write_text(to_json(), encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
