"""The file ``m3c2 aggregate`` writes: CSV or JSON by the extension of -o (docs/analysis.md,
"m3c2 aggregate"). A column no row defines (the volume and areas of a run without --cell-size) is
left out, never filled with a placeholder; the `intervals` and `notes` columns say why and how
the intervals were made. Written through the atomic writer."""
from __future__ import annotations

import csv
import json
import math
from dataclasses import asdict
from pathlib import Path

from ..base.errors import UsageError
from ..io.atomic import atomic_output
from ..io.text_cells import spreadsheet_safe
from .aggregate import COLUMNS, AggregateTable

__all__ = ["FORMATS", "table_format", "write_table", "FORMAT", "VERSION"]

FORMAT = "m3c2kit-aggregate"
VERSION = 1
FORMATS = (".csv", ".json")


def table_format(path: Path) -> str:
    """The table's format from its extension; a UsageError naming -o for any other."""
    ext = Path(path).suffix.lower()
    if ext not in FORMATS:
        raise UsageError(f"-o {path}: the table is written as {' or '.join(FORMATS)} (by the extension), "
                         f"not {ext or 'a file without extension'!r}")
    return ext


def _columns(table: AggregateTable) -> list[str]:
    return [c for c in COLUMNS if any(getattr(r, c) is not None for r in table.rows)]


def _intervals(table: AggregateTable) -> str:
    return "correlated" if table.error_model else "uncorrelated only"


def _json_value(v):
    return None if isinstance(v, float) and not math.isfinite(v) else v


def _csv_cell(v) -> str:
    if v is None:
        return ""
    if isinstance(v, float):
        return repr(float(v))
    return spreadsheet_safe(v) if isinstance(v, str) else v


def write_table(path: Path, table: AggregateTable, *, meta: dict | None = None) -> None:
    ext = table_format(path)
    cols = _columns(table)
    with atomic_output(path) as tmp:
        if ext == ".csv":
            with open(tmp, "w", newline="", encoding="utf-8") as f:
                w = csv.writer(f)
                w.writerow([*cols, "intervals", "notes"])
                notes = spreadsheet_safe("; ".join(table.notes))
                for row in table.rows:
                    values = [getattr(row, c) for c in cols]
                    w.writerow([*(_csv_cell(v) for v in values), _intervals(table), notes])
        else:
            doc = {"format": FORMAT, "version": VERSION, **(meta or {}), "confidence": table.confidence,
                   "cell_size": table.cell_size, "intervals": _intervals(table), "simulations": table.simulations,
                   "seed": table.seed, "notes": table.notes,
                   "regions": [{c: _json_value(v) for c, v in asdict(r).items() if c in cols} for r in table.rows]}
            tmp.write_text(json.dumps(doc, indent=1, allow_nan=False) + "\n", encoding="utf-8")
