"""`m3c2 info`: a file's summary as JSON-ready data (``--json``) and as text for people.

The CRS appears as its name, EPSG code and WKT (m3c2kit.io.crs.crs_info), never as a Python
repr; the text form prints names and numbers only.
"""
from __future__ import annotations

import os
from typing import Any

from .crs import crs_info
from .files import info

__all__ = ["describe", "describe_text"]


def describe(path: str | os.PathLike) -> dict[str, Any]:
    """m3c2kit.io.info(path) with ``crs`` as ``{"name", "epsg", "wkt", "units", "angular",
    "readable"}`` (None without a CRS): every value is a JSON type."""
    d = info(path)
    d["crs"] = crs_info(d.get("crs"), d.get("units_hint"))
    return d


def _xyz(values) -> str:
    return ", ".join(f"{v:.10g}" for v in values)


def describe_text(d: dict[str, Any]) -> str:
    """The lines `m3c2 info` prints for a :func:`describe` dictionary."""
    fmt = d["format"] + (f" {d['version']}" if d.get("version") else "")
    if d.get("point_format") is not None:
        fmt += f", point format {d['point_format']}"
    lines = [f"file:    {d['path']}", f"format:  {fmt}", f"points:  {d['point_count']:,}"]
    if d.get("nonfinite_count"):
        lines.append(f"         {d['nonfinite_count']:,} with non-finite coordinates")
    if d.get("scan_count") is not None:
        lines.append(f"scans:   {d['scan_count']}")
    b = d.get("bounds")
    if b:
        lines += [f"min:     {_xyz(b['min'])}", f"max:     {_xyz(b['max'])}"]
    crs = d.get("crs")
    if crs is None:
        lines.append("CRS:     none")
    elif crs.get("readable"):
        code = f" (EPSG:{crs['epsg']})" if crs.get("epsg") else ""
        lines.append(f"CRS:     {crs['name']}{code}")
    else:
        lines.append("CRS:     present but not readable by PROJ (see m3c2 info --json for its text)")
    units = (crs or {}).get("units") or d.get("units_hint")
    lines.append(f"units:   {units or 'unknown'}" + (" (angular: reproject before M3C2)" if crs and crs.get("angular") else ""))
    if d.get("scale"):
        lines.append(f"scale:   {_xyz(d['scale'])}    offset: {_xyz(d['offset'])}")
    lines.append(f"fields:  {', '.join(d['fields']) if d.get('fields') else 'none'}")
    return "\n".join(lines)
