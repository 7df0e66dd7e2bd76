"""Read a CloudCompare qM3C2 parameter file and map it onto m3c2's options.

CloudCompare saves these files through ``QSettings`` in INI format: every key sits under
``[General]`` and ``M3C2VER=1`` marks the file as an M3C2 parameter file.  Units follow
CloudCompare, which are also m3c2's:

* ``NormalScale`` (and the multi-scale ``NormalMinScale``/``NormalStep``/``NormalMaxScale``) is
  the normal scale D, a **diameter**;
* ``SearchScale`` is the projection scale d, the cylinder **diameter**;
* ``SearchDepth`` is the cylinder's **half-length** (searched on both sides of the core point).

No value is halved or doubled.  Every key is either mapped, accepted as having no effect on the
numbers (``UseOriginalCloud``, ``ExportStdDevInfo``, ``ExportDensityAtProjScale``: m3c2 always
writes the spread and count columns), or rejected with :class:`~m3c2kit.base.errors.UsageError` naming the
file, the key and the reason.  ``variance="population"`` and ``scale_selection="cloudcompare"`` are
implied by ``compat="cloudcompare"``, which is returned with the file's values: the command line's
``--params FILE`` and ``m3c2kit.compare(..., **read_cloudcompare_params(FILE))`` are one setting.
"""

from __future__ import annotations

import configparser
import logging
import math
import os
import re

from ..base.errors import UsageError
from ..io.input_file import read_small_bytes
from .parsers import scale_range
from .table import by_cloudcompare_key, by_name

__all__ = ["read_cloudcompare_params"]

_log = logging.getLogger(__name__)

PARAMS_KIND = "CloudCompare parameter file"  # its size limit: io.input_file.SMALL_FILE_LIMITS

_FLOAT_RE = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?", re.ASCII)
_INT_RE = re.compile(r"[+-]?\d+", re.ASCII)
_BOOLS = {"true": True, "1": True, "false": False, "0": False}

# Every key qM3C2Dialog::saveParamsTo writes, with its type.
_KEY_TYPES = {
    "M3C2VER": int,
    "NormalScale": float,
    "NormalMode": int,
    "NormalMinScale": float,
    "NormalStep": float,
    "NormalMaxScale": float,
    "NormalUseCorePoints": bool,
    "NormalPreferedOri": int,
    "SearchScale": float,
    "SearchDepth": float,
    "SubsampleRadius": float,
    "SubsampleEnabled": bool,
    "RegistrationError": float,
    "RegistrationErrorEnabled": bool,
    "UseSinglePass4Depth": bool,
    "PositiveSearchOnly": bool,
    "UseMedian": bool,
    "UseMinPoints4Stat": bool,
    "MinPoints4Stat": int,
    "ProjDestIndex": int,
    "UseOriginalCloud": bool,
    "ExportStdDevInfo": bool,
    "ExportDensityAtProjScale": bool,
    "MaxThreadCount": int,
    "UsePrecisionMaps": bool,
    "PM1Scale": float,
    "PM2Scale": float,
}
_CANONICAL = {key.lower(): key for key in _KEY_TYPES}
_OUTPUT_ONLY_KEYS = ("UseOriginalCloud", "ExportStdDevInfo", "ExportDensityAtProjScale")
#: Keys that set no parameter: the file's version, and options m3c2 refuses with a reason.
NON_PARAMETER_KEYS = ("M3C2VER", "NormalUseCorePoints") + _OUTPUT_ONLY_KEYS


def _name(key: str) -> str:
    """The parameter (Python name, m3c2kit.settings.table) that CloudCompare's `key` sets."""
    return by_cloudcompare_key()[key].name

# ccNormalVectors::Orientation, as m3c2's --orient values (m3c2kit.settings.orientation): "+" of a
# point mode is away from it (n . (P - point) >= 0), "-" towards it; the barycentre is the core
# points', as in qM3C2 (it orients the core points' normals).
_ORIENT = {0: "+x", 1: "-x", 2: "+y", 3: "-y", 4: "+z", 5: "-z",
           6: "away:barycentre", 7: "barycentre", 8: "away:origin", 9: "origin",
           11: "away:sensor", 12: "sensor"}
#: The key's value for each --orient value it maps to (for messages naming the key).
ORIENT_KEY_VALUES = {v: k for k, v in _ORIENT.items()}
_ORIENT_UNSUPPORTED = {10: "keep the normals' existing orientation"}
_PROJ_DEST = {0: "reference", 1: "compared", 2: "core"}
_NORMAL_SOURCE = {0: "reference", 2: "reference", 3: "vertical", 4: "horizontal", 5: "core"}


def read_cloudcompare_params(path: str | os.PathLike) -> dict[str, object]:
    """Return m3c2 options (Python names) for the qM3C2 parameter file at ``path``.

    Raises :class:`~m3c2kit.base.errors.UsageError` when the file cannot be read, is not a qM3C2
    parameter file, holds an unknown or misspelt key or a malformed value, or asks for something
    m3c2 does not support.  An optional key that is absent (CloudCompare would take it from its
    last GUI state, which a file cannot reproduce) defaults to NormalMode 0, NormalPreferedOri 4,
    ProjDestIndex 1 and every flag false; ``threads`` is only returned when ``MaxThreadCount`` is. The keys' parameters come from the
    parameter table (its ``cloudcompare_keys``).
    """
    name = os.fsdecode(path)
    values = _parse_values(name, _read_general_section(name, path))

    def fail(message: str) -> UsageError:
        return UsageError(f"{name}: {message}")

    def require(key: str):
        if key not in values:
            raise fail(f"missing {key}")
        return values[key]

    def positive(key: str) -> float:
        value = require(key)
        if not value > 0.0:
            raise fail(f"{key}={value!r} must be > 0")
        return value

    version = require("M3C2VER")
    if version != 1:
        raise fail(f"M3C2VER={version} is not supported (only version 1 exists)")

    options: dict[str, object] = {}
    mode = values.get("NormalMode", 0)
    if mode == 1:
        raise fail(
            "NormalMode=1 (normals stored in the reference cloud) is not supported; use "
            "NormalMode=5 with core points that carry normals (--core), or let m3c2 compute "
            "them (NormalMode=0)"
        )
    if mode not in _NORMAL_SOURCE:
        raise fail(f"NormalMode={mode} is not a CloudCompare normal mode (0 to 5)")
    options[_name("NormalMode")] = _NORMAL_SOURCE[mode]
    if mode in (0, 4):
        options[_name("NormalScale")] = positive("NormalScale")
    elif mode == 2:
        options[_name("NormalScale")] = _multi_scales(
            fail, positive("NormalMinScale"), positive("NormalStep"), positive("NormalMaxScale")
        )

    # CloudCompare reads NormalUseCorePoints and NormalPreferedOri only when it computes the
    # normals (modes 0, 2, 4); vertical normals and core-point normals are used as they are.
    if mode in (0, 2, 4):
        if values.get("NormalUseCorePoints", False):
            raise fail(
                "NormalUseCorePoints=true (normals fitted to the core points instead of the "
                "reference cloud) is not supported; set it to false"
            )
        ori = values.get("NormalPreferedOri", 4)
        if ori in _ORIENT_UNSUPPORTED:
            raise fail(
                f"NormalPreferedOri={ori} ({_ORIENT_UNSUPPORTED[ori]}) is not supported; "
                "qM3C2 computes new normals, which have no previous orientation to keep; orient them with "
                "--orient (an axis, X,Y,Z, FILE, origin, barycentre or sensor) instead"
            )
        if ori not in _ORIENT:
            raise fail(f"NormalPreferedOri={ori} is not a CloudCompare orientation (0 to 12)")
        options[_name("NormalPreferedOri")] = _ORIENT[ori]

    options[_name("SearchScale")] = positive("SearchScale")
    options[_name("SearchDepth")] = positive("SearchDepth")

    if values.get("RegistrationErrorEnabled", False):
        reg = require("RegistrationError")
        if reg < 0.0:
            raise fail(f"RegistrationError={reg!r} must be >= 0")
        options[_name("RegistrationError")] = reg
    else:
        options[_name("RegistrationError")] = 0.0

    options[_name("UseMedian")] = values.get("UseMedian", False)
    if values.get("UseMinPoints4Stat", False):
        min_points = require("MinPoints4Stat")
        if min_points < 1:
            raise fail(f"MinPoints4Stat={min_points} must be >= 1")
        options[_name("MinPoints4Stat")] = min_points
    else:
        options[_name("MinPoints4Stat")] = by_name()["min_points"].cloudcompare

    options[_name("SubsampleRadius")] = (
        positive("SubsampleRadius") if values.get("SubsampleEnabled", False) else None
    )
    single_pass = values.get("UseSinglePass4Depth", False)
    options[_name("UseSinglePass4Depth")] = "single" if single_pass else "progressive"
    options[_name("PositiveSearchOnly")] = values.get("PositiveSearchOnly", False)

    if "MaxThreadCount" in values:
        threads = values["MaxThreadCount"]
        if threads < 0:
            raise fail(f"MaxThreadCount={threads} must be >= 0")
        options[_name("MaxThreadCount")] = max(threads, 1)  # qM3C2's thread spin box clamps 0 to 1

    dest = values.get("ProjDestIndex", 1)
    if dest not in _PROJ_DEST:
        raise fail(f"ProjDestIndex={dest} is not a CloudCompare output placement (0, 1 or 2)")
    options[_name("ProjDestIndex")] = _PROJ_DEST[dest]

    if values.get("UsePrecisionMaps", False):
        # M3C2-PM (docs/algorithm.md §6.5): the precision fields come from --precision-fields.
        options[_name("UsePrecisionMaps")] = "pm"
        scales = [values.get("PM1Scale", 1.0), values.get("PM2Scale", 1.0)]
        if not all(s > 0 and math.isfinite(s) for s in scales):
            raise fail(f"PM1Scale and PM2Scale must be finite and > 0, got {scales[0]!r}, {scales[1]!r}")
        options[_name("PM1Scale")] = scales

    for key in _OUTPUT_ONLY_KEYS:
        if key in values:
            _log.info("%s: %s only changes CloudCompare's output fields; ignored", name, key)
    options["compat"] = "cloudcompare"  # the defaults of the keys a file leaves out are CloudCompare's
    return options


def _multi_scales(fail, low: float, step: float, high: float) -> list[float]:
    try:
        return scale_range(low, high, step)
    except ValueError as e:
        raise fail(f"NormalMinScale/NormalStep/NormalMaxScale: {e}") from None


def _read_general_section(name: str, path: str | os.PathLike) -> dict[str, str]:
    # A FIFO, device or directory is refused and the size bounded where every input file is opened.
    data = read_small_bytes(path, PARAMS_KIND, label=name)
    if b"\0" in data:
        raise UsageError(f"{name}: not a CloudCompare parameter file (binary data)")
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError:
        text = data.decode("latin-1")
    # QSettings ignores indentation; stripping it also stops configparser from reading an
    # indented line as the continuation of the previous value.  Line numbers are kept.
    text = "\n".join(line.strip() for line in text.splitlines())

    parser = configparser.ConfigParser(
        delimiters=("=",),
        comment_prefixes=("#", ";"),
        strict=True,
        empty_lines_in_values=False,
        interpolation=None,
        default_section="\0no default section",
    )
    parser.optionxform = str  # QSettings keys are case-sensitive
    try:
        parser.read_string(text, source=name)
    except configparser.DuplicateOptionError as e:
        raise UsageError(f"{name}: line {e.lineno}: duplicate key '{e.option}'") from None
    except configparser.DuplicateSectionError as e:
        raise UsageError(f"{name}: line {e.lineno}: duplicate section [{e.section}]") from None
    except configparser.MissingSectionHeaderError as e:
        raise UsageError(
            f"{name}: line {e.lineno}: {e.line.strip()!r} comes before the [General] section"
        ) from None
    except configparser.ParsingError as e:
        lineno, line = e.errors[0]  # configparser stores the line already repr()'d
        raise UsageError(
            f"{name}: line {lineno}: cannot parse {line} (expected Key=value)"
        ) from None
    except configparser.Error as e:
        raise UsageError(f"{name}: not an INI file: {e.message}") from None

    for section in parser.sections():
        if section == "General":
            continue
        if section.lower() == "general":
            raise UsageError(f"{name}: section [{section}] must be spelled [General]")
        raise UsageError(
            f"{name}: unexpected section [{section}]; every qM3C2 parameter belongs under [General]"
        )
    if not parser.has_section("General"):
        raise UsageError(
            f"{name}: no [General] section (not a CloudCompare qM3C2 parameter file?)"
        )
    return dict(parser.items("General"))


_MAX_INT_DIGITS = 20


def _shown(text: str, most: int = 40) -> str:
    """`text` quoted for a message, cut to `most` characters (a value of 5,000 digits)."""
    if len(text) <= most:
        return repr(text)
    return f"{text[:most]!r}... ({len(text)} characters)"


def _parse_values(name: str, raw: dict[str, str]) -> dict[str, object]:
    values: dict[str, object] = {}
    for key, text in raw.items():
        if key not in _KEY_TYPES:
            if key.lower() in _CANONICAL:
                raise UsageError(
                    f"{name}: CloudCompare parameter '{key}' must be spelled "
                    f"'{_CANONICAL[key.lower()]}' (keys are case-sensitive)"
                )
            raise UsageError(f"{name}: unknown CloudCompare parameter '{key}'")
        value = _unquote(text)
        kind = _KEY_TYPES[key]
        if kind is bool:
            parsed = _BOOLS.get(value.lower())
            expected = "true or false"
        elif kind is int:
            # Wider than any engine field (64 bits: 20 digits); int() refuses > 4300 digits with a ValueError.
            if _INT_RE.fullmatch(value) and len(value.lstrip("+-0")) > _MAX_INT_DIGITS:
                raise UsageError(f"{name}: {key}={_shown(text)} has {len(value.lstrip('+-0'))} digits, "
                                 f"more than any integer parameter holds ({_MAX_INT_DIGITS})")
            parsed = int(value) if _INT_RE.fullmatch(value) else None
            expected = "an integer"
        else:
            parsed = float(value) if _FLOAT_RE.fullmatch(value) else None
            if parsed is not None and not math.isfinite(parsed):
                parsed = None
            expected = "a finite number"
        if parsed is None:
            raise UsageError(f"{name}: malformed value for {key}: {_shown(text)} (expected {expected})")
        values[key] = parsed
    return values


def _unquote(text: str) -> str:
    """Drop QSettings quoting and a trailing comment; the values here never contain ; or #."""
    text = text.strip()
    if len(text) >= 2 and text[0] in "\"'":
        end = text.find(text[0], 1)
        rest = text[end + 1 :].strip() if end > 0 else "x"
        if end > 0 and (not rest or rest[0] in ";#"):
            return text[1:end].strip()
        return text
    return re.split(r"[;#]", text, maxsplit=1)[0].strip()
