"""Errors the m3c2 package reports to its users.

The command line maps them to exit codes: :class:`UsageError` exits 2, every other
:class:`M3C2Error` exits 1. Anything else escaping the package is a bug.

Read and write errors always start with the file path, ``f"{path}: {problem}"``, so a message
alone tells the user which file to look at.
"""
from __future__ import annotations

__all__ = ["M3C2Error", "UsageError", "CloudReadError", "CloudWriteError", "Cancelled", "M3C2Warning"]


class M3C2Error(Exception):
    """Base of every error the CLI reports as a failure (exit status 1)."""


class UsageError(M3C2Error):
    """A bad option or parameter value (exit status 2)."""


class CloudReadError(M3C2Error):
    """A point-cloud file could not be read; the message starts with ``"{path}: "``."""


class CloudWriteError(M3C2Error):
    """A point-cloud file could not be written; the message starts with ``"{path}: "``.

    Raised only after any partial output has been removed.
    """


class Cancelled(M3C2Error):
    """The progress callback stopped a run by returning False (exit status 1)."""


class M3C2Warning(UserWarning):
    """A run that is legitimate but likely mis-parameterised (m3c2kit.diagnostics, docs/errors.md)."""
