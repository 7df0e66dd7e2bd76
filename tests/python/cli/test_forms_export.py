"""The `m3c2 series` forms QGIS offers, exported from the command line's own parsers
(m3c2kit.cli.forms_export): the committed qgis/m3c2kit_processing/series_forms.json is the generated
one, so the plugin's series_objects algorithm cannot drift from `m3c2 series objects` (issue 41:
its --use lacked kalman, three of its minimums differed)."""
from __future__ import annotations

import json
from pathlib import Path

from m3c2kit.cli import forms_export
from m3c2kit.cli.series import PARSERS

ROOT = Path(__file__).resolve().parents[3]
COMMITTED = ROOT / "qgis" / "m3c2kit_processing" / "series_forms.json"


def test_committed_file_is_the_generated_one():
    assert COMMITTED.read_text(encoding="utf-8") == forms_export.to_json(), (
        "run: python -m m3c2kit.cli.forms_export qgis/m3c2kit_processing/series_forms.json")


def test_every_option_of_the_form_is_exported_with_its_choices_and_bounds():
    rows = {r["flag"]: r for r in forms_export.exported()["forms"]["objects"]}
    parser = PARSERS["objects"]()
    offered = {max(a.option_strings, key=len) for a in parser._actions if a.option_strings} - {
        "--output", "--threads", "--quiet", "--help"}
    assert set(rows) == offered
    assert "kalman" in rows["--use"]["choices"]
    for flag, row in rows.items():
        action = parser._option_string_actions[flag]
        if action.choices is not None:
            assert row["type"] == "choice" and row["choices"] == list(action.choices)
        bounds = getattr(action.type, "bounds", None)
        if row["type"] == "integer":
            assert (row["minimum"], row["maximum"]) == bounds, flag
            assert action.type(str(bounds[0])) == bounds[0]  # the minimum is accepted by the parser


def test_main_writes_the_file(tmp_path):
    out = tmp_path / "forms.json"
    assert forms_export.main([str(out)]) == 0
    assert json.loads(out.read_text())["format"] == forms_export.FORMAT
