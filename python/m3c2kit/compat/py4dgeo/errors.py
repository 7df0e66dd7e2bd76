"""py4dgeo's exceptions for the compatibility API: every error it raises is a
:class:`Py4DGeoError` (py4dgeo's own base, so `except py4dgeo.Py4DGeoError` catches it), also the
builtin exception py4dgeo's users catch for that case (ValueError for a bad argument, TypeError
for an argument of the wrong kind, FileNotFoundError for a missing file), and still m3c2kit's own
class (UsageError, CloudReadError...). Issue 43: our own classes alone escaped those handlers."""
from __future__ import annotations

import functools
import logging
from collections.abc import Iterable, Mapping
from typing import Any

from ...base.errors import CloudReadError, M3C2Error, UsageError

__all__ = ["Py4DGeoError", "UnsupportedArgument", "translated", "refuse"]

LOGGER = "py4dgeo"


class Py4DGeoError(Exception):
    """py4dgeo's error base; like py4dgeo's, it writes its message to the "py4dgeo" logger."""

    def __init__(self, msg="", loggername: str = LOGGER):
        super().__init__(msg)
        logging.getLogger(loggername).error(self)


class UnsupportedArgument(UsageError, Py4DGeoError, ValueError):
    """A py4dgeo argument this front end does not implement (named in the message)."""


def _builtin_for(error: M3C2Error) -> type[Exception]:
    if isinstance(error, CloudReadError) and "no such file" in str(error):
        return FileNotFoundError
    if isinstance(error, TypeError):
        return TypeError
    return ValueError


@functools.cache
def _translated_class(kind: type, builtin: type) -> type:
    return type(kind.__name__, (kind, Py4DGeoError, builtin), {"__module__": __name__})


def _as_py4dgeo(error: M3C2Error) -> Exception:
    if isinstance(error, Py4DGeoError):
        return error
    return _translated_class(type(error), _builtin_for(error))(*error.args)  # logged by Py4DGeoError


def translated(function):
    """`function` with m3c2kit's errors raised as py4dgeo's (see the module docstring)."""
    @functools.wraps(function)
    def wrapper(*args, **kwargs):
        try:
            return function(*args, **kwargs)
        except M3C2Error as e:
            raise _as_py4dgeo(e) from None
    return wrapper


def refuse(where: str, given: Mapping[str, Any], supported: Iterable[str]) -> None:
    """UnsupportedArgument naming every argument of `given` (those this front end lacks)."""
    if given:
        names = ", ".join(sorted(given))
        raise UnsupportedArgument(
            f"{where}: unsupported py4dgeo argument(s) {names}; m3c2kit.compat.py4dgeo supports "
            f"{', '.join(supported)} (see docs/python.md for the m3c2kit equivalents)")
