"""The parameter table exported for the QGIS plugin (m3c2kit.settings.export): the committed
qgis/m3c2kit_processing/parameters.json is the generated one, and it says what the table says."""
from __future__ import annotations

import json
from pathlib import Path

from m3c2kit.settings import export
from m3c2kit.settings.table import PARAMETERS

ROOT = Path(__file__).resolve().parents[3]
COMMITTED = ROOT / "qgis" / "m3c2kit_processing" / "parameters.json"


def test_committed_file_is_the_generated_one():
    assert COMMITTED.read_text(encoding="utf-8") == export.to_json(), (
        "run: python -m m3c2kit.settings.export qgis/m3c2kit_processing/parameters.json")


def test_every_row_is_exported_with_its_help_flag_and_default():
    rows = export.exported()["parameters"]
    assert [r["name"] for r in rows] == [p.name for p in PARAMETERS]
    for row, p in zip(rows, PARAMETERS):
        assert (row["flag"], row["help"], row["commands"]) == (p.flag, p.help, list(p.commands))
        assert row["range"] == p.kind.describe()
        if p.choices:
            assert row["type"] == "choice" and row["choices"] == list(p.choices)


def test_kinds_follow_the_table():
    rows = {r["name"]: r for r in export.exported()["parameters"]}
    assert rows["threads"]["type"] == "integer" and rows["threads"]["minimum"] == 0
    assert rows["confidence"]["type"] == "real" and rows["confidence"]["below"] == 1.0
    assert rows["registration_error"]["minimum_included"] is True
    assert rows["median"]["type"] == "flag"
    assert rows["normal_scale"]["type"] == "text"  # one D, a list or a range: m3c2 checks it
    assert rows["lod"]["default"] == "auto"


def test_main_writes_the_file(tmp_path):
    out = tmp_path / "p.json"
    assert export.main([str(out)]) == 0
    assert json.loads(out.read_text(encoding="utf-8")) == export.exported()


def test_every_row_has_a_label_in_words_for_the_dialog():
    """Issue 44: QGIS's labels read like flags ("Lod (--lod)"). Each row's label is words; the
    flag is in its help."""
    rows = export.exported()["parameters"]
    for row, p in zip(rows, PARAMETERS):
        assert row["label"] == p.title() and "--" not in row["label"] and row["label"][0].isupper(), row["label"]
    labels = {r["name"]: r["label"] for r in rows}
    assert labels["lod"] == "LOD statistic" and labels["normal_scale"] == "Normal scale D (diameter)"
