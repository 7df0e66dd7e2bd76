"""Just enough CRS parsing, without pyproj, to tell WKT apart from junk, name the linear units
of a WKT (1 or 2) CRS, and read the EPSG code and units of LAS GeoTIFF keys."""
from __future__ import annotations

import re

__all__ = ["looks_like_wkt", "wkt_units", "geokey_crs", "geokey_units", "combine_units", "same_crs", "crs_label"]

_WKT_START = re.compile(r"\s*[A-Za-z_][A-Za-z0-9_]*\s*[\[(]")
_TOKEN = re.compile(r'\s*(?:"((?:[^"]|"")*)"|([\[\](),])|([^\s\[\](),"]+))')

# GeoTIFF unit codes (EPSG unit of measure) that LAS files use.
_LINEAR_UNITS = {9001: "metre", 9002: "foot", 9003: "US survey foot", 9030: "nautical mile",
                 9036: "kilometre"}
_USER_DEFINED = 32767


def looks_like_wkt(text: str | None) -> bool:
    """True when `text` starts like a WKT CRS (``KEYWORD[`` or ``KEYWORD(``), e.g. not ``"''"``."""
    return bool(text) and bool(_WKT_START.match(text)) and text.rstrip().endswith(("]", ")"))


def _parse(text: str):
    """WKT as nested [keyword, arg, ...] lists; strings stay str, numbers stay their text."""
    stack: list[list] = [[None]]
    last_word: str | None = None
    for m in _TOKEN.finditer(text):
        quoted, punct, word = m.groups()
        if punct in ("[", "("):
            node = [last_word or ""]
            if last_word is not None:
                stack[-1].pop()  # the keyword was pushed as a plain word; it becomes the node
            stack[-1].append(node)
            stack.append(node)
            last_word = None
        elif punct in ("]", ")"):
            if len(stack) == 1:
                raise ValueError("unbalanced brackets")
            stack.pop()
            last_word = None
        elif punct == ",":
            last_word = None
        elif quoted is not None:
            stack[-1].append(quoted.replace('""', '"'))
            last_word = None
        elif word is not None:
            stack[-1].append(word)
            last_word = word
    if len(stack) != 1:
        raise ValueError("unbalanced brackets")
    return stack[0][1:]


_UNIT_KEYS = ("UNIT", "LENGTHUNIT")
_GEOG_KEYS = ("GEOGCS", "BASEGEOGCRS", "GEOGCRS", "GEODCRS", "BASEGEODCRS")
_PROJ_KEYS = ("PROJCS", "PROJCRS", "GEOCCS")
_VERT_KEYS = ("VERT_CS", "VERTCRS", "VERTICALCRS")


def _first_unit(node: list, skip: tuple[str, ...] = ()) -> str | None:
    """Name of the first UNIT/LENGTHUNIT under `node`, not descending into `skip` keywords."""
    for child in node[1:]:
        if not isinstance(child, list):
            continue
        key = str(child[0]).upper()
        if key in _UNIT_KEYS and len(child) > 1 and isinstance(child[1], str):
            return child[1]
        if key in skip:
            continue
        found = _first_unit(child, skip)
        if found:
            return found
    return None


def _find(node: list, keys: tuple[str, ...]) -> list | None:
    if str(node[0]).upper() in keys:
        return node
    for child in node[1:]:
        if isinstance(child, list):
            found = _find(child, keys)
            if found is not None:
                return found
    return None


_UNIT_NAMES = {"metre": "metre", "meter": "metre", "m": "metre", "foot_us": "US survey foot",
               "us survey foot": "US survey foot", "foot": "foot", "foot_international": "foot",
               "international foot": "foot", "degree": "degree"}


def _normal_unit(name: str) -> str:
    return _UNIT_NAMES.get(name.strip().lower(), name.strip())


def combine_units(horizontal: str | None, vertical: str | None) -> str | None:
    """``"metre"`` when both agree (or one is unknown), else ``"<h> (horizontal), <v> (vertical)"``."""
    if horizontal and vertical and horizontal != vertical:
        return f"{horizontal} (horizontal), {vertical} (vertical)"
    return horizontal or vertical


def wkt_units(wkt: str) -> str | None:
    """The linear units a WKT CRS gives coordinates, or None if it cannot tell."""
    try:
        roots = [n for n in _parse(wkt) if isinstance(n, list)]
    except ValueError:
        return None
    if not roots:
        return None
    root = roots[0]
    horizontal = vertical = None
    proj = _find(root, _PROJ_KEYS)
    if proj is not None:
        horizontal = _first_unit(proj, skip=_GEOG_KEYS)
    else:
        geog = _find(root, _GEOG_KEYS)
        if geog is not None:
            horizontal = _first_unit(geog)
    vert = _find(root, _VERT_KEYS)
    if vert is not None:
        vertical = _first_unit(vert)
    return combine_units(_normal_unit(horizontal) if horizontal else None,
                         _normal_unit(vertical) if vertical else None)


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


# ------------------------------------------------------------------------- comparing two CRSs

_EPSG_TEXT = re.compile(r"\s*EPSG\s*:\s*(\d+)\s*", re.IGNORECASE)
_AUTHORITY_KEYS = ("AUTHORITY", "ID")
_COMPOUND_KEYS = ("COMPD_CS", "COMPOUNDCRS")
_CRS_KEYS = _GEOG_KEYS + _PROJ_KEYS + _VERT_KEYS + _COMPOUND_KEYS + ("GEOCCS", "ENGCRS", "LOCAL_CS")


def _root(crs: str) -> list | None:
    try:
        roots = [n for n in _parse(crs) if isinstance(n, list)]
    except ValueError:
        return None
    return roots[0] if roots else None


def _authority(node: list) -> tuple | None:
    for child in node[1:]:
        if isinstance(child, list) and str(child[0]).upper() in _AUTHORITY_KEYS and len(child) >= 3:
            return ("AUTH", str(child[1]).upper(), str(child[2]).strip())
    return None


def _node_identity(node: list) -> tuple:
    auth = _authority(node)
    if auth is not None:
        return auth
    if str(node[0]).upper() in _COMPOUND_KEYS:
        parts = tuple(_node_identity(c) for c in node[1:]
                      if isinstance(c, list) and str(c[0]).upper() in _CRS_KEYS)
        return ("COMPOUND", parts)
    name = node[1] if len(node) > 1 and isinstance(node[1], str) else ""
    return ("NAME", " ".join(name.lower().split()))


def _identity(crs: str) -> tuple | None:
    m = _EPSG_TEXT.fullmatch(crs)
    if m:
        return ("AUTH", "EPSG", m.group(1))
    root = _root(crs)
    return None if root is None else _node_identity(root)


def _same_identity(a: tuple, b: tuple) -> bool | None:
    if a == b:
        return True
    if a[0] == b[0] and a[0] in ("AUTH", "NAME"):
        return False
    if a[0] == b[0] == "COMPOUND" and len(a[1]) == len(b[1]) and a[1]:
        answers = [_same_identity(x, y) for x, y in zip(a[1], b[1])]
        if False in answers:
            return False
        return True if all(answers) else None
    for compound, single in ((a, b), (b, a)):  # a 2D/3D CRS against a compound's horizontal part
        if compound[0] == "COMPOUND" and single[0] != "COMPOUND" and compound[1]:
            return False if _same_identity(compound[1][0], single) is False else None
    return None  # e.g. an EPSG code against a WKT without one: cannot tell without pyproj


def same_crs(a: str | None, b: str | None) -> bool | None:
    """True / False when two CRS strings (WKT 1 or 2, or ``"EPSG:<code>"``) can be told to be
    the same / different, None when either is unknown or they cannot be compared without a
    full CRS library. Equal texts (up to white space) are the same; otherwise the root's
    authority code (``AUTHORITY``/``ID``), compound parts one by one, or the root names are
    compared, so two WKT spellings of one EPSG CRS count as the same."""
    if not a or not b:
        return None
    if " ".join(a.split()) == " ".join(b.split()):
        return True
    ia, ib = _identity(a), _identity(b)
    if ia is None or ib is None:
        return None
    return _same_identity(ia, ib)


def crs_label(crs: str | None, limit: int = 120) -> str:
    """A one-line name for a CRS: ``'NAME' (EPSG:code)``, ``EPSG:code`` or the text cut short."""
    if not crs:
        return "unknown"
    if _EPSG_TEXT.fullmatch(crs):
        return crs.strip()
    root = _root(crs)
    if root is not None and len(root) > 1 and isinstance(root[1], str):
        auth = _authority(root)
        label = repr(root[1]) + (f" ({auth[1]}:{auth[2]})" if auth else "")
    else:
        label = " ".join(crs.split())
    return label if len(label) <= limit else label[: limit - 3] + "..."
