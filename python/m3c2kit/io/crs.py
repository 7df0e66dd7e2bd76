"""Coordinate reference systems through pyproj: equality, names, EPSG codes, units, checks.

A CRS travels through the package as text (``Cloud.crs``: WKT 1 or 2, ESRI WKT, or
``"EPSG:<code>"``); pyproj (PROJ) parses it. Two texts are the same CRS when pyproj says they are
equivalent (``CRS.equals``, axis order ignored), so the ESRI and OGC WKT of one CRS are equal.
Without pyproj (the ``crs`` extra) every CRS is "unknown" except texts equal but for white
space: two such texts pass; two that differ are refused by :func:`check_crs` with a message
naming the extra (they may be one CRS spelled twice, or two CRSs: nothing is decided on a guess).

Only :func:`looks_like_wkt` (a sniff that tells WKT from junk in a LAS record) and the GeoTIFF
key tables (:func:`geokey_crs`, :func:`geokey_units`: numbers, not WKT) are done by hand.
"""
from __future__ import annotations

import functools
import os
import re
from typing import Any

from ..base.errors import M3C2Error, UsageError

__all__ = ["looks_like_wkt", "parse_crs", "wkt_units", "crs_units", "geokey_crs", "geokey_units",
           "combine_units", "same_crs", "crs_label", "crs_info", "is_angular", "CrsMismatch",
           "check_crs", "assign_crs", "PYPROJ_MISSING"]

_WKT_START = re.compile(r"\s*[A-Za-z_][A-Za-z0-9_]*\s*[\[(]")

# GeoTIFF unit codes (EPSG unit of measure) that LAS files use.
_LINEAR_UNITS = {9001: "metre", 9002: "foot", 9003: "US survey foot", 9030: "nautical mile",
                 9036: "kilometre"}
_USER_DEFINED = 32767
_ANGULAR = ("degree", "radian", "grad", "arc-second", "arc-minute")

PYPROJ_MISSING = "pyproj is not installed (pip install 'm3c2kit[crs]'): CRSs are unknown"


def _has_pyproj() -> bool:
    try:
        import pyproj  # noqa: F401
    except ImportError:
        return False
    return True


class CrsMismatch(M3C2Error):
    """The clouds' CRSs or units differ or cannot be compared (exit 1); --ignore-crs overrides."""


def looks_like_wkt(text: str | None) -> bool:
    """True when `text` starts like a WKT CRS (``KEYWORD[`` or ``KEYWORD(``), e.g. not ``"''"``."""
    return bool(text) and bool(_WKT_START.match(text)) and text.rstrip().endswith(("]", ")"))


@functools.lru_cache(maxsize=64)
def parse_crs(text: str | None) -> Any:
    """The ``pyproj.CRS`` of a CRS text, or None when there is none, pyproj is missing, or PROJ
    cannot read it."""
    if not text or not text.strip():
        return None
    try:
        import pyproj
    except ImportError:
        return None
    try:
        crs = pyproj.CRS.from_user_input(text)
    except Exception:  # pyproj.exceptions.CRSError, or junk PROJ refuses in other ways
        return None
    # A WKT 1 with a TOWGS84 clause is a BoundCRS (the CRS plus a datum shift to WGS 84): the
    # coordinates are in its source CRS, which is what names, units and equality concern.
    return crs.source_crs if crs.is_bound and crs.source_crs is not None else crs


def _unit_name(name: str | None) -> str | None:
    if not name:
        return None
    n = name.strip()
    return {"meter": "metre", "m": "metre", "us survey foot": "US survey foot", "degree (supplier to define representation)": "degree"}.get(n.lower(), n)


def _axis_unit(crs) -> str | None:
    axes = crs.axis_info
    return _unit_name(axes[0].unit_name) if axes else None


def combine_units(horizontal: str | None, vertical: str | None) -> str | None:
    """``"metre"`` when both agree (or one is unknown), else ``"<h> (horizontal), <v> (vertical)"``."""
    if horizontal and vertical and horizontal != vertical:
        return f"{horizontal} (horizontal), {vertical} (vertical)"
    return horizontal or vertical


def crs_units(text: str | None) -> str | None:
    """The units a CRS gives coordinates (horizontal, and vertical when it differs), or None."""
    crs = parse_crs(text)
    if crs is None:
        return None
    if crs.is_compound and crs.sub_crs_list:
        parts = crs.sub_crs_list
        vertical = _axis_unit(parts[1]) if len(parts) > 1 else None
        return combine_units(_axis_unit(parts[0]), vertical)
    return _axis_unit(crs)


#: The units of a WKT text (kept under this name for the LAS reader).
wkt_units = crs_units


def geokey_crs(keys: dict[int, int]) -> str | None:
    """``"EPSG:<code>"`` from GeoTIFF keys (projected 3072, else geographic 2048), or None."""
    for key in (3072, 2048):
        code = keys.get(key)
        if code and code != _USER_DEFINED:
            return f"EPSG:{code}"
    return None


def geokey_units(keys: dict[int, int]) -> str | None:
    """Units from GeoTIFF keys: ProjLinearUnits (3076) and VerticalUnits (4099); degrees for a
    geographic model (1024 == 2)."""
    horizontal = _LINEAR_UNITS.get(keys.get(3076, 0))
    if horizontal is None and keys.get(1024) == 2:
        horizontal = "degree"
    vertical = _LINEAR_UNITS.get(keys.get(4099, 0))
    return combine_units(horizontal, vertical)


#: Two CRSs on one datum are the same when converting coordinates from one to the other moves no
#: sample point by more than this (in the target's units): the ESRI and OGC WKT of one CRS often
#: differ in the last digits of a parameter (a false easting given to 1e-9 ft or to 1e-3 ft).
SAME_CRS_TOLERANCE = 1e-3


def same_crs(a: str | None, b: str | None, sample=None) -> bool | None:
    """True / False when two CRS texts are / are not the same CRS, None when either is absent or
    cannot be read (or pyproj is missing and the texts differ).

    The same: PROJ finds them equivalent (axis order ignored), or they share a datum and
    converting `sample` points ((K, 2+) coordinates in `a`, or a callable returning them, called
    only if the conversion is needed; default: a grid over either CRS's area of use) from `a` to
    `b` moves none by more than :data:`SAME_CRS_TOLERANCE`."""
    if not a or not b:
        return None
    if " ".join(a.split()) == " ".join(b.split()):
        return True
    ca, cb = parse_crs(a), parse_crs(b)
    if ca is None or cb is None:
        return None
    da, db = _declared_epsg(ca), _declared_epsg(cb)
    if da is not None and db is not None and da != db:
        return False  # two different EPSG CRSs, even where PROJ finds their definitions equal
    if ca.equals(cb, ignore_axis_order=True):
        return True
    ea, eb = _epsg(ca), _epsg(cb)
    if ea is not None and eb is not None:
        return ea == eb
    try:
        return _same_by_conversion(ca, cb, sample)
    except Exception:  # PROJ cannot convert between them: not shown to be the same
        return False


def same_horizontal_crs(a: str | None, b: str | None) -> bool | None:
    """same_crs of the horizontal parts (a compound CRS's first): plan-view data, such as regions,
    carry no vertical datum, and 'NAD83 / Oregon LCC' is the plan of 'NAD83 / Oregon LCC + NAVD88
    height' (issue 42: the regions of a compound-CRS LAS file were refused)."""
    ca, cb = parse_crs(a), parse_crs(b)
    if ca is None or cb is None:
        return same_crs(a, b)
    return same_crs(_horizontal(ca).to_wkt(), _horizontal(cb).to_wkt())


def _horizontal(crs):
    return crs.sub_crs_list[0] if crs.is_compound and crs.sub_crs_list else crs


def _vertical(crs):
    return crs.sub_crs_list[1] if crs.is_compound and len(crs.sub_crs_list) > 1 else None


def _same_by_conversion(ca, cb, sample) -> bool:
    import numpy as np
    import pyproj

    ha, hb = _horizontal(ca), _horizontal(cb)
    da, db = ha.datum, hb.datum
    if da is None or db is None or not da == db:
        return False
    va, vb = _vertical(ca), _vertical(cb)
    if (va is None) != (vb is None) or (va is not None and not va.equals(vb, ignore_axis_order=True)):
        return False
    if _axis_unit(ha) != _axis_unit(hb):
        return False
    points = None
    if callable(sample):
        sample = sample()
    if sample is not None:
        points = np.asarray(sample, dtype=float).reshape(-1, np.shape(sample)[-1])[:, :2]
    else:
        area = ha.area_of_use or hb.area_of_use
        for crs in (ha, hb):  # a WKT 1 with an EPSG AUTHORITY carries no area: PROJ's database has it
            code = _epsg(crs) if area is None else None
            area = pyproj.CRS.from_epsg(code).area_of_use if code else area
        if area is None:
            return False
        lon, lat = np.meshgrid(np.linspace(area.west, area.east, 3), np.linspace(area.south, area.north, 3))
        to_a = pyproj.Transformer.from_crs(ha.geodetic_crs, ha, always_xy=True)
        points = np.column_stack(to_a.transform(lon.ravel(), lat.ravel()))
    convert = pyproj.Transformer.from_crs(ha, hb, always_xy=True)
    x, y = convert.transform(points[:, 0], points[:, 1])
    moved = np.hypot(np.asarray(x) - points[:, 0], np.asarray(y) - points[:, 1])
    return bool(np.all(np.isfinite(moved)) and moved.max() <= SAME_CRS_TOLERANCE)


def _declared_epsg(crs) -> int | None:
    """The EPSG code a CRS text declares (its ID / AUTHORITY), or None."""
    try:
        ident = crs.to_json_dict().get("id") or {}
        if str(ident.get("authority", "")).upper() == "EPSG":
            return int(ident["code"])
    except Exception:
        pass
    return None


def _epsg(crs) -> int | None:
    """The EPSG code a CRS declares, else the one PROJ identifies it as, or None."""
    code = _declared_epsg(crs)
    if code is not None:
        return code
    try:
        return crs.to_epsg(min_confidence=90)
    except Exception:
        return None


def crs_label(text: str | None, limit: int = 120) -> str:
    """A one-line name: ``'NAME' (EPSG:code)``, ``'NAME'``, ``unknown``, or the text cut short
    when PROJ cannot read it."""
    if not text:
        return "unknown"
    crs = parse_crs(text)
    if crs is None:
        label = " ".join(text.split())
        return label if len(label) <= limit else label[: limit - 3] + "..."
    code = _epsg(crs)
    name = " ".join(str(crs.name).split())  # a WKT's quoted name may hold line breaks: one line all the same
    return f"'{name}' (EPSG:{code})" if code else f"'{name}'"


def is_angular(text: str | None, units_hint: str | None = None) -> bool:
    """True when the horizontal coordinates are angles (a geographic CRS such as EPSG:4326)."""
    crs = parse_crs(text)
    if crs is not None:
        horizontal = crs.sub_crs_list[0] if crs.is_compound and crs.sub_crs_list else crs
        return bool(horizontal.is_geographic) or (_axis_unit(horizontal) or "").lower() in _ANGULAR
    return (units_hint or "").split(" (")[0].lower() in _ANGULAR


def crs_info(text: str | None, units_hint: str | None = None) -> dict[str, Any] | None:
    """A JSON-ready description: ``name``, ``epsg`` (int or None), ``wkt`` (WKT2 from PROJ, else
    the text as stored), ``units``, ``angular``; None when there is no CRS."""
    if not text:
        return None
    crs = parse_crs(text)
    if crs is None:
        return {"name": None, "epsg": None, "wkt": text, "units": units_hint, "angular": is_angular(None, units_hint),
                "readable": False}
    return {"name": crs.name, "epsg": _epsg(crs), "wkt": crs.to_wkt(), "units": crs_units(text) or units_hint,
            "angular": is_angular(text), "readable": True}


def assign_crs(spec: str) -> str:
    """WKT2 of a user's ``--crs`` (``EPSG:32617``, a WKT, a PROJ string or a path to a .prj/.wkt
    file), or a UsageError naming it."""
    text = spec
    if os.path.lexists(spec):  # a .prj/.wkt file (lexists is False for a name too long to exist)
        from .input_file import read_small_bytes
        text = read_small_bytes(spec, "CRS file", label=f"--crs {spec}").decode("utf-8", errors="replace")
    if not _has_pyproj():
        raise UsageError(f"--crs {spec!r} needs the crs extra (pyproj): pip install 'm3c2kit[crs]'")
    crs = parse_crs(text.strip())
    if crs is None:
        raise UsageError(f"--crs {spec!r} is not a CRS PROJ can read (give e.g. EPSG:32617, a WKT or a .prj file)")
    return crs.to_wkt()


def _role(cloud, role: str) -> str:
    path = getattr(cloud, "path", None)
    return f"{role} {path}" if path is not None else f"the {role} cloud"


#: The last cloud's extent corners, by a weak reference to its coordinates: `m3c2 series` checks
#: one reference against every epoch, and its extent was ~15 % of the time of adding an epoch.
_LAST_CORNERS: list = [None, None]


def _extent_corners(cloud):
    """The corners of the cloud's horizontal extent; computed only when a CRS conversion needs
    them (check_crs passes this as a callable) and once per cloud."""
    import weakref

    import numpy as np
    xyz = getattr(cloud, "xyz", None)
    if xyz is None or len(xyz) == 0:
        return None
    if _LAST_CORNERS[0] is not None and _LAST_CORNERS[0]() is xyz:
        return _LAST_CORNERS[1]
    lo, hi = np.nanmin(xyz[:, :2], axis=0), np.nanmax(xyz[:, :2], axis=0)
    corners = np.array([[lo[0], lo[1]], [hi[0], lo[1]], [lo[0], hi[1]], [hi[0], hi[1]]])
    try:
        _LAST_CORNERS[:] = [weakref.ref(xyz), corners]
    except TypeError:  # not an object a weak reference can point to: not cached
        pass
    return corners


def check_crs(reference, compared, core=None, *, ignore: bool = False, allow_angular: bool = False) -> None:
    """Refuses (CrsMismatch) clouds that cannot be compared as they are (docs/errors.md):

    - the compared cloud (or the core points) in a CRS known to differ from the reference's, or
      with different units;
    - a CRS on one of reference and compared only (core points without one are taken to be in
      the reference's CRS);
    - horizontal coordinates in degrees (a geographic CRS): distances would mix degrees and
      metres; reproject, or pass --allow-angular.

    `ignore` (--ignore-crs) skips every check. Clouds are objects with ``crs``, ``units_hint``
    and ``path`` (m3c2kit.io.Cloud)."""
    if ignore:
        return
    ref_crs, ref_units = getattr(reference, "crs", None), getattr(reference, "units_hint", None)
    for role, other in (("compared", compared), ("core points", core)):
        if other is None:
            continue
        other_crs, other_units = getattr(other, "crs", None), getattr(other, "units_hint", None)
        if role == "compared" and bool(ref_crs) != bool(other_crs):
            has, lacks = (reference, other) if ref_crs else (other, reference)
            has_role, lacks_role = ("reference", role) if ref_crs else (role, "reference")
            raise CrsMismatch(
                f"only one cloud has a CRS: {_role(has, has_role)} is in {crs_label(has.crs)}, "
                f"{_role(lacks, lacks_role)} has none; give it one with --crs (e.g. --crs EPSG:<code>), "
                f"or pass --ignore-crs if the coordinates are comparable")
        same = same_crs(ref_crs, other_crs, lambda: _extent_corners(reference))
        if same is None and ref_crs and other_crs and not _has_pyproj():
            raise CrsMismatch(f"{_role(reference, 'reference')} and {_role(other, role)} have CRS texts that differ, "
                              f"and telling whether they are the same CRS needs the crs extra (pyproj): pip install "
                              f"'m3c2kit[crs]', or pass --ignore-crs if the coordinates are comparable")
        if same is None and ref_crs and other_crs:
            # A CRS that PROJ cannot read (a WKT nested thousands deep, a truncated one) tells nothing:
            # the clouds were compared as if it matched (issue 42).
            unreadable = reference if parse_crs(ref_crs) is None else other
            label = "reference" if unreadable is reference else role
            raise CrsMismatch(f"{_role(unreadable, label)}: its CRS cannot be read (not a CRS text PROJ knows, "
                              f"{crs_label(unreadable.crs, 60)}), so it cannot be checked against the other's; "
                              f"give it one with --crs, or pass --ignore-crs if the coordinates are comparable")
        if same is False:
            raise CrsMismatch(f"the clouds have different CRSs: {_role(reference, 'reference')} is in "
                              f"{crs_label(ref_crs)}, {_role(other, role)} in {crs_label(other_crs)}; "
                              f"reproject one of them, or pass --ignore-crs if the coordinates are comparable")
        if ref_units and other_units and ref_units != other_units:
            raise CrsMismatch(f"the clouds have different units: {_role(reference, 'reference')} is in "
                              f"{ref_units}, {_role(other, role)} in {other_units}; convert one of them, or "
                              f"pass --ignore-crs if the coordinates are comparable")
    if not allow_angular:
        for role, cloud in (("reference", reference), ("compared", compared)):
            if cloud is not None and is_angular(getattr(cloud, "crs", None), getattr(cloud, "units_hint", None)):
                raise CrsMismatch(
                    f"{_role(cloud, role)} has angular coordinates ({crs_label(cloud.crs)}, units: degrees): "
                    f"M3C2's scales and distances would mix degrees with heights; reproject to a projected "
                    f"CRS in metres (e.g. UTM), or pass --allow-angular if you mean it")
