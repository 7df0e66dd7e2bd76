"""Text cells of the tables m3c2 writes (CSV), made safe for spreadsheets (issue 42): a region
named `=HYPERLINK(...)` landed in `m3c2 aggregate`'s CSV as a live formula. A text cell that a
spreadsheet would read as a formula or a command (it starts with = + - @, a tab or a carriage
return) gets a leading apostrophe, the neutralisation spreadsheets themselves use and OWASP's
"CSV injection" guidance recommends; numbers are written by their writers and never pass here.
JSON outputs keep the text as it is (no program evaluates a JSON string)."""
from __future__ import annotations

__all__ = ["spreadsheet_safe"]

FORMULA_STARTS = ("=", "+", "-", "@", "\t", "\r")


def spreadsheet_safe(text: str) -> str:
    """`text` with a leading apostrophe when a spreadsheet would evaluate it."""
    return "'" + text if text.startswith(FORMULA_STARTS) else text
