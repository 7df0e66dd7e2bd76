"""The dialog groups of m3c2 compare's parameters (m3c2kit.settings.groups): every compare row in
exactly one, shown so by `m3c2 compare --help` and exported for QGIS in that order."""
import json
from pathlib import Path

import pytest

from m3c2kit.cli.main import main

from m3c2kit.settings import by_name, parameters_of
from m3c2kit.settings.export import exported
from m3c2kit.settings.groups import GROUPS, group_of

ROOT = Path(__file__).resolve().parents[3]


def test_every_compare_row_is_in_exactly_one_group_and_every_grouped_name_is_a_compare_row():
    listed = [name for _, names in GROUPS for name in names]
    assert len(listed) == len(set(listed)), "a row in two groups"
    compare = {p.name for p in parameters_of("compare")}
    assert set(listed) == compare, (sorted(compare - set(listed)), sorted(set(listed) - compare))
    assert all(name in by_name() for name in listed)


def test_the_groups_follow_cloudcompares_tabs_in_order():
    titles = [title for title, _ in GROUPS]
    assert titles[:4] == ["Scales", "Normals", "Statistics", "Uncertainty"]
    assert {"Vegetation", "Output"} <= set(titles)
    assert group_of("normal_scale") == "Scales" and group_of("classifier") == "Vegetation"
    assert group_of("window") is None  # a series step's row is in no compare group


def _help_sections(text: str) -> dict[str, list[str]]:
    """{section title: the long flags listed under it} of an argparse help text."""
    sections, current = {}, None
    for line in text.splitlines():
        if line and not line.startswith(" ") and line.endswith(":"):
            current = sections.setdefault(line[:-1], [])
        elif current is not None and line.startswith("  -"):
            current.extend(w.rstrip(",") for w in line.split() if w.startswith("--"))
    return sections


def test_compare_help_lists_each_table_option_under_its_group(capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "200")
    with pytest.raises(SystemExit) as ended:
        main(["compare", "--help"])
    assert ended.value.code == 0
    sections = _help_sections(capsys.readouterr().out)
    titles = [title for title, _ in GROUPS]
    assert [t for t in sections if t in titles] == titles  # in the dialogs' order
    for title, names in GROUPS:
        for name in names:
            assert by_name()[name].flag in sections[title], (name, title)


def test_the_exported_rows_carry_their_group_and_the_groups_order():
    data = exported()
    assert data["groups"] == [title for title, _ in GROUPS]
    for row in data["parameters"]:
        assert row["group"] == group_of(row["name"])
    committed = json.loads((ROOT / "qgis/m3c2kit_processing/parameters.json").read_text(encoding="utf-8"))
    assert committed["groups"] == data["groups"]
